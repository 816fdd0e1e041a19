"""Shared fixtures: composing the app config without the Hydra runtime, and locating shared data."""
from pathlib import Path

import pytest

from gmtiflow.compose import compose as compose_app

ROOT = Path(__file__).resolve().parents[1]
SHARED_DATA = ROOT.parent / "shared" / "data"


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
