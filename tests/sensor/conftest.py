"""Fixtures of the sensor tests.

The fakes of Fleet, Platform and Terrain (docs/architecture.md) live in ``sensor_fakes.py`` and
are re-exported here.  A uniquely named module rather than ``from conftest import ...``: another
package's conftest can never shadow it.  This directory is put on ``sys.path`` so that the
import works under any pytest import mode (prepend, append or importlib).
"""
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

from gmtiflow.sensor.config import SensorConfig  # noqa: E402
from sensor_fakes import (ORIGIN, FlatTerrain, LevelPlatform, LineFleet,  # noqa: E402,F401
                          WallTerrain, grid_fleet, run, still)


@pytest.fixture
def cfg():
    return SensorConfig()


@pytest.fixture
def platform():
    return LevelPlatform()


@pytest.fixture
def flat():
    return FlatTerrain()
