"""/config text: ``config.to_yaml`` writes what OmegaConf's structured round trip writes, and
``gmtiflow.config_yaml`` (its fast writer) exactly what PyYAML writes, or nothing."""
import math
import sys
from pathlib import Path

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from omegaconf import OmegaConf
from omegaconf.errors import GrammarParseError

from gmtiflow import config, config_yaml
from gmtiflow.compose import compose, compose_dictconfig
from gmtiflow.scene.vehicles import VehicleSpec, VehiclesConfig


@pytest.mark.parametrize("overrides", [[], ["experiment=two_orbits"],
                                       ["experiment=challenge/offroad", "fidelity=fast"]])
def test_to_yaml_is_omegaconfs_text(overrides):
    cfg = compose(overrides)
    assert config.to_yaml(cfg) == OmegaConf.to_yaml(OmegaConf.structured(cfg))


def test_to_yaml_of_listed_vehicles_and_enums():
    cfg = compose(["fidelity=full"])
    cfg.vehicles = VehiclesConfig(vehicles=[
        VehicleSpec(name=f"v{i}", off_road=[[0.0, 0.0], [100.0 * i + 1, 5.0]]) for i in range(5)])
    text = config.to_yaml(cfg)
    assert text == OmegaConf.to_yaml(OmegaConf.structured(cfg))
    assert "dwell_mode: dwell_resolved" in text and "name: v4" in text


def test_to_yaml_quotes_and_wraps_as_omegaconf_does():
    # to_yaml emits with libyaml (when PyYAML has it), OmegaConf with the pure-Python emitter:
    # names that read as bools or numbers, non-ASCII, long and odd strings, tiny and huge floats.
    cfg = compose([])
    names = ["yes", "1.5", "10", "1e5", "null", "~", "héllo ✓", "a: b", "#c", " lead", "'q'",
             "x" * 200, "word " * 40]
    cfg.vehicles = VehiclesConfig(vehicles=[
        VehicleSpec(name=n, off_road=[[1e-300, -0.0], [1e300, 123456789.123456789]])
        for n in names])
    text = config.to_yaml(cfg)
    assert text == OmegaConf.to_yaml(OmegaConf.structured(cfg))
    assert "name: 'yes'" in text and "name: héllo ✓" in text


# --- gmtiflow.config_yaml: the text PyYAML writes, without PyYAML's per-node representer -------

CONF = Path(__file__).resolve().parents[1] / "conf"


def fast_text(tree):
    """config_yaml's own text of ``tree``, or None where it leaves the document to PyYAML."""
    return config_yaml.dump(tree, config._resolves_as_str)


def group_options():
    """``group=option`` for every option file of the shipped config groups."""
    for group in sorted(p for p in CONF.iterdir() if p.is_dir() and p.name not in ("hydra",
                                                                                    "bench")):
        for path in sorted(group.rglob("*.yaml")):
            yield f"{group.name}={path.relative_to(group).with_suffix('').as_posix()}"


NEEDS_A_VALUE = {"platform=trajectory": "platform.path=/data/log.csv",
                 "roadmap=geojson": "roadmap.path=/data/map.geojson",
                 "roadmap=osm": "roadmap.path=/data/map.osm",
                 "tracker=python": "tracker.target=mypackage.MyTracker",
                 "vehicles=file": f"vehicles.file={CONF / 'vehicles' / 'default.yaml'}"}
"""Options that need a path or a name (validation checks only that one is given; a vehicles
file is read when the config is converted: the shipped default group file, as a file)."""


@pytest.mark.slow
@pytest.mark.parametrize("option", sorted(group_options()))
def test_every_shipped_option_is_written_as_pyyaml_writes_it(option):
    cfg = compose([option] + ([NEEDS_A_VALUE[option]] if option in NEEDS_A_VALUE else []))
    assert fast_text(cfg) is not None        # no fallback: the fast writer is what runs
    assert config.to_yaml(cfg) == config.pyyaml_text(cfg)


def test_shipped_options_are_found():
    options = set(group_options())
    assert {"sensor=wide_fov", "experiment=challenge/offroad", "vehicles=random"} <= options
    assert len(options) > 40


@pytest.mark.parametrize("overrides", [[], ["experiment=monaco"], ["vehicles=random",
                                       "clutter=windfarm", "export=stream", "terrain=hills"]])
def test_composed_configs_are_written_as_pyyaml_writes_them(overrides):
    cfg = compose(overrides)
    assert fast_text(cfg) is not None
    assert config.to_yaml(cfg) == config.pyyaml_text(cfg)


def test_the_peer_benchmarks_listed_vehicles_are_written_as_pyyaml_writes_them():
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    try:
        from stonesoup_peer import peer_vehicles
    finally:
        sys.path.pop(0)
    cfg = compose(["fidelity=fast", "scene.duration_s=600"])
    cfg.vehicles = peer_vehicles(50, 600.0)
    text = fast_text(cfg)
    assert text is not None and text == config.pyyaml_text(cfg)
    assert "  - - -3" in text                   # waypoints written as rows of the list


AWKWARD_STRINGS = [
    "", " ", "yes", "No", "on", "OFF", "y", "true", "1.5", "10", "-3", "+4", "1e5", "1E-5", ".5",
    "0x1F", "0o17", "0b101", "1_000", "1,000", "null", "Null", "NULL", "~", "2026-06-01",
    "2026-06-01T08:00:00Z", "2026-06-01 08:00:00", "12:30", "1:20:30.5", ".inf", "-.Inf",
    ".NaN", "nan", "inf", "=", "<<", " lead", "trail ", "a: b", "a:b", "a:", ":a", ": a", "#c",
    "a #c", "a#c", "'q'", "it's", 'say "hi"', "- x", "-x", "-", "--", "---", "--- x", "...",
    "..x", "?x", "? x", "?", "[a]", "{a}", "a,b", "&a", "*a", "!a", "|a", ">a", "%a", "@a", "`a",
    "back\\slash", "a  b", "x" * 200, "word " * 40, "a " * 39 + "b", "héllo ✓", "line\nbreak",
    "trail\n", "tab\there", "\x85", "\u2028", "\ufeff", "\x7f", "\x00", "é" * 90,
    "udp://127.0.0.1:4607", "../shared/data/map.osm", "GMTIFLOW"]
AWKWARD_NUMBERS = [0, 1, -1, 2 ** 63, -(2 ** 80), 0.0, -0.0, 1.0, 1e-7, 1e16, 1e17, -1e22, 1e300,
                   5e-324, 123456789.123456789, 0.1 + 0.2, math.inf, -math.inf, math.nan, True,
                   False, None]

ONE_LINE_ASCII = "".join(map(chr, range(32, 127)))
numbers = st.one_of(st.floats(), st.integers(), st.sampled_from(AWKWARD_NUMBERS[:-3]))


def plain_trees(strings, keys, max_leaves=25):
    """Nested dicts, lists and tuples of scalars, and lists of equally long number lists."""
    scalars = st.one_of(strings, numbers, st.none(), st.booleans())
    rows = st.integers(1, 3).flatmap(
        lambda k: st.lists(st.lists(numbers, min_size=k, max_size=k), max_size=5))
    inner = st.recursive(st.one_of(scalars, rows),
                         lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                 st.tuples(inner, inner),
                                                 st.dictionaries(keys, inner, max_size=4)),
                         max_leaves=max_leaves)
    return st.dictionaries(keys, inner, max_size=6)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(plain_trees(st.one_of(st.sampled_from(AWKWARD_STRINGS), st.text(max_size=12),
                             st.text(alphabet=ONE_LINE_ASCII, max_size=90)),
                   st.one_of(st.sampled_from(AWKWARD_STRINGS), st.text(max_size=8))))
def test_plain_data_is_written_as_pyyaml_writes_it_or_left_to_pyyaml(tree):
    text = fast_text(tree)
    if text is not None:
        assert text == config.pyyaml_text(tree)


SHORT_ASCII = st.text(alphabet=ONE_LINE_ASCII, max_size=12)


ONE_LINE_ASCII_TREES = plain_trees(
    st.one_of(st.sampled_from([s for s in AWKWARD_STRINGS if len(s) <= 12
                               and all(" " <= c <= "~" for c in s)]), SHORT_ASCII),
    st.one_of(SHORT_ASCII.filter(bool), st.sampled_from(["a", "yes", "1.5"])), max_leaves=12)
"""Nesting <= 12 levels, keys and strings <= 12 characters: no string reaches column 80, where
PyYAML would fold it, so the fast writer always writes these."""


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(ONE_LINE_ASCII_TREES)
def test_one_line_ascii_data_is_written_as_pyyaml_writes_it(tree):
    text = fast_text(tree)
    assert text is not None and text == config.pyyaml_text(tree)


@pytest.mark.parametrize("value", AWKWARD_STRINGS + AWKWARD_NUMBERS)
@pytest.mark.parametrize("where", ["value", "key", "item", "deep"])
def test_each_awkward_value_in_each_place(value, where):
    if where == "key" and not isinstance(value, str):
        return
    tree = {"value": {"k": value}, "key": {value: 1.5}, "item": {"k": [value, "x"]},
            "deep": {"a": [[{"b": [value]}], {}, []]}}[where]
    text = fast_text(tree)
    if text is not None:
        assert text == config.pyyaml_text(tree)
    one_line_ascii = isinstance(value, str) and all(" " <= c <= "~" for c in value)
    short = isinstance(value, str) and (" " not in value or len(value) < 50)
    key_ok = where != "key" or 0 < len(value) <= config_yaml.MAX_KEY
    if not isinstance(value, str) or (one_line_ascii and short and key_ok):
        assert text is not None, "written by PyYAML although config_yaml covers it"


@pytest.mark.parametrize("value", [1e-7, 1e16, -0.0, 5e-324, 1e300, math.inf, -math.inf, math.nan,
                                   0.1, -2.5e-12])
def test_float_text_is_pyyamls(value):
    pyyaml = yaml.dump(value, Dumper=config._yaml_dumper()).split()[0]
    assert config_yaml.float_text(value) == pyyaml


def test_values_pyyaml_writes_as_objects_are_left_to_it():
    import numpy as np
    for odd in (np.float64(1.5), np.int64(3), Path("x"), {1: "int key"}, b"bytes", 1j):
        assert fast_text({"k": odd}) is None


def test_enum_keys_are_written_by_name_once():
    from gmtiflow.config import DwellMode
    tree = {"modes": {DwellMode.instant_scan: 1, "instant_scan": 2, DwellMode.dwell_resolved: 3}}
    assert fast_text(tree) == config.pyyaml_text(tree) == "modes:\n  instant_scan: 2\n  dwell_resolved: 3\n"


def record_lists(strings, keys, depth=2):
    """Lists of two or more dicts with the same keys, each key's values of one kind across
    the list (floats, strings, number lists, rows, nested dicts or record lists with the same
    keys) or of any kind: what the writer writes field by field across the list."""
    scalars = st.one_of(strings, numbers, st.none(), st.booleans())
    kinds = [st.floats(), strings, scalars, st.lists(numbers, max_size=3),
             st.integers(1, 3).flatmap(lambda k: st.lists(
                 st.lists(numbers, min_size=k, max_size=k), max_size=3)),
             plain_trees(strings, keys, max_leaves=4)]
    if depth:
        kinds.append(record_lists(strings, keys, depth - 1))
    same_keys = st.lists(keys, min_size=1, max_size=3, unique=True).map(
        lambda ks: st.fixed_dictionaries({k: st.floats() | scalars for k in ks}))
    column = st.one_of(st.sampled_from(kinds), same_keys)
    return st.lists(keys, min_size=1, max_size=4, unique=True).flatmap(
        lambda ks: st.tuples(*[column for _ in ks]).flatmap(
            lambda columns: st.lists(st.fixed_dictionaries(dict(zip(ks, columns))),
                                     min_size=2, max_size=4)))


RECORD_TREES = st.dictionaries(SHORT_ASCII.filter(bool), record_lists(
    st.one_of(st.sampled_from([s for s in AWKWARD_STRINGS if len(s) <= 12
                               and all(" " <= c <= "~" for c in s)]), SHORT_ASCII),
    st.one_of(SHORT_ASCII.filter(bool), st.sampled_from(["a", "yes", "1.5", "b"]))),
    min_size=1, max_size=2)
"""Short one-line ASCII strings and keys, little nesting: the fast writer writes them all."""


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(RECORD_TREES)
def test_lists_of_records_are_written_as_pyyaml_writes_them(tree):
    text = fast_text(tree)
    assert text is not None and text == config.pyyaml_text(tree)
    sorted_text, expected = fast_sorted_text(tree), omegaconf_sorted_text(tree)
    assert sorted_text is not None and (expected is None or sorted_text == expected)


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.dictionaries(st.sampled_from(AWKWARD_STRINGS), record_lists(
    st.one_of(st.sampled_from(AWKWARD_STRINGS), st.text(max_size=8),
              st.text(alphabet=ONE_LINE_ASCII, max_size=90)),
    st.one_of(st.sampled_from(AWKWARD_STRINGS), st.text(max_size=8))), max_size=2))
def test_lists_of_awkward_records_are_written_as_pyyaml_writes_them_or_left_to_it(tree):
    text = fast_text(tree)
    if text is not None:
        assert text == config.pyyaml_text(tree)


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.builds(
    VehicleSpec, name=st.sampled_from(AWKWARD_STRINGS), type=SHORT_ASCII,
    cruise_speed_mps=st.one_of(st.floats(), st.sampled_from(AWKWARD_NUMBERS)),
    start=st.one_of(st.none(), SHORT_ASCII, st.lists(numbers, max_size=2)),
    position_noise_m=st.lists(numbers, max_size=3),
    off_road=st.lists(st.lists(numbers, min_size=2, max_size=3), max_size=4)),
    min_size=2, max_size=4))
def test_vehicle_lists_are_written_as_pyyaml_writes_them(vehicles):
    tree = VehiclesConfig(vehicles=vehicles)
    text = fast_text(tree)
    if text is not None:
        assert text == config.pyyaml_text(tree)


def test_many_repeated_waypoints_are_written_as_pyyaml_writes_them():
    # a lapped route repeats its corners: each distinct value's text is made once
    laps = [[1e-7, -2.5], [1e16, 3.0], [0.1 + 0.2, 123456789.123456789]] * 40
    for extra in ([], [[0.0, 1.0]], [[-0.0, 1.0]], [[math.nan, math.inf]]):
        tree = VehiclesConfig(vehicles=[VehicleSpec(name=f"v{i}", off_road=laps + extra)
                                        for i in range(3)])
        text = fast_text(tree)
        assert text is not None and text == config.pyyaml_text(tree)
        assert fast_text({"k": laps + extra}) == config.pyyaml_text({"k": laps + extra})


@pytest.mark.parametrize("zeros", [[0.0] * 100, [-0.0] * 100, [0.0] * 99 + [-0.0],
                                   [-0.0] + [0.0] * 99])
def test_many_repeated_zeros_are_written_with_their_sign(zeros):
    # a field that is zero in every vehicle is written once, unless zeros of both signs
    values = zeros + [1.5] * 10
    tree = {"k": values, "rows": [[z, 1.0] for z in values]}
    assert fast_text(tree) == config.pyyaml_text(tree)
    tree = VehiclesConfig(vehicles=[VehicleSpec(name=f"v{i}", start_time_s=z,
                                                off_road=[[z, 1.0], [2.0, z]])
                                    for i, z in enumerate(values)])
    text = fast_text(tree)
    assert text is not None and text == config.pyyaml_text(tree)
    assert text.count("-0.0") == 3 * sum(math.copysign(1.0, z) < 0 for z in zeros)


@pytest.mark.parametrize("shared", [1.5, 0.0, -0.0, math.nan, math.inf, 1e16, "car", "no", "",
                                    "a: b", None, True, False, 0, 7, [], [1.0], {}])
def test_a_value_every_record_holds_is_written_as_pyyaml_writes_it(shared):
    for rows in ([shared] * 80, [shared] * 79 + [-0.0], [0.0] + [shared] * 79,
                 [shared] * 79 + [shared == 0 and not isinstance(shared, bool)]):
        tree = {"k": [{"a": value, "b": i} for i, value in enumerate(rows)]}
        assert fast_text(tree) == config.pyyaml_text(tree)


@pytest.mark.parametrize("text", ["inf", "Infinity", "nAn", "inf ", "nan\t\n", "inf\x1c", "info",
                                  "t0001", "yes", "null", "1e5", "+inf", "x"])
def test_words_read_as_numbers_as_omegaconf_reads_them(text):
    from omegaconf._utils import is_float, is_int
    assert config._reads_as_number(text) == (is_int(text) or is_float(text))


@given(st.one_of(st.text(alphabet="yYeEsSnNoOtTrRuUfFaAlL ", max_size=6),
                 st.sampled_from(["yes", "Off", "TRUE", "n", "y ", "nO", "oN"])))
def test_bool_words_are_omegaconfs(text):
    from omegaconf._utils import yaml_is_bool
    assert (text in config._YAML_BOOLS) == yaml_is_bool(text)


@given(st.text(alphabet="aAiInNfFtTyY_0.e+- \t\n\x0b\x1c\x85", max_size=10))
def test_strings_read_as_numbers_as_omegaconf_reads_them(text):
    from omegaconf._utils import is_float, is_int
    assert config._reads_as_number(text) == (is_int(text) or is_float(text))


# --- .hydra/config.yaml: OmegaConf.to_yaml of the composed DictConfig (config.omegaconf_text) --

def composed(overrides=()):
    """The composed DictConfig, as the CLI's job gets it."""
    return compose_dictconfig(overrides)


LISTED = ("vehicles.vehicles=[{name: a1, off_road: [[0.0, 0.0], [1500.5, -20.25], [3000, 10]]}, "
          "{name: 'yes', off_road: [[-100, 5.5], [-2000.125, 400.0]], cruise_speed_mps: 8.5}, "
          "{name: b2, start: g_0_0, end: g_6_2, position_noise_m: [1, 0.5, 0.05]}]")


@pytest.mark.parametrize("overrides", [[], ["experiment=monaco"], [LISTED, "fidelity=fast"],
                                       ["vehicles=random", "clutter=windfarm", "export=stream",
                                        "terrain=hills", "experiment=two_orbits"],
                                       ["scene.epoch_utc=${now:%Y}-06-01T08:00:00Z"]])
def test_hydras_config_text_is_omegaconfs(overrides):
    cfg = composed(overrides)
    text = config.omegaconf_text(cfg)
    assert text == OmegaConf.to_yaml(cfg)
    assert config_yaml.dump(OmegaConf.to_container(cfg, enum_to_str=True),
                            config._resolves_as_str, max_key=config_yaml.PYTHON_MAX_KEY) == text
    if overrides and overrides[0] == LISTED:
        assert "  - name: 'yes'\n" in text and "    - - 3000\n      - 10\n" in text


def test_peer_vehicles_config_text_is_omegaconfs():
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    try:
        from stonesoup_peer import peer_vehicles
    finally:
        sys.path.pop(0)
    cfg = OmegaConf.merge(composed(["fidelity=fast"]),
                          {"vehicles": config._plain(peer_vehicles(30, 600.0))})
    assert config.omegaconf_text(cfg) == OmegaConf.to_yaml(cfg)


def omegaconf_create(tree):
    try:
        return OmegaConf.create(tree)
    except Exception:           # noqa: BLE001 - trees OmegaConf refuses are not configs
        return None


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.one_of(ONE_LINE_ASCII_TREES, RECORD_TREES, plain_trees(
    st.one_of(st.sampled_from(AWKWARD_STRINGS), st.text(max_size=12),
              st.text(alphabet=ONE_LINE_ASCII, max_size=90)),
    st.one_of(st.sampled_from(AWKWARD_STRINGS), st.text(alphabet=ONE_LINE_ASCII, min_size=1,
                                                        max_size=8)))))
def test_config_text_of_plain_data_is_omegaconfs(tree):
    cfg = omegaconf_create(tree)
    if cfg is not None:
        try:
            expected = OmegaConf.to_yaml(cfg)
        except GrammarParseError:
            return
        assert config.omegaconf_text(cfg) == expected


# --- the stage cache's key text: OmegaConf.to_yaml(OmegaConf.create(tree), sort_keys=True) -----

def omegaconf_sorted_text(tree):
    """OmegaConf's text, or None where OmegaConf refuses the tree (a string such as ``${``
    that is not a valid interpolation)."""
    try:
        return OmegaConf.to_yaml(OmegaConf.create(tree), sort_keys=True)
    except GrammarParseError:
        return None


def fast_sorted_text(tree):
    return config_yaml.dump(tree, config._resolves_as_str, sort_keys=True,
                            max_key=config_yaml.PYTHON_MAX_KEY)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(plain_trees(st.one_of(st.sampled_from(AWKWARD_STRINGS), st.text(max_size=12),
                             st.text(alphabet=ONE_LINE_ASCII, max_size=90)),
                   st.one_of(st.sampled_from(AWKWARD_STRINGS),
                             st.text(alphabet=ONE_LINE_ASCII, min_size=1, max_size=8))))
def test_sorted_plain_data_is_written_as_omegaconf_writes_it(tree):
    text, expected = fast_sorted_text(tree), omegaconf_sorted_text(tree)
    if text is not None and expected is not None:
        assert text == expected


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(ONE_LINE_ASCII_TREES)
def test_sorted_one_line_ascii_data_is_written_as_omegaconf_writes_it(tree):
    text, expected = fast_sorted_text(tree), omegaconf_sorted_text(tree)
    assert text is not None and (expected is None or text == expected)


@pytest.mark.parametrize("length", [121, 122, 123, 127, 128, 129])
@pytest.mark.parametrize("start", ["k", "yes", " ", "it's"])
def test_long_keys_as_each_emitter_writes_them(start, length):
    tree = {(start + "k" * length)[:length]: 1.0, "a": [1]}
    for text, expected in ((fast_text(tree), config.pyyaml_text(tree)),
                           (fast_sorted_text(tree), omegaconf_sorted_text(tree))):
        assert text is None or text == expected
    assert (fast_text(tree) is None) == (length > config_yaml.MAX_KEY)
    assert (fast_sorted_text(tree) is None) == (length > config_yaml.PYTHON_MAX_KEY)


def test_a_stage_key_text_of_the_peer_vehicles_is_omegaconfs():
    # the parts a stage key hashes are plain data (gmtiflow.cache): the same text, sorted
    cfg = compose(["vehicles=random", "clutter=windfarm"])
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    try:
        from stonesoup_peer import peer_vehicles
    finally:
        sys.path.pop(0)
    cfg.vehicles.vehicles = peer_vehicles(20, 600.0).vehicles
    parts = {"parts": {"clutter": config._plain(cfg.clutter), "scene": config._plain(cfg.scene),
                       "vehicles": config._plain(cfg.vehicles)}, "files": []}
    text = fast_sorted_text(parts)
    assert text is not None and text == omegaconf_sorted_text(parts)


@pytest.mark.parametrize("overrides", [[], ["vehicles=random", "clutter=windfarm",
                                            "terrain=hills", "experiment=two_orbits"]])
def test_stage_key_texts_are_written_without_omegaconf_and_unchanged(overrides):
    # every cached stage's key text (gmtiflow.pipeline.stages) of these configs, and of the
    # peer's listed vehicles, comes from the fast writer and is the text OmegaConf writes
    from gmtiflow import cache, pipeline
    cfg = compose(overrides)
    if not overrides:
        sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
        try:
            from stonesoup_peer import peer_vehicles
        finally:
            sys.path.pop(0)
        cfg.vehicles = peer_vehicles(30, 600.0)
    keyed = [st for st in pipeline.stages(cfg) if st.key is not None]
    assert len(keyed) >= 4
    for st in keyed:
        parts = st.key()
        assert cache._fast_key_text(parts) is not None, st.name
        assert cache.to_key_text(**parts) == cache._omegaconf_key_text(parts), st.name
