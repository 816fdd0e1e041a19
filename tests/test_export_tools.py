"""Every export of three short scenes, checked with software we did not write and for the
columns a tracker needs: the default scene, ``clutter=lake`` (false alarms and a clutter region)
and ``experiment=two_orbits`` (two sensors).  tshark finds no expert error in detections.4607
and decodes our values; GDAL (pyogrio) opens scene.geojson and truth.geojson with one type per
field; every CSV has ``time_s`` and ISO-8601 ``time_utc``; detections.csv and dwells.csv carry
``sensor_id`` (detections their ``dwell_id``) and the CSV and GeoJSON readers bring it back."""
from __future__ import annotations

import numpy as np
import pytest

from gmtiflow import formats, pipeline, store
from gmtiflow.formats import stanag4607 as s4607
from gmtiflow.formats._io import iso_utc, parse_epoch
from tests.conftest import compose_app
from tests.external_tools import gdal_read, needs_tshark, tshark_expert_errors, tshark_fields

SCENES = {"default": [], "lake": ["clutter=lake"], "two_orbits": ["experiment=two_orbits"]}
SHORT = ["scene.duration_s=20", "fidelity.truth_output_dt_s=1.0", "progress=false",
         "report=none", "export=all", "export.csv_tables=[detections,dwells,truth,tracks]",
         "cache.enabled=false"]


@pytest.fixture(scope="module", params=sorted(SCENES))
def scene_run(request, tmp_path_factory):
    """(scene name, run.h5 path) of a 20 s run with every export."""
    name = request.param
    cfg = compose_app(SCENES[name] + SHORT)
    return name, pipeline.run(cfg, tmp_path_factory.mktemp(name))


def _located(det):
    return np.isfinite(det["lat_deg"]) & np.isfinite(det["lon_deg"])


@needs_tshark
def test_tshark_reads_the_4607_export_without_errors_and_decodes_our_values(scene_run):
    name, run = scene_run
    path = run.parent / "detections.4607"
    assert tshark_expert_errors(path) == []
    ours = s4607.read_4607(path)
    d, t = ours["dwells"], ours["detections"]
    det = store.read_table(run, "detections")
    assert len(t["det_id"]) == int(_located(det).sum()) > 0, name
    got = tshark_fields(path, "s4607.dwell.time", "s4607.dwell.count", "s4607.dwell.sensor.lat",
                        "s4607.dwell.rpt.lat", "s4607.dwell.rpt.lon", "s4607.dwell.rpt.radial",
                        "s4607.dwell.rpt.unc.slant", "s4607.dwell.rpt.unc.height")
    pieces = np.repeat(np.arange(len(d["dwell_id"])), d["n_packets"])
    assert got["s4607.dwell.time"].tolist() == d["dwell_time_ms"][pieces].tolist()
    assert got["s4607.dwell.count"].sum() == len(t["det_id"])
    assert got["s4607.dwell.sensor.lat"].tolist() == s4607.enc_sa32(
        d["platform_lat_deg"][pieces]).tolist()
    assert got["s4607.dwell.rpt.lat"].tolist() == s4607.enc_sa32(t["lat_deg"]).tolist()
    assert got["s4607.dwell.rpt.lon"].tolist() == s4607.enc_ba32(t["lon_deg"]).tolist()
    assert got["s4607.dwell.rpt.radial"].tolist() == np.rint(
        t["los_velocity_mps"] * 100).astype(int).tolist()
    assert got["s4607.dwell.rpt.unc.slant"].tolist() == np.rint(
        t["sigma_range_m"] * 100).astype(int).tolist()
    assert got["s4607.dwell.rpt.unc.height"].tolist() == t["sigma_height_m"].astype(int).tolist()
    assert got["s4607.dwell.rpt.unc.height"].min() >= 1      # a present 0 m σ: singular
    n_sensors = len(store.read_table(run, "sensors")["sensor_id"])
    assert sorted(set(d["sensor_id"].tolist())) == list(range(n_sensors))


def test_gdal_opens_every_geojson_with_one_type_per_field(scene_run):
    name, run = scene_run
    det = store.read_table(run, "detections")
    fields, types, _ = gdal_read(run.parent / "scene.geojson")
    assert not any(t.endswith("List") for t in types.values()), types
    kind = fields["kind"].astype(str)
    points = kind == "detection"
    assert points.sum() == int(_located(det).sum()) > 0
    assert types["sensor_id"].startswith("OFTInteger") and types["time_s"] == "OFTReal"
    order = np.argsort(fields["det_id"][points].astype(np.int64))
    ok = _located(det)
    np.testing.assert_array_equal(fields["sensor_id"][points].astype(np.int64)[order],
                                  det["sensor_id"][ok][np.argsort(det["det_id"][ok])])
    np.testing.assert_array_equal(fields["time_s"][points].astype(float)[order],
                                  det["time_s"][ok][np.argsort(det["det_id"][ok])])
    truth, ttypes, geom = gdal_read(run.parent / "truth.geojson")
    # LineStrings, and a Point for a vehicle with one sample (GDAL: "Unknown", i.e. mixed)
    assert geom in ("LineString", "LineString Z", "Unknown") and ttypes["time_s"] == "OFTRealList"
    assert len(truth["vehicle_id"]) == len(np.unique(store.read_table(run, "truth")["vehicle_id"]))
    back = formats.read_geojson(run.parent / "scene.geojson")["detections"]
    assert sorted(back["sensor_id"].tolist()) == sorted(det["sensor_id"][ok].tolist())
    # tracks.geojson: one line per track, its per-vertex times as a RealList; reads back exactly
    tracks = store.read_table(run, "tracks")
    lines, ktypes, _ = gdal_read(run.parent / "tracks.geojson")
    assert ktypes["time_s"] == "OFTRealList" and ktypes["track_id"].startswith("OFTInteger")
    assert sorted(lines["track_id"].astype(np.int64).tolist()) == \
        np.unique(tracks["track_id"]).tolist()
    got = formats.read_geojson(run.parent / "tracks.geojson")["tracks"]
    o, r = np.lexsort((got["time_s"], got["track_id"])), np.lexsort((tracks["time_s"],
                                                                     tracks["track_id"]))
    for c in ("time_s", "x_m", "y_m", "vx_mps"):
        np.testing.assert_array_equal(got[c][o], np.asarray(tracks[c])[r], err_msg=c)


@pytest.mark.parametrize("table", ["detections", "dwells", "truth", "tracks"])
def test_every_csv_has_both_times_and_the_sensor_comes_back(scene_run, table):
    name, run = scene_run
    path = run.parent / f"{table}.csv"
    header = path.read_text().split("\n", 1)[0].split(",")
    assert header[:2] == ["time_utc", "time_s"]
    back = formats.read_csv(path, table)
    ref = store.read_table(run, table)
    with store.open_run(run) as f:
        epoch = parse_epoch(store.read_attrs(f)["scene_epoch_utc"])
    column = [line.split(",")[0] for line in path.read_text().splitlines()[1:]]
    assert column == iso_utc(epoch, back["time_s"]).tolist()
    assert len(back["time_s"]) == len(ref["time_s"])
    if table in ("detections", "dwells"):
        assert "sensor_id" in header and "dwell_id" in header
        key = "det_id" if table == "detections" else "dwell_id"
        o, r = np.argsort(back[key]), np.argsort(ref[key])
        np.testing.assert_array_equal(back["sensor_id"][o], ref["sensor_id"][r])
        np.testing.assert_array_equal(back["dwell_id"][o], ref["dwell_id"][r])
        np.testing.assert_array_equal(back["time_s"][o], ref["time_s"][r])
        if name == "two_orbits":
            assert set(back["sensor_id"].tolist()) == {0, 1}


@needs_tshark
def test_tshark_decodes_the_values_of_run_h5_itself(scene_run):
    """What tshark decodes from detections.4607 against run.h5 directly (not our reader):
    each Dwell packet's D6, D7-D9, D24-D26, D31 and J15 of its platform, and each report's
    position, height, SNR and truth tag, in the run's dwell and report order."""
    name, run = scene_run
    path = run.parent / "detections.4607"
    dw = store.read_table(run, "dwells")
    det = store.read_table(run, "detections")
    with store.open_run(run) as f:
        epoch = parse_epoch(store.read_attrs(f)["scene_epoch_utc"])
        revisit_s = float(store.read_config(f)["sensor"]["revisit_s"])
    day_ms = (epoch - epoch.replace(hour=0, minute=0, second=0, microsecond=0)).total_seconds() * 1e3
    order = np.argsort(dw["time_s"], kind="stable")
    got = tshark_fields(path, "s4607.dwell.time", "s4607.dwell.count", "s4607.dwell.sensor.lat",
                        "s4607.dwell.sensor.lon", "s4607.dwell.sensor.alt", "s4607.dwell.da.lat",
                        "s4607.dwell.da.range", "s4607.dwell.mdv", "s4607.job.revisit")
    assert got["s4607.dwell.time"].tolist() == np.rint(dw["time_s"][order] * 1e3 + day_ms).astype(
        int).tolist()
    assert got["s4607.dwell.sensor.lat"].tolist() == np.rint(
        dw["platform_lat_deg"][order] * 2**31 / 90).astype(int).tolist()
    assert got["s4607.dwell.sensor.lon"].tolist() == (np.rint(
        np.mod(dw["platform_lon_deg"][order], 360) * 2**32 / 360).astype(int) % 2**32).tolist()
    assert got["s4607.dwell.sensor.alt"].tolist() == np.rint(
        dw["platform_height_m"][order] * 100).astype(int).tolist()
    assert got["s4607.dwell.da.lat"].tolist() == np.rint(
        dw["area_lat_deg"][order] * 2**31 / 90).astype(int).tolist()
    assert got["s4607.dwell.da.range"].tolist() == np.rint(
        dw["range_half_extent_m"][order] * 128 / 1000).astype(int).tolist()
    assert got["s4607.dwell.mdv"].tolist() == np.rint(dw["mdv_mps"][order] * 10).astype(int).tolist()
    assert set(got["s4607.job.revisit"].tolist()) == {round(revisit_s * 10)}
    located = np.isfinite(det["lat_deg"]) & np.isfinite(det["lon_deg"])
    rank = np.empty(len(order), np.int64)
    rank[order] = np.arange(len(order))
    row = {int(i): k for k, i in enumerate(dw["dwell_id"])}
    k = np.flatnonzero(located)
    k = k[np.lexsort((det["det_id"][k], rank[[row[int(i)] for i in det["dwell_id"][k]]]))]
    assert got["s4607.dwell.count"].tolist() == np.bincount(
        rank[[row[int(i)] for i in det["dwell_id"][k]]], minlength=len(order)).tolist()
    rpt = tshark_fields(path, "s4607.dwell.rpt.lat", "s4607.dwell.rpt.lon", "s4607.dwell.rpt.height",
                        "s4607.dwell.rpt.snr", "s4607.dwell.rpt.tag.entity")
    assert rpt["s4607.dwell.rpt.lat"].tolist() == np.rint(det["lat_deg"][k] * 2**31 / 90).astype(
        int).tolist()
    assert rpt["s4607.dwell.rpt.lon"].tolist() == (np.rint(
        np.mod(det["lon_deg"][k], 360) * 2**32 / 360).astype(int) % 2**32).tolist()
    assert rpt["s4607.dwell.rpt.height"].tolist() == np.rint(det["height_m"][k]).astype(int).tolist()
    assert rpt["s4607.dwell.rpt.snr"].tolist() == np.rint(det["snr_db"][k]).astype(int).tolist()
    assert rpt["s4607.dwell.rpt.tag.entity"].tolist() == np.where(
        det["truth_id"][k] < 0, 2**32 - 1, det["truth_id"][k]).tolist()
