"""Compose and run gmtiflow from Python, without the command line.

>>> from gmtiflow.compose import compose, run
>>> cfg = compose(["sensor=wide_fov", "clutter=lake", "seed=3"])   # validated AppConfig
>>> path = run(cfg, "outputs/my-run")                                # -> outputs/my-run/run.h5

Overrides are exactly what the CLI takes (Hydra syntax); bad ones raise
:class:`~gmtiflow.errors.ConfigError` before anything runs: an unknown group option or key, a
value of the wrong type or an override Hydra cannot parse as its subclass
:class:`~gmtiflow.errors.CompositionError` (one line naming the override and the choices,
:mod:`gmtiflow.compose_errors`; Hydra's own exception is its ``__cause__``).
"""
from __future__ import annotations

from typing import Iterable

from hydra import compose as hydra_compose
from hydra import initialize_config_module
from hydra.core.global_hydra import GlobalHydra
from omegaconf import DictConfig

from gmtiflow import config
from gmtiflow.compose_errors import COMPOSITION_ERRORS, composition_error
from gmtiflow.pipeline import run

__all__ = ["compose", "compose_dictconfig", "run"]


def compose(overrides: Iterable[str] = ()) -> config.AppConfig:
    """The validated app config of ``conf/config.yaml`` with ``overrides`` applied."""
    return config.to_object(compose_dictconfig(overrides))


def compose_dictconfig(overrides: Iterable[str] = ()) -> DictConfig:
    """Hydra's composed ``DictConfig`` of ``conf/config.yaml`` with ``overrides``, as the CLI's
    job gets it: before conversion and validation (:func:`compose` does both)."""
    GlobalHydra.instance().clear()
    try:
        with initialize_config_module(config_module="gmtiflow.conf", version_base="1.3"):
            return hydra_compose(config_name="config", overrides=list(overrides))
    except COMPOSITION_ERRORS as exc:
        error = composition_error(exc)
        if error is None:
            raise
        raise error from exc
    finally:
        GlobalHydra.instance().clear()
