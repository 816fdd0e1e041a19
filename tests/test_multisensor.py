"""Several sensors in one scene (issue 14): per-sensor random streams (common random numbers),
unique sensor names and platform ids, per-sensor stage cache, run-wide ids."""
import logging
import re
import subprocess
import sys

import h5py
import numpy as np
import pytest

from gmtiflow import pipeline
from gmtiflow.compose import compose
from gmtiflow.config import sensor_slots
from gmtiflow.errors import ConfigError

SMALL = ["scene.duration_s=40", "vehicles=random", "vehicles.random.count=12",
         "vehicles.random.start_time_max_s=10", "progress=false", "export=none",
         "report.enabled=false"]
LEAN = ["tracker=none", "metrics.enabled=false", "cache.enabled=false"]
TWO = ["experiment=two_orbits"]
SENSOR_TABLES = ("dwells", "detections", "looks")


def tables(path, names=SENSOR_TABLES + ("platform", "sensors")):
    with h5py.File(path, "r") as f:
        return {n: {c: f[n][c][()] for c in f[n]} for n in names}


def rows_of(table, sensor_id):
    sel = table["sensor_id"] == sensor_id
    return {c: v[sel] for c, v in table.items()}


def assert_same_rows(a, b, skip=()):
    assert sorted(a) == sorted(b)
    for c in a:
        if c in skip:
            continue
        x, y = np.asarray(a[c]), np.asarray(b[c])
        assert x.dtype == y.dtype and x.shape == y.shape, c
        if x.dtype.kind == "f":
            assert np.array_equal(x.view(np.uint8), y.view(np.uint8)), c   # bit for bit
        else:
            assert np.array_equal(x, y), c


def one_sensor(cfg, name):
    """The two-sensor config reduced to its sensor ``name`` alone (as the first sensor)."""
    slot = {s.name: s for s in sensor_slots(cfg)}[name]
    cfg.platform, cfg.sensor, cfg.sensor_name, cfg.sensors = slot.platform, slot.sensor, name, {}
    return cfg


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """The two_orbits scene (short) with both sensors and with each sensor alone."""
    out = tmp_path_factory.mktemp("multisensor")
    both = pipeline.run(compose(TWO + SMALL + LEAN), out / "both")
    south = pipeline.run(one_sensor(compose(TWO + SMALL + LEAN), "south"), out / "south")
    west = pipeline.run(one_sensor(compose(TWO + SMALL + LEAN), "west"), out / "west")
    return tables(both), tables(south), tables(west)


def test_adding_a_sensor_leaves_the_first_bit_identical(runs):
    both, south, _ = runs
    assert list(both["sensors"]["name"].astype(str)) == ["south", "west"]
    for name in SENSOR_TABLES:
        assert set(np.unique(both[name]["sensor_id"])) == {0, 1}, name
        assert_same_rows(rows_of(both[name], 0), south[name])
    assert_same_rows(rows_of(both["platform"], 0), south["platform"])


def test_each_sensor_draws_from_its_own_named_streams(runs):
    """West alone (as the first sensor) equals west beside south, up to the id offsets: its
    draws depend on the seed and its name only, not on its position or the other sensor."""
    both, south, west = runs
    n_dw, n_det = len(south["dwells"]["dwell_id"]), len(south["detections"]["det_id"])
    got = {n: rows_of(both[n], 1) for n in SENSOR_TABLES}
    assert np.array_equal(got["dwells"]["dwell_id"], west["dwells"]["dwell_id"] + n_dw)
    assert np.array_equal(got["detections"]["det_id"], west["detections"]["det_id"] + n_det)
    assert np.array_equal(got["looks"]["det_id"],
                          np.where(west["looks"]["det_id"] >= 0, west["looks"]["det_id"] + n_det,
                                   -1))
    for n in SENSOR_TABLES:
        assert_same_rows(got[n], west[n], skip=("dwell_id", "det_id", "sensor_id"))
    assert len(got["detections"]["det_id"]) > 0 and n_det > 0
    # Same vehicles, other geometry: the sensors' errors are not the same draws.
    common = np.intersect1d(south["detections"]["truth_id"], west["detections"]["truth_id"])
    assert len(common) > 0


def test_ids_are_run_wide_and_join(runs):
    both, _, _ = runs
    dw, det, look = both["dwells"], both["detections"], both["looks"]
    assert np.array_equal(dw["dwell_id"], np.arange(len(dw["dwell_id"])))
    assert np.array_equal(det["det_id"], np.arange(len(det["det_id"])))
    sensor_of_dwell = dw["sensor_id"][det["dwell_id"]]
    assert np.array_equal(sensor_of_dwell, det["sensor_id"])
    hit = look["det_id"] >= 0
    assert np.array_equal(det["sensor_id"][look["det_id"][hit]], look["sensor_id"][hit])


def test_same_sensor_name_is_one_clear_error():
    with pytest.raises(ConfigError) as err:
        compose(TWO + ["sensor_name=west"])
    assert str(err.value) == ("invalid config: sensors.west: sensor name 'west' is already "
                              "used by sensor_name; every sensor needs its own name")
    slots = sensor_slots(compose(TWO + ["export.platform_id=JSTARS"]))
    assert [s.platform_id for s in slots] == ["JSTARS0", "JSTARS1"]   # as the 4607 writer
    assert sensor_slots(compose([]))[0].platform_id == "GMTIFLOW"       # one sensor: as is


def test_cli_rejects_a_duplicate_sensor_name_before_any_work(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "gmtiflow.cli", *TWO, "sensor_name=west",
                           f"hydra.run.dir={tmp_path}"], capture_output=True, text=True)
    assert proc.returncode == 1
    errors = [ln for ln in proc.stderr.splitlines() if "ERROR" in ln]
    assert len(errors) == 1 and "sensor name 'west' is already used by sensor_name" in errors[0]
    assert not (tmp_path / "run.h5").exists()


def test_changing_one_sensor_recomputes_only_that_sensor(tmp_path, caplog):
    caplog.set_level(logging.INFO, logger="gmtiflow")
    base = TWO + SMALL + ["tracker=none", "metrics.enabled=false", f"cache.dir={tmp_path / 'c'}"]
    keys = pipeline.stage_keys(compose(base))
    assert set(keys) == {"scene", "truth", "platform.south", "platform.west", "sensor.south",
                         "sensor.west"}
    changed = pipeline.stage_keys(compose(base + ["sensors.west.sensor.peak_power_w=900"]))
    assert {k for k in keys if keys[k] != changed[k]} == {"sensor.west"}
    pipeline.run(compose(base), tmp_path / "a")
    caplog.clear()
    b = pipeline.run(compose(base + ["sensors.west.sensor.peak_power_w=900"]), tmp_path / "b")
    misses = re.findall(r"cache miss (\S+) ", caplog.text)
    assert misses == ["sensor.west"], caplog.text
    for stage in ("scene", "truth", "platform.south", "platform.west", "sensor.south"):
        assert f"cache hit {stage} " in caplog.text
    plain = pipeline.run(compose(base[:-1] + ["cache.enabled=false",
                                              "sensors.west.sensor.peak_power_w=900"]),
                         tmp_path / "plain")
    got, want = tables(b), tables(plain)
    for name in SENSOR_TABLES:
        assert_same_rows(got[name], want[name])


def test_two_orbits_fused_coverage_beats_each_sensor_and_the_report_shows_it(tmp_path):
    """experiment=two_orbits (the full 240 s scene): /metrics/sensors has a row per sensor and
    a fused row, fused detection coverage is higher and there are fewer detection gaps than
    with either sensor alone, and the report gets its "sensors" page after the title."""
    import re
    from gmtiflow.report.run_report import PAGES
    from gmtiflow.store import read_table
    path = pipeline.run(compose(TWO + ["progress=false", "export=none", "cache.enabled=false",
                                       "report.animation=false"]), tmp_path)
    t = read_table(path, "metrics/sensors")
    assert list(t["name"]) == ["south", "west", "fused"]
    assert list(t["sensor_id"]) == [0, 1, -1]
    cov, gaps = t["detection_coverage"], t["detection_gaps"]
    assert cov[2] > max(cov[:2]) and gaps[2] < min(gaps[:2]), t
    assert t["n_detections"][2] == t["n_detections"][0] + t["n_detections"][1]
    assert t["doppler_blind_gaps"][2] < t["doppler_blind_gaps"][0]     # south's notch filled
    pdf = (tmp_path / "report.pdf").read_bytes()
    assert len(re.findall(rb"/Type\s*/Page[^s]", pdf)) == len(PAGES) + 1


def test_4607_of_a_two_sensor_run_is_two_platforms_in_time_order(tmp_path):
    """The independent PyPI decoder sees two platform ids, each with its sensor's dwells and
    located reports; dwells come in time order across sensors; our reader gives the sensors
    back."""
    stanag = pytest.importorskip("stanag4607", reason="PyPI stanag4607 (test extra)")
    from gmtiflow import formats
    path = pipeline.run(compose(TWO + SMALL[:-2] + ["report.enabled=false", "export=stanag4607",
                                                    *LEAN]), tmp_path)
    t = tables(path, ("dwells", "detections", "sensors"))
    data = (tmp_path / "detections.4607").read_bytes()
    dec = stanag.PacketStreamDecoder()
    packets = list(dec.feed(data))
    dec.finish()
    n_dwells, n_targets, times = {}, {}, []
    for p in packets:
        pid = p.header.platform_id.rstrip(b"\0 ").decode()
        for e in stanag.iter_packet_events(p):
            if isinstance(e.value, stanag.DwellSegment):
                n_dwells[pid] = n_dwells.get(pid, 0) + 1
                n_targets[pid] = n_targets.get(pid, 0) + e.value.target_report_count
                times.append(e.value.dwell_time_milliseconds)
    ids = [s.decode() for s in t["sensors"]["platform_id"]]
    assert ids == ["GMTIFLOW0", "GMTIFLOW1"] and sorted(n_dwells) == ids
    det = t["detections"]
    located = np.isfinite(det["lat_deg"]) & np.isfinite(det["lon_deg"])
    for sid, pid in enumerate(ids):
        assert n_dwells[pid] == np.sum(t["dwells"]["sensor_id"] == sid)
        assert n_targets[pid] == np.sum(located & (det["sensor_id"] == sid)) > 0
    assert times == sorted(times) and len(times) == len(t["dwells"]["dwell_id"])
    ours = formats.read_4607(data)
    order = np.lexsort((t["dwells"]["sensor_id"], t["dwells"]["time_s"]))
    assert np.array_equal(ours["dwells"]["sensor_id"], t["dwells"]["sensor_id"][order])
    assert list(np.unique(ours["dwells"]["platform_id"])) == ids


def test_xml_and_csv_exports_carry_the_sensor_id_and_read_back(tmp_path):
    from gmtiflow import formats
    pipeline.run(compose(TWO + SMALL[:-2] + ["report.enabled=false", "export=all", *LEAN]),
                 tmp_path)
    t = tables(tmp_path / "run.h5", ("dwells", "detections"))
    xml = formats.read_xml(tmp_path / "detections.xml")
    assert np.array_equal(np.sort(xml["dwells"]["sensor_id"]), np.sort(t["dwells"]["sensor_id"]))
    assert set(xml["dwells"]["sensor_id"]) == {0, 1}
    csv = formats.read_csv(tmp_path / "detections.csv", "detections")
    by_id = np.argsort(csv["det_id"])
    assert np.array_equal(csv["sensor_id"][by_id], t["detections"]["sensor_id"])
