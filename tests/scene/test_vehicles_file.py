"""``vehicles.file``: vehicles read from YAML past Hydra (gmtiflow/scene/vehicles_file.py).

The type checks are compared with OmegaConf's own conversion of the same entry merged into the
typed schema (what Hydra does with a vehicles group file): both accept with the same values,
or both refuse.  Then the errors (file, entry, key), the expansion in ``config.to_object``
(``compose``), relative paths, and the stage cache keys.
"""
import dataclasses
import logging
import math
import textwrap
from pathlib import Path

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from omegaconf import OmegaConf

from gmtiflow import config, pipeline
from gmtiflow.compose import compose
from gmtiflow.errors import ConfigError, RoadMapError
from gmtiflow.scene import vehicles_file
from gmtiflow.scene.vehicles_config import VehiclesConfig, VehiclesGroupConfig, VehicleSpec
CONF_DIR = Path(__file__).resolve().parents[2] / "conf"

REFUSED = "refused"


def by_omegaconf(entry):
    """What Hydra makes of ``entry`` in a group file's list: the VehicleSpec, or REFUSED."""
    try:
        merged = OmegaConf.merge(OmegaConf.structured(VehiclesConfig),
                                 OmegaConf.create({"vehicles": [entry]}))
        return OmegaConf.to_object(merged).vehicles[0]
    except Exception:
        return REFUSED


def by_us(entry):
    try:
        return vehicles_file.vehicle(entry)
    except vehicles_file._Refused:
        return REFUSED


def same(a, b) -> bool:
    """Equal dataclasses, value types included (14 and 14.0 differ; NaN equals NaN)."""
    return repr(a) == repr(b) and _types(a) == _types(b)


def agree(ours, theirs) -> bool:
    """``same``, but for OmegaConf's one lapse: it lets a list or mapping into a typed list
    (``position_noise_m: [[1], 2, 3]`` -> ``[[1], 2.0, 3.0]``), which ``problems()`` then
    refuses; the file's loader refuses it at once."""
    if ours is REFUSED and theirs is not REFUSED and any(
            isinstance(v, (list, dict)) for v in theirs.position_noise_m):
        return any(p.key == "position_noise_m" for p in theirs.problems())
    return same(ours, theirs)


def _types(value):
    if isinstance(value, VehicleSpec) or hasattr(value, "__dataclass_fields__"):
        return {k: _types(v) for k, v in vars(value).items()}
    if isinstance(value, list):
        return [_types(v) for v in value]
    if isinstance(value, dict):
        return {k: _types(v) for k, v in value.items()}
    return type(value).__name__


FIELD_CASES = [
    # (field, value): every kind of value against every kind of field
    *[(f, v) for f in ("cruise_speed_mps", "start_speed_mps", "start_time_s")
      for v in (14, 14.5, -3, "14", " 2.5 ", "1e3", "1_000", "nan", "inf", "fast", "", True,
                None, [1.0], {"a": 1}, float("nan"), 10 ** 20)],
    *[(f, v) for f in ("name", "type")
      for v in ("car", 3, 1.5, True, None, [1], {"a": 1}, "", "yes")],
    *[("obey_speed_limits", v) for v in (True, False, 0, 2, "yes", "Off", "y", "N", "1", "0",
                                         "true", "maybe", 1.0, None, [True])],
    *[(f, v) for f in ("start", "end", "at_node")
      for v in ("g_0_0", 123, 1.5, [100.0, 200.0], [[1, 2]], {"x": 1}, None, True)],
    *[(f, v) for f in ("stopovers", "stop_points", "off_road")
      for v in ([], ["a", 3], [[0, 0], [10, 5, 1]], [None], None, "a", 3, {"a": 1})],
    *[("position_noise_m", v) for v in ([1, 2, 3], [1.0, "2", 0.5], [1, None, 2], [True, 1, 2],
                                        [[1], 2, 3], None, 1.0, "1,2,3", [])],
    *[("convoy", v) for v in ({"count": 3, "spacing_m": 25}, {"count": "3", "spacing_s": "2"},
                              {"count": 3.0}, {"count": True}, {"count": "three"},
                              {"spacing_m": None}, {"count": None}, {"cont": 2}, None, [], 3)],
    *[("speed_changes", v) for v in ([{"at": "g_1_1", "cruise_speed_mps": 5}],
                                     [{"at": [1, 2], "cruise_speed_mps": "7.5"}],
                                     [{"at": "x", "speed": 5}], [None], ["x"], None,
                                     {"at": "x"}, [{"cruise_speed_mps": "slow"}])],
    ("colour", "red"),            # unknown key
]


@pytest.mark.parametrize("field, value", FIELD_CASES, ids=repr)
def test_each_kind_of_value_is_converted_or_refused_as_omegaconf_does(field, value):
    entry = {"name": "v1", field: value}
    ours, theirs = by_us(entry), by_omegaconf(entry)
    assert agree(ours, theirs), (ours, theirs)


def test_the_cases_include_both_answers():
    """The comparison above is not vacuous: OmegaConf accepts some and refuses others."""
    answers = [by_omegaconf({"name": "v1", f: v}) is REFUSED for f, v in FIELD_CASES]
    assert 20 < sum(answers) < len(answers) - 20


SCALAR_TEXTS = ["14", "14.0", "-3", "1e3", "1.5e-3", "1_000", "0x1F", "0o17", "017", "+5",
                ".5", "1.", ".inf", "-.inf", ".nan", "1:30", "190:20:30.15", "yes", "No", "on",
                "off", "y", "true", "False", "null", "~", "2001-12-14", "2001-12-14t21:59:43.10-05:00",
                "'14'", '"1e3"', "''", "car", "g_0_0", "[1, 2]", "{a: 1}", "!!str 12",
                "!!float 3", "!!int '7'", "0b101", "1,000", "inf", "NaN"]


@pytest.mark.parametrize("text", SCALAR_TEXTS)
@pytest.mark.parametrize("field", ["cruise_speed_mps", "name", "obey_speed_limits", "start",
                                   "start_speed_mps"])
def test_yaml_scalars_read_as_hydra_reads_them(field, text):
    """The same YAML text through our loader and OmegaConf's (a group file's route)."""
    doc = f"vehicles:\n  - name: v1\n    {field}: {text}\n"
    if field == "name":
        doc = f"vehicles:\n  - name: {text}\n"
    try:
        entry = vehicles_file.parse(doc.encode())["vehicles"][0]
        ours = by_us(entry)
    except ConfigError:
        ours = REFUSED
    try:
        loaded = OmegaConf.create(doc)
        merged = OmegaConf.merge(OmegaConf.structured(VehiclesConfig), loaded)
        theirs = OmegaConf.to_object(merged).vehicles[0]
    except Exception:
        theirs = REFUSED
    assert agree(ours, theirs), (ours, theirs)


scalars = st.one_of(
    st.none(), st.booleans(), st.integers(-2 ** 62, 2 ** 62),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from(["1", "1.5", " 2 ", "1e3", "1_0", "nan", "-inf", "yes", "off", "0", "N",
                     "fast", "", "car", "g_0_0", "1.5.2", "0x10", "True"]),
    st.text(max_size=6).filter(lambda s: "${" not in s and s != "???"))
values = st.one_of(scalars, st.lists(scalars, max_size=4),
                   st.lists(st.lists(scalars, max_size=3), max_size=3),
                   st.dictionaries(st.sampled_from(["at", "count", "x", "cruise_speed_mps",
                                                    "spacing_m", "spacing_s"]), scalars,
                                   max_size=3))
field_names = st.sampled_from([f for f in VehicleSpec.__dataclass_fields__] + ["bogus"])
entries = st.dictionaries(field_names, values, max_size=6).map(lambda d: {"name": "v", **d})


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(entries)
def test_random_entries_are_converted_or_refused_as_omegaconf_does(entry):
    ours, theirs = by_us(entry), by_omegaconf(entry)
    assert agree(ours, theirs), (entry, ours, theirs)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(entries)
def test_random_entries_through_yaml_read_as_hydra_reads_them(entry):
    text = yaml.safe_dump({"vehicles": [entry]})
    ours = by_us(vehicles_file.parse(text.encode())["vehicles"][0])
    try:
        merged = OmegaConf.merge(OmegaConf.structured(VehiclesConfig), OmegaConf.create(text))
        theirs = OmegaConf.to_object(merged).vehicles[0]
    except Exception:
        theirs = REFUSED
    assert agree(ours, theirs), (text, ours, theirs)


@pytest.mark.parametrize("value", ["???", "${seed}", "a${b}"])
def test_missing_and_interpolations_are_refused(value):
    """OmegaConf would keep the default for ``???`` merged into a field, or resolve
    ``${...}`` against the config: neither means anything in a plain vehicles file."""
    for field in ("cruise_speed_mps", "name", "start", "obey_speed_limits"):
        with pytest.raises(vehicles_file._Refused, match=f"vehicle.{field}"):
            vehicles_file.vehicle({"name": "v", field: value})


def test_the_loader_falls_back_to_pure_python_without_libyaml(monkeypatch):
    text = (CONF_DIR / "vehicles" / "default.yaml").read_bytes() + b"extra: [1e3, 2001-12-14]\n"
    fast = vehicles_file.parse(text)
    vehicles_file._loader.cache_clear()
    monkeypatch.delattr(yaml, "CSafeLoader")
    try:
        assert "CSafeLoader" not in [c.__name__ for c in vehicles_file._loader().__mro__]
        assert repr(vehicles_file.parse(text)) == repr(fast)
    finally:
        vehicles_file._loader.cache_clear()
    assert fast["extra"] == [1000.0, "2001-12-14"]     # OmegaConf's resolvers, not YAML 1.1's


def test_yaml_aliases_give_separate_lists(tmp_path):
    path = tmp_path / "v.yaml"
    path.write_text(textwrap.dedent("""\
        vehicles:
          - {name: a, start: g_0_0, end: g_6_2, position_noise_m: &pn [1, 1, 0.1],
             stopovers: &st [[5, 5]]}
          - {name: b, start: g_0_0, end: g_6_2, position_noise_m: *pn, stopovers: *st}
        """))
    a, b = vehicles_file.load(str(path))
    assert a.position_noise_m == b.position_noise_m == [1.0, 1.0, 0.1]
    assert a.position_noise_m is not b.position_noise_m
    assert a.stopovers[0] is not b.stopovers[0]


# --- errors ----------------------------------------------------------------------------------

def write(tmp_path, text, name="big.yaml"):
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


def compose_file(path, *more):
    return compose(["vehicles=file", f"vehicles.file={path}", *more])


@pytest.mark.parametrize("text, needle", [
    ("vehicles:\n  - {name: a, start: g_0_0, end: g_6_2}\n  - {name: b, cruise_speed_mps: fast}\n",
     ": vehicles[1].cruise_speed_mps: expected a number, got 'fast'"),
    ("vehicles:\n  - {name: a, convoy: {count: 2.5}}\n",
     ": vehicles[0].convoy.count: expected an integer, got 2.5"),
    ("vehicles:\n  - {name: a, speed_changes: [{at: x, cruise_speed: 3}]}\n",
     ": vehicles[0].speed_changes[0]: unknown key 'cruise_speed' (did you mean "
     "'cruise_speed_mps'?)"),
    ("vehicles:\n  - {name: a, position_noise_m: [1, null, 2]}\n",
     ": vehicles[0].position_noise_m[1]: must not be null"),
    ("vehicles:\n  - just-a-name\n",
     ": vehicles[0]: expected a mapping of VehicleSpec fields, got 'just-a-name'"),
    ("vehicles:\n  - {name: a, start: g_0_0\n", ": line 3, column 1: "),
    ("vehicles:\n  - name: a\n    name: b\n", ": line 3, column 5: while constructing a "
                                               "mapping, found duplicate key name"),
    ("vehicles: []\n---\nvehicles: []\n", ": line 2, column 1: "),
    ("", ": expected a mapping with a 'vehicles' list, got an empty file"),
    ("[1, 2]\n", ": expected a mapping with a 'vehicles' list, got a list"),
    ("vehicle: []\n", ": unknown top-level key 'vehicle'"),
    ("random: {count: 0}\n", ": no 'vehicles' list"),
    ("vehicles: {name: a}\n", ": vehicles: expected a list of vehicles, got a mapping"),
    ("vehicles: []\nrandom: {count: 5}\n", ": random.count: a vehicles file brings no random "
                                           "fleet (got count 5)"),
    ("vehicles: []\nrandom: {count: 0, typos: {}}\n", ": random: unknown key 'typos'"),
    (b"\xff\xfe\x00\x00junk", ": "),
])
def test_bad_files_are_one_error_naming_file_entry_and_key(tmp_path, text, needle):
    path = tmp_path / "big.yaml"
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    with pytest.raises(ConfigError) as err:
        compose_file(path)
    message = str(err.value)
    assert message.startswith(f"vehicles.file {path}: "), message
    assert needle in message, message
    assert "\n" not in message


def test_problems_found_after_reading_name_the_file_and_its_entry(tmp_path):
    path = write(tmp_path, """\
        vehicles:
          - {name: a, start: g_0_0, end: g_6_2}
          - {name: b, start: g_0_0, end: g_6_2, cruise_speed_mps: -3}
          - {name: a, start: g_0_0, end: g_6_2, convoy: {count: 2}}
        """)
    with pytest.raises(ConfigError) as err:
        compose_file(path)
    message = str(err.value)
    assert f"vehicles.file {path}: vehicles[1].cruise_speed_mps: must be" in message
    assert f"vehicles.file {path}: vehicles[2].name: vehicle name 'a' is used twice" in message
    assert f"vehicles.file {path}: vehicles[2].convoy.spacing_m: give exactly one" in message
    assert "vehicles.vehicles[" not in message


def test_missing_path_and_directory_and_no_path(tmp_path):
    with pytest.raises(ConfigError, match=f"^vehicles.file {tmp_path}/nope.yaml: no such file$"):
        compose_file(tmp_path / "nope.yaml")
    with pytest.raises(ConfigError, match="is a directory"):
        compose_file(tmp_path)
    with pytest.raises(ConfigError, match="^vehicles.file: no file given"):
        compose(["vehicles=file"])


def test_a_device_or_an_oversized_file_is_refused_unread(tmp_path, monkeypatch):
    """``vehicles.file=/dev/zero`` used to be read without end (the run hung, its memory
    growing); like the other loaders, only a regular file within a size cap is read."""
    import time
    start = time.process_time()
    with pytest.raises(ConfigError, match="^vehicles.file /dev/zero: not a regular file"):
        vehicles_file.load("/dev/zero")
    assert time.process_time() - start < 1.0
    big = tmp_path / "big.yaml"
    with open(big, "wb") as f:                  # sparse: costs no disk
        f.truncate(vehicles_file.MAX_FILE_BYTES + 1)
    with pytest.raises(ConfigError, match=f"^vehicles.file {big}: .* over the 256 MiB"):
        vehicles_file.load(str(big))
    small = tmp_path / "small.yaml"
    small.write_text("vehicles: []\n" + "#" * 10_000)
    monkeypatch.setenv("GMTIFLOW_MEMORY_BYTES", "100000")     # parsing needs ~50x the size
    with pytest.raises(ConfigError, match=f"^vehicles.file {small}: reading .* of memory"):
        vehicles_file.load(str(small))


def test_a_file_beside_listed_vehicles_is_refused(tmp_path):
    """The default group lists the town's vehicles: the file's list would silently join them."""
    path = write(tmp_path, "vehicles: []\n")
    with pytest.raises(ConfigError, match="also lists 8 vehicle.*vehicles=file vehicles.file="):
        compose([f"vehicles.file={path}"])


# --- expansion -------------------------------------------------------------------------------

def test_a_group_file_as_vehicles_file_gives_the_same_config(tmp_path):
    """conf/vehicles/default.yaml works as is (its random: has count 0); the result is the
    plain AppConfig of vehicles=default: same vehicles, same /config text, same cache keys."""
    group = compose([])
    from_file = compose_file(CONF_DIR / "vehicles" / "default.yaml")
    assert type(from_file) is config.AppConfig and type(from_file.vehicles) is VehiclesConfig
    assert not hasattr(from_file.vehicles, "file")
    assert from_file.vehicles == group.vehicles
    assert config.to_yaml(from_file) == config.to_yaml(group)
    assert pipeline.stage_keys(from_file) == pipeline.stage_keys(group)


def test_configs_without_the_file_convert_as_before():
    cfg = compose(["vehicles=random"])
    assert type(cfg) is config.AppConfig and type(cfg.vehicles) is VehiclesConfig
    assert list(yaml.safe_load(config.to_yaml(cfg))["vehicles"]) == ["vehicles", "random"]
    assert config.to_yaml(cfg) == OmegaConf.to_yaml(OmegaConf.structured(cfg))


def test_the_random_fleet_of_the_config_still_applies(tmp_path):
    path = write(tmp_path, "vehicles:\n  - {name: a, start: g_0_0, end: g_6_2}\n")
    cfg = compose_file(path, "vehicles.random.count=7")
    assert [v.name for v in cfg.vehicles.vehicles] == ["a"]
    assert cfg.vehicles.random.count == 7


def test_a_relative_path_is_read_from_the_working_directory(tmp_path, monkeypatch):
    (tmp_path / "sub").mkdir()
    write(tmp_path / "sub", "vehicles:\n  - {name: rel, start: g_0_0, end: g_6_2}\n")
    monkeypatch.chdir(tmp_path)
    assert [v.name for v in compose_file("sub/big.yaml").vehicles.vehicles] == ["rel"]
    with pytest.raises(ConfigError, match=f"vehicles.file {tmp_path}/big.yaml: no such file"):
        compose_file("big.yaml")


def test_expand_keeps_a_plain_group_and_drops_the_file_key(tmp_path):
    plain = VehiclesConfig()
    assert vehicles_file.expand(plain) == (plain, None)
    group = VehiclesGroupConfig(vehicles=[VehicleSpec(name="x", start="a", end="b")])
    got, path = vehicles_file.expand(group)
    assert type(got) is VehiclesConfig and got.vehicles == group.vehicles and path is None
    write(tmp_path, "vehicles:\n  - {name: y, start: a, end: b}\n")
    got, path = vehicles_file.expand(VehiclesGroupConfig(file="big.yaml"), str(tmp_path))
    assert path == str(tmp_path / "big.yaml") and [v.name for v in got.vehicles] == ["y"]


SMALL = ["scene.duration_s=20", "tracker=none", "metrics.enabled=false", "report=none",
         "export=none", "progress=false"]


def test_cache_keys_follow_the_file_content_not_its_path(tmp_path, caplog):
    """Edit the file, keep its path: the truth is computed again, not served from the cache."""
    caplog.set_level(logging.INFO, logger="gmtiflow")
    cache = [f"cache.dir={tmp_path / 'cache'}"]
    path = write(tmp_path, "vehicles:\n  - {name: a, start: g_0_0, end: g_6_2}\n")
    first = compose_file(path, *SMALL, *cache)
    pipeline.run(first, tmp_path / "r1")
    assert "cache miss truth" in caplog.text
    caplog.clear()
    pipeline.run(compose_file(path, *SMALL, *cache), tmp_path / "r2")
    assert "cache hit truth" in caplog.text and "cache miss truth" not in caplog.text
    caplog.clear()
    write(tmp_path, "vehicles:\n  - {name: a, start: g_0_0, end: g_6_2, cruise_speed_mps: 9}\n")
    edited = compose_file(path, *SMALL, *cache)
    assert pipeline.stage_keys(edited)["truth"] != pipeline.stage_keys(first)["truth"]
    pipeline.run(edited, tmp_path / "r3")
    assert "cache miss truth" in caplog.text and "cache hit truth" not in caplog.text
    assert math.isclose(edited.vehicles.vehicles[0].cruise_speed_mps, 9.0)


def test_vehicles_starting_after_the_scene_are_named_in_one_warning(tmp_path, caplog):
    """A vehicles file reused for a shorter scene is accepted, with one warning naming the file
    and each late entry (index, name, start time): those vehicles never appear."""
    path = write(tmp_path, """\
        vehicles:
          - {name: a, start: g_0_0, end: g_6_2}
          - {name: late, start: g_0_0, end: g_6_2, start_time_s: 500}
          - {name: edge, start: g_0_0, end: g_6_2, start_time_s: 60}
          - {name: later, start: g_0_0, end: g_6_2, start_time_s: 61.5}
        """)
    caplog.set_level(logging.WARNING, logger="gmtiflow")
    cfg = compose_file(path, "scene.duration_s=60")
    assert [v.name for v in cfg.vehicles.vehicles] == ["a", "late", "edge", "later"]
    (record,) = [r for r in caplog.records if r.levelno == logging.WARNING]
    message = record.getMessage()
    assert message.startswith(f"vehicles.file {path}: 2 vehicle(s) start after the scene's end"), \
        message
    assert "scene.duration_s = 60 s" in message
    assert "vehicles[1] 'late' at 500 s" in message and "vehicles[3] 'later' at 61.5 s" in message
    assert "'edge'" not in message          # at the last instant: it appears there
    caplog.clear()
    compose_file(path, "scene.duration_s=600")
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING]


def test_listed_vehicles_starting_after_the_scene_are_named_by_key(caplog):
    caplog.set_level(logging.WARNING, logger="gmtiflow")
    compose(["scene.duration_s=60", "vehicles.vehicles.2.start_time_s=90"])
    (record,) = [r for r in caplog.records if r.levelno == logging.WARNING]
    assert record.getMessage().startswith("vehicles.vehicles: 1 vehicle(s) start after the "
                                          "scene's end (scene.duration_s = 60 s)")
    assert "vehicles[2] " in record.getMessage()


@pytest.mark.parametrize("lo, hi, share", [(0, 120, "50%"), (70, 80, "all")])
def test_a_random_fleet_starting_after_the_scene_is_warned_of(caplog, lo, hi, share):
    caplog.set_level(logging.WARNING, logger="gmtiflow")
    compose(["vehicles=random", "vehicles.random.count=5", "scene.duration_s=60",
             f"vehicles.random.start_time_min_s={lo}", f"vehicles.random.start_time_max_s={hi}"])
    (record,) = [r for r in caplog.records if r.levelno == logging.WARNING]
    message = record.getMessage()
    assert message.startswith(f"vehicles.random.start_time_max_s = {hi} s is after the scene's "
                              f"end (scene.duration_s = 60 s)"), message
    assert f"{share} of the random vehicles" in message
    caplog.clear()
    compose(["vehicles=random", "vehicles.random.count=5", "scene.duration_s=60",
             "vehicles.random.start_time_max_s=60"])
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING]


@pytest.mark.parametrize("entry, error, why", [
    ("{name: b, start: g_0_0, end: nowhere}", RoadMapError, "unknown node 'nowhere'"),
    ("{name: b, start: g_0_0, end: g_6_2, stop_points: [hw_x3000]}", RoadMapError,
     "node 'hw_x3000' is not on the vehicle's route"),
    ("{name: b, start: g_0_0, end: g_6_2, speed_changes: [{at: c_1, cruise_speed_mps: 5}]}",
     RoadMapError, "node 'c_1' is not on the vehicle's route"),
    ("{name: b, start: g_0_0, end: g_6_2, start_speed_mps: 0, convoy: {count: 2, spacing_s: 2}}",
     ConfigError, "convoy spacing_s with a zero start speed gives no gap"),
    ("{name: b, off_road: [[5, 5], [5, 5]]}", RoadMapError, "off_road waypoints all coincide"),
])
def test_errors_building_the_fleet_name_the_file_and_the_entry(tmp_path, entry, error, why):
    """Route and convoy problems are found when the fleet is built (they need the road map),
    after the config is converted: they used to name the vehicle only ("vehicle 'b': ...")."""
    from gmtiflow.scene.roadmap import load_roadmap
    from gmtiflow.scene.vehicles import build_fleet
    path = write(tmp_path, f"vehicles:\n  - {{name: a, start: g_0_0, end: g_6_2}}\n  - {entry}\n")
    cfg = compose_file(path, "scene.duration_s=60")
    with pytest.raises(error) as err:
        build_fleet(cfg.vehicles, load_roadmap(cfg.roadmap), seed=1, duration_s=60.0, dt_s=1.0)
    message = str(err.value)
    assert message.startswith(f"vehicles.file {path}: vehicles[1] (vehicle 'b'): "), message
    assert why in message and "\n" not in message


def test_errors_building_the_fleet_name_the_listed_entry_by_key():
    from gmtiflow.scene.roadmap import load_roadmap
    from gmtiflow.scene.vehicles import build_fleet
    cfg = compose(["vehicles.vehicles.2.end=nowhere"])
    with pytest.raises(RoadMapError) as err:
        build_fleet(cfg.vehicles, load_roadmap(cfg.roadmap), seed=1, duration_s=60.0, dt_s=1.0)
    name = cfg.vehicles.vehicles[2].name
    assert str(err.value).startswith(f"vehicles.vehicles[2] (vehicle {name!r}): "), err.value
    assert cfg.vehicles.source_file is None


def test_the_file_of_the_vehicles_is_no_config_key(tmp_path):
    """The path travels beside the config, not in it: /config and the cache keys as before."""
    path = write(tmp_path, "vehicles:\n  - {name: a, start: g_0_0, end: g_6_2}\n")
    cfg = compose_file(path)
    assert cfg.vehicles.source_file == str(path)
    assert "source_file" not in config.to_yaml(cfg)
    assert "source_file" not in {f.name for f in dataclasses.fields(cfg.vehicles)}


def test_a_cli_run_names_the_file_and_entry_of_an_impossible_route(tmp_path):
    import os
    import subprocess
    import sys
    write(tmp_path, "vehicles:\n  - {name: a, start: g_0_0, end: g_6_2}\n"
                    "  - {name: b, start: g_0_0, end: nowhere}\n")
    proc = subprocess.run(
        [sys.executable, "-m", "gmtiflow.cli", f"hydra.run.dir={tmp_path / 'run'}",
         "vehicles=file", "vehicles.file=big.yaml", "scene.duration_s=60", "tracker=none",
         "report=none", "export=none", "cache.enabled=false"],
        cwd=tmp_path, capture_output=True, text=True, timeout=300,
        env=dict(os.environ, HYDRA_FULL_ERROR="0"))
    assert proc.returncode == 1
    (line,) = proc.stderr.splitlines()
    assert f"vehicles.file {tmp_path / 'big.yaml'}: vehicles[1] (vehicle 'b'): " in line, line
    assert not list(tmp_path.rglob("*.h5"))
