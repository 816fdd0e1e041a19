"""Fixtures of the sensor tests; the fakes themselves live in ``sensor_fakes.py``
(a uniquely named module, so that ``from sensor_fakes import ...`` cannot pick up another
package's conftest)."""
import pytest

from gmtiflow.sensor.config import SensorConfig
from sensor_fakes import FlatTerrain, LevelPlatform


@pytest.fixture
def cfg():
    return SensorConfig()


@pytest.fixture
def platform():
    return LevelPlatform()


@pytest.fixture
def flat():
    return FlatTerrain()
