"""Every numeric config field, set to NaN, ±inf or a negative number, either gives one
ConfigError naming that key or is a documented valid value (docs/reliability.md, "Config").

The fields are found by walking the validated dataclass tree of a few preset combinations, so a
field added later without a check fails here rather than deep inside numpy.
"""
from __future__ import annotations

import copy
import math
import re

import pytest

from gmtiflow import config
from gmtiflow.compose import compose
from gmtiflow.config_tree import get_path, numeric_leaves, set_leaf
from gmtiflow.errors import ConfigError

PRESETS = {
    "default": [],
    "busy": ["vehicles=random", "clutter=windfarm", "platform=racetrack", "sensor=wide_fov",
             "terrain=hills"],
    "urban": ["clutter=urban", "fidelity=full", "export=all"],
}

SIGNED_OK = {
    # Signed quantities: a negative value is meaningful (dB below 1, angles left of boresight,
    # heights below the datum, ENU coordinates west/south of the origin, receding clutter).
    "clutter.fov_range_rate.mean_mps", "clutter.regions[].centre_m[]",
    "clutter.regions[].range_rate.mean_mps", "clutter.regions[].snr.low_db",
    "clutter.regions[].vertices_m[][]", "clutter.snr.low_db", "platform.time_offset_s",
    "platform.waypoints_m[][]",
    "sensor.az_max_deg", "sensor.az_min_deg", "sensor.el_max_deg", "sensor.el_min_deg",
    "sensor.mount_deg", "sensor.rcs.car.rcs_dbsm", "sensor.rcs.default.rcs_dbsm",
    "sensor.rcs.truck.rcs_dbsm", "sensor.rcs0_dbsm", "sensor.snr0_db", "terrain.flat_height_m",
    "terrain.hills[].azimuth_deg", "terrain.hills[].height_m", "terrain.hills[].x_m",
    "terrain.hills[].y_m", "terrain.hills_base_height_m", "vehicles.vehicles[].off_road[][]",
}


def named_in(message: str, key: str, tree) -> bool:
    """The message names ``key``, or the list/dict field that holds it (``types``, ``[1]``)."""
    candidates = {key, re.sub(r"(\[\d+\])+$", "", key)}
    parts = key.split(".")
    holder = get_path(tree, ".".join(parts[:-1]))
    if isinstance(holder, dict):          # a dict entry: the dict's key names it
        candidates.add(".".join(parts[:-1]))
    return any(c in message for c in candidates)


def generic(key: str) -> str:
    return re.sub(r"\[\d+\]", "[]", key)


@pytest.fixture(scope="module", params=sorted(PRESETS))
def preset(request):
    return request.param, compose(PRESETS[request.param])


def test_every_numeric_field_rejects_nan_and_infinity_by_name(preset):
    name, base = preset
    keys = [key for key, _ in numeric_leaves(base)]
    assert len(keys) > 100, keys           # the walk really reaches the whole tree
    silent, unnamed, tried = [], [], 0
    for key in keys:
        for value in (math.nan, math.inf, -math.inf):
            cfg = copy.deepcopy(base)
            set_leaf(cfg, key, value)
            tried += 1
            try:
                config.validate(cfg)
            except ConfigError as exc:
                if not named_in(str(exc), key, cfg):
                    unnamed.append((key, value, str(exc)[:200]))
            else:
                silent.append((key, value))
    assert not silent, f"{name}: accepted without a ConfigError: {silent}"
    assert not unnamed, f"{name}: ConfigError does not name the key: {unnamed}"


def test_every_negative_number_is_refused_by_name_or_a_signed_quantity(preset):
    name, base = preset
    accepted = []
    for key, _ in numeric_leaves(base):
        cfg = copy.deepcopy(base)
        set_leaf(cfg, key, -1.0)
        try:
            config.validate(cfg)
        except ConfigError:
            continue
        accepted.append(generic(key))
    undocumented = sorted(set(accepted) - SIGNED_OK)
    assert not undocumented, f"{name}: negative accepted for {undocumented}"


@pytest.mark.parametrize("overrides, key", [
    (["sensor.az_min_deg=30", "sensor.az_max_deg=-30"], "sensor.az_min_deg"),
    (["sensor.pulse_width_s=0.01", "sensor.pri_s=0.001"], "sensor.pri_s"),
    (["sensor.revisit_s=0.01"], "sensor.revisit_s"),
    (["vehicles=random", "vehicles.random.types={car: nan}"], "vehicles.random.types"),
    (["vehicles=random", "vehicles.random.position_noise_m=[inf,0,0]"],
     "vehicles.random.position_noise_m"),
    (["clutter=windfarm", "clutter.snr.kind=uniform_db", "clutter.snr.high_db=inf"],
     "clutter.snr.high_db"),
])
def test_cross_field_rules_through_compose(overrides, key):
    with pytest.raises(ConfigError, match=re.escape(key)):
        compose(overrides)


@pytest.mark.parametrize("overrides, key, hint", [
    # Hydra's own hint for a misspelt key is "To append to your config use +key=value"; a
    # user who follows it used to get a run with the key silently ignored (exit 0).
    (["+sensor.pfaa=1e-6"], "sensor.pfaa", "sensor.pfa"),
    (["+foo=1"], "foo", None),
    (["+scene.duration=60"], "scene.duration", "scene.duration_s"),
    (["clutter=lake", "+clutter.regions.0.radius=5"], "clutter.regions[0].radius",
     "clutter.regions[0].radius_m"),
    (["+platform@sensors.east.platform=racetrack", "+sensor@sensors.east.sensor=default",
      "+sensors.east.sensor.pfaa=1e-6"], "sensors.east.sensor.pfaa", "sensors.east.sensor.pfa"),
])
def test_a_key_added_with_plus_that_the_schema_lacks_is_refused_by_name(overrides, key, hint):
    with pytest.raises(ConfigError) as err:
        compose(overrides)
    message = str(err.value)
    assert f"{key}: unknown config key" in message, message
    if hint is not None:
        assert f"did you mean {hint}?" in message, message


def test_keys_added_where_the_schema_takes_any_name_are_still_accepted():
    """Free-form dicts stay open: tracker params, vehicle-type weights, more sensors."""
    cfg = compose(["tracker=python", "tracker.target=mypkg.MyTracker",
                   "+tracker.params.gate_m=250", "vehicles=random",
                   "+vehicles.random.types.van=0.5",
                   "+platform@sensors.east.platform=racetrack",
                   "+sensor@sensors.east.sensor=default"])
    assert cfg.tracker.params == {"gate_m": 250}
    assert cfg.vehicles.random.types["van"] == 0.5
    assert list(cfg.sensors) == ["east"]


@pytest.mark.parametrize("overrides, key", [
    # Heights far off the earth used to end the run with "tracker NNKalmanTracker: row 1:
    # negative variance cov_xx_m2/cov_yy_m2" (blaming the tracker), or run with nothing seen.
    (["terrain.flat_height_m=-1e7"], "terrain.flat_height_m"),
    (["terrain.flat_height_m=1e7"], "terrain.flat_height_m"),
    (["terrain=hills", "terrain.hills_base_height_m=-1e7"], "terrain.hills_base_height_m"),
    (["terrain=hills", "terrain.hills_base_height_m=1e9"], "terrain.hills_base_height_m"),
    (["terrain=hills", "terrain.hills.0.height_m=2e4"], "terrain.hills[0].height_m"),
])
def test_terrain_heights_off_the_earth_are_refused_by_name(overrides, key):
    with pytest.raises(ConfigError, match=re.escape(key) + r": must be in \[-11000.0, 11000.0\]"):
        compose(overrides)


def test_a_terrain_step_finer_than_any_dem_is_refused_by_name():
    """fidelity.terrain_step_m=1e-4 with terrain=hills took 2.9 GB and over a minute on a 20 s
    scene (1e-6: no end); the extremes sweep runs on flat terrain, where the step is unused."""
    with pytest.raises(ConfigError, match=r"fidelity\.terrain_step_m: must be at least 0\.1 m"):
        compose(["terrain=hills", "fidelity.terrain_step_m=1e-4"])
    assert compose(["terrain=hills", "fidelity.terrain_step_m=0.1"]).fidelity.terrain_step_m == 0.1
