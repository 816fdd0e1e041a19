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
             "terrain_shadow", "offroad", "dense_clutter", "two_sensors")


def shipped() -> List[str]:
    """Names of the scenario files shipped in the package's ``conf/experiment/challenge/``."""
    folder = resources.files("gmtiflow.conf").joinpath("experiment", GROUP)
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".yaml"))


def override(name: str) -> str:
    """The ``experiment=`` value of a scenario name."""
    return f"{GROUP}/{name}"

#: One line per scenario: the challenge it isolates (report pages, docs/benchmark.md).
CHALLENGE_TEXT = {
    "crossing": "two trucks cross at an X junction; merged plots around the crossing (identity)",
    "overtake": "a faster truck overtakes a slower one; ambiguous, then merged, then split plots",
    "convoy": "five trucks 15 m apart; fewer, merged plots that change from dwell to dwell",
    "stop_and_go": "trucks stop at junctions for up to 45 s and vanish in the clutter notch",
    "tangential": "moving trucks Doppler-blind for ~50 s because the road is broadside to the radar",
    "tunnel": "trucks out of sight for 20 s and 40 s in tunnels",
    "terrain_shadow": "a truck hidden behind a ridge for about a minute",
    "offroad": "trucks leave the road and cross fields, or join the road from them",
    "dense_clutter": "about 50 false alarms per scan around three trucks in a town",
    "two_sensors": "two radars 90° apart: each loses one truck in its Doppler notch, the other "
                   "sees it",
}
