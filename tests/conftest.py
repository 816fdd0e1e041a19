"""Shared fixtures: composing the app config without the Hydra runtime, and locating shared data."""
from pathlib import Path

import pytest
from hydra import compose, initialize_config_module
from hydra.core.global_hydra import GlobalHydra

from gmtiflow import config

ROOT = Path(__file__).resolve().parents[1]
SHARED_DATA = ROOT.parent / "shared" / "data"


def compose_app(overrides=()):
    """Compose conf/config.yaml with overrides and convert to validated dataclasses."""
    GlobalHydra.instance().clear()
    with initialize_config_module(config_module="gmtiflow.conf", version_base="1.3"):
        cfg = compose(config_name="config", overrides=list(overrides))
    return config.to_object(cfg)


@pytest.fixture
def compose_config():
    """The config composer as a fixture: ``compose_config(["sensor=wide_fov", ...])``."""
    return compose_app


@pytest.fixture
def shared_data():
    if not SHARED_DATA.is_dir():
        pytest.skip(f"shared data not found at {SHARED_DATA}")
    return SHARED_DATA


@pytest.fixture(scope="session")
def small_scene_overrides():
    """A short default scene: quick to run end to end."""
    return ["scene.duration_s=30", "fidelity.truth_output_dt_s=1.0"]
