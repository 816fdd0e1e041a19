"""Exports of runs with nothing in them, checked with software we did not write (tshark,
xmllint, GDAL, Stone Soup) and read back with our readers: a scene too short for one scan
(``scene.duration_s=0.2``: no dwell, no detection, no track), which the CLI accepts and exports,
and a radar without PRF (``sensor.pri_s=null``: ``wrap_velocity_mps`` NaN on every row)."""
from __future__ import annotations

import shutil
import subprocess

import numpy as np
import pytest

from gmtiflow import formats, pipeline, store
from tests.conftest import compose_app
from gmtiflow.formats import stanag4607 as s4607
from tests.external_tools import TSHARK, gdal_read, needs_tshark, tshark_fields

EMPTY = ["scene.duration_s=0.2", "progress=false", "report=none", "export=all",
         "export.csv_tables=[detections,dwells,truth,tracks]", "cache.enabled=false"]


@pytest.fixture(scope="module")
def empty_run(tmp_path_factory):
    """run.h5 of a scene shorter than one scan (14 dwells x 32 ms): no dwell at all."""
    run = pipeline.run(compose_app(EMPTY), tmp_path_factory.mktemp("empty"))
    assert len(store.read_table(run, "dwells")["dwell_id"]) == 0
    return run


def _scene_box(run):
    """(south, north, west, east) of the scene origin and the platform's positions."""
    with store.open_run(run) as f:
        attrs = store.read_attrs(f)
    plat = store.read_table(run, "platform")
    lat = np.r_[attrs["origin_lat_deg"], plat["lat_deg"]]
    lon = np.r_[attrs["origin_lon_deg"], plat["lon_deg"]]
    return lat.min(), lat.max(), lon.min(), lon.max()


def test_4607_of_a_run_without_dwells_has_no_dwell_and_its_job_area_is_the_scene(empty_run):
    got = formats.read_4607(empty_run.parent / "detections.4607")
    assert len(got["dwells"]["dwell_id"]) == 0 and len(got["detections"]["det_id"]) == 0
    assert 2 not in got["segments"]["seg_type"].tolist()          # no Dwell segment
    s, n, w, e = _scene_box(empty_run)
    jobs = got["jobs"]
    q = 180.0 / 2**32                                                # SA32 / BA32 quanta
    for c in "abcd":
        lat, lon = jobs[f"{c}_lat_deg"][0], jobs[f"{c}_lon_deg"][0]
        assert s - 2 * q <= lat <= n + 2 * q and w - 4 * q <= lon <= e + 4 * q, (c, lat, lon)
    lats = [jobs[f"{c}_lat_deg"][0] for c in "abcd"]
    assert max(lats) - min(lats) > 0.1        # the platform (30 km south) and the town
    xml = formats.read_xml(empty_run.parent / "detections.xml")["meta"]["bounding_area"]
    assert [p[0] for p in xml] == pytest.approx(lats, abs=1e-6)


@needs_tshark
def test_tshark_finds_nothing_wrong_in_the_4607_of_a_run_without_dwells(empty_run):
    path = empty_run.parent / "detections.4607"
    out = subprocess.run([TSHARK, "-r", str(path), "-q", "-z", "expert"], capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert not any(w in out.stdout for w in ("Errors", "Warns", "Malformed")), out.stdout
    # the area tshark decodes is ours, and is where the scene is (not 0 deg N 0 deg E)
    jobs = formats.read_4607(path)["jobs"]
    fields = [f"s4607.job.ba.{ll}.{c}" for c in "abcd" for ll in ("lat", "lon")]
    got = tshark_fields(path, *fields)
    for c in "abcd":
        assert got[f"s4607.job.ba.lat.{c}"].tolist() == s4607.enc_sa32(jobs[f"{c}_lat_deg"]).tolist()
        assert got[f"s4607.job.ba.lon.{c}"].tolist() == s4607.enc_ba32(jobs[f"{c}_lon_deg"]).tolist()
        assert np.all(got[f"s4607.job.ba.lat.{c}"] != 0)


NO_PRF = ["scene.duration_s=20", "sensor.pri_s=null", "sensor.integration_gain_db=21",
          "progress=false", "report=none", "export=all",
          "export.csv_tables=[detections,dwells,truth,tracks]", "cache.enabled=false"]


@pytest.fixture(scope="module")
def no_prf_run(tmp_path_factory):
    """run.h5 of a radar without PRF: ``wrap_velocity_mps`` is NaN on every dwell and report."""
    run = pipeline.run(compose_app(NO_PRF), tmp_path_factory.mktemp("no_prf"))
    det = store.read_table(run, "detections")
    assert len(det["det_id"]) > 0 and np.isnan(det["wrap_velocity_mps"]).all()
    return run


@pytest.fixture(scope="module")
def unlocated_run(no_prf_run, tmp_path_factory):
    """The no-PRF run with every report unlocated (NaN position, as a folded report that could
    not be put on the ground), exported again: no report in 4607 nor GeoJSON."""
    import h5py
    from gmtiflow.export import ExportConfig, export_run
    run = tmp_path_factory.mktemp("unlocated") / "run.h5"
    shutil.copy(no_prf_run, run)
    with h5py.File(run, "r+") as f:
        for c in ("lat_deg", "lon_deg", "height_m", "x_m", "y_m", "z_m"):
            f["detections"][c][...] = np.nan
    export_run(ExportConfig(csv_tables=["detections", "dwells", "truth", "tracks"]), run)
    return run


@needs_tshark
def test_4607_of_a_run_whose_reports_are_all_unlocated(unlocated_run):
    path = unlocated_run.parent / "detections.4607"
    got = formats.read_4607(path)
    assert len(got["detections"]["det_id"]) == 0
    assert len(got["dwells"]["dwell_id"]) == len(store.read_table(unlocated_run, "dwells")["dwell_id"])
    out = subprocess.run([TSHARK, "-r", str(path), "-q", "-z", "expert"], capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0 and not any(w in out.stdout for w in ("Errors", "Warns")), out.stdout


def _assert_same_columns(ref, got, columns, what):
    """Every column of the run table that the format carries comes back: name, dtype, rows."""
    for c in ref:
        if c not in columns:
            continue
        assert c in got, (what, c)
        a, b = np.asarray(ref[c]), np.asarray(got[c])
        assert b.dtype == a.dtype and len(b) == len(a), (what, c, a.dtype, b.dtype, len(b))


@pytest.mark.parametrize("which", ["empty", "no_prf", "unlocated"])
def test_xml_of_the_run_gives_back_every_table_and_column(which, request):
    run = request.getfixturevalue(f"{which}_run")
    path = run.parent / "detections.xml"
    formats.validate_xml(path)
    if shutil.which("xmllint"):
        out = subprocess.run(["xmllint", "--noout", "--schema", str(formats.xmldoc.XSD_PATH),
                              str(path)], capture_output=True, text=True, timeout=60)
        assert out.returncode == 0, out.stderr
    got = formats.read_xml(path)
    for table, columns in (("dwells", formats.xmldoc.DWELL_COLUMNS),
                           ("detections", formats.xmldoc.DETECTION_COLUMNS)):
        ref = store.read_table(run, table)
        _assert_same_columns(ref, got[table], columns, table)
        order = np.argsort(got[table]["det_id" if table == "detections" else "dwell_id"])
        for c in ref:
            if c in columns and np.asarray(ref[c]).dtype.kind == "f":
                np.testing.assert_array_equal(got[table][c][order], ref[c], err_msg=c)


@pytest.mark.parametrize("which", ["empty", "no_prf", "unlocated"])
def test_geojson_of_the_run_gives_back_every_column_and_gdal_opens_it(which, request):
    run = request.getfixturevalue(f"{which}_run")
    det = store.read_table(run, "detections")
    located = np.isfinite(det["lat_deg"]) & np.isfinite(det["lon_deg"])
    got = formats.read_geojson(run.parent / "scene.geojson")["detections"]
    _assert_same_columns({c: v[located] for c, v in det.items()}, got, det, "detections")
    tracks = store.read_table(run, "tracks")
    got = formats.read_geojson(run.parent / "tracks.geojson")["tracks"]
    _assert_same_columns(tracks, got, tracks, "tracks")
    for name in ("scene.geojson", "tracks.geojson", "truth.geojson"):
        gdal_read(run.parent / name)                 # GDAL opens it (an empty layer too)


@pytest.mark.parametrize("which", ["empty", "no_prf", "unlocated"])
@pytest.mark.parametrize("table", ["detections", "dwells", "truth", "tracks"])
def test_csv_of_the_run_gives_back_every_column(which, table, request):
    run = request.getfixturevalue(f"{which}_run")
    ref = store.read_table(run, table)
    got = formats.read_csv(run.parent / f"{table}.csv", table)
    _assert_same_columns(ref, got, formats.csvtable.COLUMNS[table], table)


@pytest.mark.parametrize("which", ["empty", "no_prf"])
def test_stone_soup_reads_the_csv_of_the_run(which, request):
    generic = pytest.importorskip("stonesoup.reader.generic")
    run = request.getfixturevalue(f"{which}_run")
    n_det = len(store.read_table(run, "detections")["det_id"])
    reader = generic.CSVDetectionReader(run.parent / "detections.csv",
                                        state_vector_fields=("x_m", "y_m"),
                                        time_field="time_utc")
    assert sum(len(d) for _, d in reader) == n_det
    n_tracks = len(store.read_table(run, "tracks")["track_id"])
    reader = generic.CSVGroundTruthReader(run.parent / "tracks.csv",
                                          state_vector_fields=("x_m", "vx_mps", "y_m", "vy_mps"),
                                          time_field="time_utc", path_id_field="track_id")
    assert sum(len(p) for _, p in reader) == n_tracks


@pytest.mark.parametrize("which", ["empty", "no_prf"])
def test_4607_reader_gives_the_same_columns_for_an_empty_and_a_full_run(which, request,
                                                                         no_prf_run):
    run = request.getfixturevalue(f"{which}_run")
    got = formats.read_4607(run.parent / "detections.4607")
    full = formats.read_4607(no_prf_run.parent / "detections.4607")
    for table in ("dwells", "detections", "jobs", "missions"):
        assert {c: v.dtype for c, v in got[table].items()} == \
            {c: v.dtype for c, v in full[table].items()}, table
    if which == "no_prf":                 # D32.8 absent: no wrap velocity, read as NaN
        assert np.isnan(got["detections"]["wrap_velocity_mps"]).all()
