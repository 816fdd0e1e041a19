"""The benchmark's scenarios: the configs under ``conf/experiment/challenge/``.

A scenario is a Hydra experiment (``# @package _global_``), run alone with
``gmtiflow experiment=challenge/<name>`` and swept by the benchmark as the ``experiment``
choice.  :data:`SCENARIOS` lists them in the order of the docs and the report.
"""
from __future__ import annotations

from importlib import resources
from typing import List

#: Config group path of the scenarios, relative to the ``experiment`` group.
GROUP = "challenge"

#: The suite, in report order (one GMTI challenge each; docs/benchmark.md).
SCENARIOS = ("crossing", "overtake", "convoy", "stop_and_go", "tangential", "tunnel",
             "terrain_shadow", "offroad", "dense_clutter")


def shipped() -> List[str]:
    """Names of the scenario files shipped in the package's ``conf/experiment/challenge/``."""
    folder = resources.files("gmtiflow.conf").joinpath("experiment", GROUP)
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".yaml"))


def override(name: str) -> str:
    """The ``experiment=`` value of a scenario name."""
    return f"{GROUP}/{name}"
