"""``config.validate`` reports exactly what the plain tree walk reports, however it gets there.

Validation skips plain leaves and checks lists of numbers (waypoints ...) in bulk; the reference
here is the walk it replaced, node by node (``reference_validate``), and every case compares the
two outcomes: the same ConfigError text (keys, messages, order), or the same other exception.
"""
from __future__ import annotations

import dataclasses
import math
import sys
import typing
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gmtiflow import config, schema
from gmtiflow.compose import compose, compose_dictconfig
from gmtiflow.config_tree import get_path, numeric_leaves, set_leaf
from gmtiflow.errors import ConfigError
from gmtiflow.scene.vehicles_config import (ConvoySpec, SpeedChangeSpec, VehicleSpec,
                                             VehiclesConfig)


def reference_numeric_leaves(obj, prefix=""):
    if dataclasses.is_dataclass(obj):
        for f in dataclasses.fields(obj):
            yield from reference_numeric_leaves(getattr(obj, f.name), f"{prefix}{f.name}.")
    elif isinstance(obj, (list, tuple)):
        for i, item in enumerate(obj):
            yield from reference_numeric_leaves(item, f"{prefix[:-1]}[{i}].")
    elif isinstance(obj, dict):
        for key, item in obj.items():
            yield from reference_numeric_leaves(item, f"{prefix}{key}.")
    elif isinstance(obj, (int, float)) and not isinstance(obj, bool):
        yield prefix[:-1], obj


def reference_problems_of(obj, prefix=""):
    out = []
    if dataclasses.is_dataclass(obj):
        check = getattr(obj, "problems", None)
        if callable(check):
            out += [schema.Problem(f"{prefix}{p.key}", p.message) for p in check()]
        for f in dataclasses.fields(obj):
            out += reference_problems_of(getattr(obj, f.name), f"{prefix}{f.name}.")
    elif isinstance(obj, (list, tuple)):
        for i, item in enumerate(obj):
            out += reference_problems_of(item, f"{prefix[:-1]}[{i}].")
    elif isinstance(obj, dict):
        for key, item in obj.items():
            out += reference_problems_of(item, f"{prefix}{key}.")
    return out


def reference_validate(obj):
    found = reference_problems_of(obj)
    big = [schema.Problem(key, f"must be within ±{config.MAX_MAGNITUDE:g}, got {value!r}")
           for key, value in reference_numeric_leaves(obj)
           if key != "seed" and math.isfinite(value) and abs(value) > config.MAX_MAGNITUDE]
    found = list(dict.fromkeys(found + big))
    if found:
        raise ConfigError("invalid config: " + "; ".join(f"{p.key}: {p.message}" for p in found))


def reference_points_problems(key, points, **kw):
    return [p for i, point in enumerate(points)
            for p in schema.point_problems(f"{key}[{i}]", point, **kw)]


def outcome(check, cfg):
    """What validating ``cfg`` gives: None, or the exception's type and text."""
    try:
        check(cfg)
    except Exception as exc:          # noqa: BLE001 - compared, not swallowed
        return type(exc).__name__, str(exc)
    return None


def assert_same_outcome(cfg):
    expected = outcome(reference_validate, cfg)
    assert outcome(config.validate, cfg) == expected
    return expected


def peer_config(n, duration_s=600.0):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    try:
        from stonesoup_peer import peer_vehicles
    finally:
        sys.path.pop(0)
    cfg = compose(["fidelity=fast", f"scene.duration_s={duration_s:g}"])
    cfg.vehicles = peer_vehicles(n, duration_s)
    return cfg


BAD_NUMBERS = [math.nan, -1, 2e12, True, 10 ** 400]
SLOW = pytest.mark.slow


@pytest.mark.parametrize("overrides", [[], pytest.param(["vehicles=random", "clutter=windfarm",
                                                         "platform=racetrack", "sensor=wide_fov",
                                                         "terrain=hills"], marks=SLOW),
                                       pytest.param(["experiment=challenge/offroad",
                                                     "clutter=urban"], marks=SLOW)])
def test_every_numeric_leaf_set_wrong_gives_the_same_problems(overrides):
    cfg = compose(overrides)
    keys = [key for key, _ in reference_numeric_leaves(cfg)]
    assert keys == [key for key, _ in numeric_leaves(cfg)] and len(keys) > 100
    errors = 0
    for key in keys:
        original = get_path(cfg, key)
        for value in BAD_NUMBERS:
            set_leaf(cfg, key, value)
            errors += assert_same_outcome(cfg) is not None
        set_leaf(cfg, key, original)
    assert errors > len(keys)          # most bad values are refused
    assert assert_same_outcome(cfg) is None


def test_a_large_vehicle_list_with_one_bad_value_deep_inside():
    cfg = peer_config(1000)
    assert assert_same_outcome(cfg) is None
    waypoints = cfg.vehicles.vehicles[731].off_road
    for bad in (math.nan, -math.inf, 5e12, "x", None, True):
        waypoints[7] = [waypoints[7][0], bad]
        expected = assert_same_outcome(cfg)
        assert expected is not None and "vehicles.vehicles[731].off_road[7]" in expected[1]
    waypoints[7] = [waypoints[7][0], -2000.0]
    cfg.vehicles.vehicles[998].off_road[3] = [1.0, 2.0, 3.0, 4.0]
    expected = assert_same_outcome(cfg)
    assert expected == ("ConfigError", "invalid config: vehicles.vehicles[998].off_road[3]: must "
                        "be [x, y] or [x, y, z] in finite metres or {lat_deg, lon_deg, height_m}, "
                        "got [1.0, 2.0, 3.0, 4.0]")


def test_a_large_vehicle_list_with_many_bad_values_keeps_their_order():
    cfg = peer_config(200)
    for i in (150, 3, 77):
        cfg.vehicles.vehicles[i].off_road[i % 7] = [7e12, 0.0]
        cfg.vehicles.vehicles[i].position_noise_m[2] = math.nan
    cfg.vehicles.vehicles[5].off_road[2] = {"lat_deg": 95.0, "lon_deg": 7.0}
    cfg.vehicles.vehicles[9].off_road = [[0.0, 0.0]]
    cfg.vehicles.vehicles[12].speed_changes = [SpeedChangeSpec(at=None, cruise_speed_mps=-1.0)]
    cfg.vehicles.vehicles[13].convoy.count = 0           # problems its parents report
    cfg.vehicles.random.count = -1
    kind, text = assert_same_outcome(cfg)
    assert "vehicles.vehicles[13].convoy.count" in text and "vehicles.random.count" in text
    assert text.count("must be within ±1e+12") == 3 and text.count("lat_deg must be") == 1


waypoint_values = st.one_of(st.floats(), st.integers(-10 ** 400, 10 ** 400), st.booleans(),
                            st.none(), st.sampled_from([1e308, -1e308, 0.0, -0.0, "1.0", 3]))
points = st.one_of(st.lists(waypoint_values, min_size=0, max_size=4),
                   st.tuples(waypoint_values, waypoint_values),
                   st.sampled_from([{"lat_deg": 1.0, "lon_deg": 2.0}, {"lat": 1.0}, "x", None]))


def same_result(fn, *args, **kw):
    try:
        return fn(*args, **kw)
    except Exception as exc:          # noqa: BLE001 - compared, not swallowed
        return type(exc).__name__, str(exc)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.one_of(st.lists(points, max_size=6),
                 st.lists(st.lists(st.floats(-1e308, 1e308), min_size=2, max_size=2), max_size=6)),
       st.sampled_from([(2, 3), (3,)]), st.booleans())
def test_points_problems_are_those_of_each_point(pts, dims, geodetic):
    assert (same_result(schema.points_problems, "p", pts, dims=dims, geodetic=geodetic)
            == same_result(reference_points_problems, "p", pts, dims=dims, geodetic=geodetic))


leaf_values = st.one_of(st.floats(), st.integers(-10 ** 20, 10 ** 20), st.booleans(), st.none(),
                        st.text(max_size=3), st.sampled_from([math.nan, math.inf, 2e12]))
plain = st.recursive(leaf_values, lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                          st.tuples(inner),
                                                          st.dictionaries(st.text(max_size=2),
                                                                          inner, max_size=3)),
                     max_leaves=20)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(plain, st.sampled_from([0.5, 1e12, math.inf]))
def test_numeric_leaves_within_a_bound_leave_out_only_leaves_within_it(tree, bound):
    every = list(numeric_leaves(tree))
    assert every == list(reference_numeric_leaves(tree))
    some = list(numeric_leaves(tree, bound=bound))

    def beyond(leaves):                   # NaNs in a list within the bound may be left out
        return [leaf for leaf in leaves if leaf[1] == leaf[1] and not -bound <= leaf[1] <= bound]
    assert beyond(every) == beyond(some)
    assert all(leaf in every for leaf in some)


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(plain, st.integers(0, 5))
def test_problems_are_found_inside_plain_looking_lists(tree, depth):
    # a dataclass with problems inside lists of scalars (possible from Python) is still checked
    bad = VehicleSpec(name="", off_road=[[0.0, 0.0]])
    holder = bad
    for _ in range(depth):
        holder = [tree, holder] if depth % 2 else [[1.0, holder]]
    cfg = VehiclesConfig(vehicles=[VehicleSpec(name="a", off_road=[[0.0, 0.0], [1.0, 1.0]],
                                               stopovers=[tree, holder])])
    assert config.problems_of(cfg) == reference_problems_of(cfg)
    assert config.problems_of(cfg)


# --- long lists of dataclasses: checked field by field across the list, the same outcome ------

good_numbers = st.sampled_from([0.0, 1.5, 13.9, -2000.0, 7, 1e12, -1e12])
lenient_numbers = st.one_of(good_numbers, good_numbers, good_numbers, waypoint_values)
rows = st.one_of(st.lists(st.lists(good_numbers, min_size=2, max_size=2), min_size=2,
                          max_size=4), st.lists(points, max_size=3))
vehicle_specs = st.builds(
    VehicleSpec, name=st.sampled_from(["a", "b", "", "???"]),
    start=st.sampled_from([None, "n1", [1.0, 2.0]]), end=st.sampled_from([None, "n2"]),
    stopovers=st.one_of(st.just([]), st.lists(st.one_of(st.just("n3"), points), max_size=2)),
    cruise_speed_mps=lenient_numbers, start_speed_mps=st.one_of(st.none(), lenient_numbers),
    position_noise_m=st.one_of(st.just([0.0, 0.0, 0.0]), st.lists(lenient_numbers, max_size=4)),
    max_wait_s=lenient_numbers, off_road=st.one_of(rows, rows, st.just([])),
    speed_changes=st.one_of(st.just([]), st.lists(st.builds(
        SpeedChangeSpec, at=st.sampled_from([None, "n1", [1.0, 2.0], {"x": 1e13}]),
        cruise_speed_mps=lenient_numbers), max_size=2)),
    convoy=st.builds(ConvoySpec, count=st.sampled_from([1, 1, 3, 0]),
                     spacing_m=st.one_of(st.none(), lenient_numbers)))
BASE = []


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(vehicle_specs, min_size=2, max_size=5), st.sampled_from([0.5, 1e12, math.inf]))
def test_vehicle_lists_checked_field_by_field_give_the_same_problems(vehicles, bound):
    if not BASE:
        BASE.append(compose(["fidelity=fast"]))
    cfg = dataclasses.replace(BASE[0], vehicles=VehiclesConfig(vehicles=vehicles))
    def once(problems):                   # a parent may report its items' problems too
        return problems if isinstance(problems, tuple) else list(dict.fromkeys(problems))
    assert (once(same_result(config.problems_of, cfg.vehicles))
            == once(same_result(reference_problems_of, cfg.vehicles)))
    assert_same_outcome(cfg)
    every = list(numeric_leaves(cfg))
    some = list(numeric_leaves(cfg, bound=bound))

    def beyond(leaves):                   # NaNs in a list within the bound may be left out
        return [leaf for leaf in leaves if leaf[1] == leaf[1] and not -bound <= leaf[1] <= bound]
    assert beyond(every) == beyond(some)
    assert all(leaf in every for leaf in some)


def test_a_clean_vehicle_list_is_checked_field_by_field():
    # the bulk checks answer for the peer's list (no walk item by item), and are not fooled
    from gmtiflow.config_tree import records_within
    vehicles = peer_config(20).vehicles.vehicles
    assert config._reported_records(vehicles, True) and records_within(vehicles, 1e12)
    assert not config._reported_records(vehicles, False)      # their problems() must run
    vehicles[7].convoy.spacing_m = -3e12
    assert config._reported_records(vehicles, True) and not records_within(vehicles, 1e12)
    vehicles[7].convoy.spacing_m = None
    vehicles[3].speed_changes = [SpeedChangeSpec(at="n1")]
    vehicles[4].speed_changes = [SpeedChangeSpec(at="n2", cruise_speed_mps=-1.0)]
    assert config._reported_records(vehicles, True)          # reported by VehicleSpec.problems
    vehicles[3].stopovers = [{"lat_deg": 1.0, "lon_deg": 2.0}]
    assert not config._reported_records(vehicles, True)      # a dict: walked item by item


# --- to_object: missing values listed as before, the walk that finds them only on failure -----

def reference_to_object(cfg):
    from omegaconf import OmegaConf
    from omegaconf.errors import OmegaConfBaseException
    missing = sorted(OmegaConf.missing_keys(cfg))
    if missing:
        raise ConfigError("missing config value(s): " + ", ".join(missing)
                          + " (set them on the command line, e.g. key=value)")
    try:
        obj = OmegaConf.to_object(cfg)
    except OmegaConfBaseException as exc:
        raise ConfigError(f"invalid config: {exc}") from None
    config.validate(obj)
    return obj


def composed(overrides=()):
    """The composed DictConfig (before conversion)."""
    return compose_dictconfig(overrides)


def merged(cfg, **changes):
    from omegaconf import OmegaConf
    return OmegaConf.merge(cfg, changes)


def no_name(cfg):
    return merged(cfg, vehicles={"vehicles": [{"off_road": [[0.0, 0.0], [1.0, 1.0]]}]})


def missing_coordinate(cfg):
    return merged(cfg, vehicles={"vehicles": [{"name": "a",
                                               "off_road": [[0.0, "???"], [1.0, 1.0]]}]})


def missing_many(cfg):
    cfg = no_name(cfg)
    cfg.scene.duration_s = "???"
    cfg.sensor.peak_power_w = "???"
    return cfg


def missing_and_invalid(cfg):
    return merged(no_name(cfg), scene={"duration_s": -5.0})


def invalid(cfg):
    return merged(cfg, scene={"duration_s": -5.0})


def interpolation_to_nothing(cfg):
    return merged(cfg, scene={"epoch_utc": "${scene.nowhere}"})


@pytest.mark.parametrize("change", [None, no_name, missing_coordinate, missing_many,
                                    missing_and_invalid, invalid, interpolation_to_nothing])
def test_to_object_fails_and_succeeds_as_before(change):
    cfg = composed(["vehicles=random"] if change is None else [])
    if change is not None:
        cfg = change(cfg)
    expected = outcome(reference_to_object, cfg)
    assert outcome(config.to_object, cfg) == expected
    assert (expected is None) == (change is None)
    if change is missing_many:
        assert expected[1].startswith("missing config value(s): scene.duration_s, "
                                      "sensor.peak_power_w, vehicles.vehicles[0].name")


def test_no_schema_field_is_left_out_of_the_conversion():
    # OmegaConf.to_object skips a missing init=False field that missing_keys would list
    seen, todo = set(), [config.AppConfig]
    while todo:
        cls = todo.pop()
        if cls in seen:
            continue
        seen.add(cls)
        hints = typing.get_type_hints(cls)
        for f in dataclasses.fields(cls):
            assert f.init, f"{cls.__name__}.{f.name}"
            kinds = [hints[f.name], *typing.get_args(hints[f.name])]
            todo += [t for t in kinds if isinstance(t, type) and dataclasses.is_dataclass(t)]
    assert len(seen) > 10


@pytest.mark.parametrize("leaf", ["platform.waypoints_m[0][0]", "platform.waypoints_m[1][1]"])
def test_a_platform_waypoint_beyond_the_magnitude_bound_is_one_clear_error(leaf):
    """The platform's leg and turn checks leave a coordinate beyond MAX_MAGNITUDE to the
    magnitude check: one message, no numpy overflow warning, no turn message about a path that
    only the typo made."""
    import warnings
    cfg = compose([])
    set_leaf(cfg, leaf, 1e300)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ConfigError) as info:
            config.validate(cfg)
    assert str(info.value) == f"invalid config: {leaf}: must be within ±1e+12, got 1e+300"
