"""gmtiflow-convert: run.h5 -> each format -> HDF5 tables equal within the documented quanta,
and bad input (one line on stderr naming where, exit 1, no output file)."""
import subprocess
import sys

import h5py
import numpy as np
import pytest

from gmtiflow import convert, pipeline, store
from tests.conftest import compose_app

OVERRIDES = ["scene.duration_s=30", "fidelity.truth_output_dt_s=1.0", "progress=false",
             "clutter=lake"]

# docs/exports.md: what survives run.h5 -> 4607 -> h5 (absolute tolerances, table units)
QUANTA_4607_DETECTIONS = {
    "time_s": 0.0005, "lat_deg": 180 / 2**32, "lon_deg": 360 / 2**32, "height_m": 0.5,
    "range_rate_mps": 0.05, "snr_db": 0.5, "sigma_range_m": 0.005, "sigma_range_rate_mps": 0.005,
    "rcs_dbsm": 0.25, "wrap_velocity_mps": 0.005, "truth_id": 0, "dwell_id": 0,
    "x_m": 0.01, "y_m": 0.01, "z_m": 0.5, "azimuth_rad": 1e-6, "range_m": 0.5,
}
QUANTA_4607_DWELLS = {
    "time_s": 0.0005, "revisit_id": 0, "dwell_index": 0, "last_dwell": 0,
    "platform_lat_deg": 180 / 2**32, "platform_lon_deg": 360 / 2**32,
    "platform_height_m": 0.005, "area_lat_deg": 180 / 2**32, "area_lon_deg": 360 / 2**32,
    "platform_heading_rad": np.radians(360 / 2**16), "platform_bank_rad": np.radians(180 / 2**16),
    "range_half_extent_m": 1000 / 128 / 2, "angle_half_extent_rad": np.radians(360 / 2**16),
    "mdv_mps": 0.05, "platform_vx_mps": 0.02, "platform_vy_mps": 0.02, "platform_vz_mps": 0.05,
    "platform_x_m": 0.01, "platform_y_m": 0.01, "platform_z_m": 0.01,
}


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    return pipeline.run(compose_app(OVERRIDES), tmp_path_factory.mktemp("run"))


def cli(*args):
    """Run the console script in a subprocess: (returncode, stdout, stderr)."""
    proc = subprocess.run([sys.executable, "-m", "gmtiflow.convert", *map(str, args)],
                          capture_output=True, text=True, timeout=120)
    return proc.returncode, proc.stdout, proc.stderr


def origin_of(run):
    with h5py.File(run) as f:
        return ",".join(str(float(f.attrs[k])) for k in
                        ("origin_lat_deg", "origin_lon_deg", "origin_height_m"))


def by(table, *keys):
    order = np.lexsort(tuple(np.asarray(table[k]) for k in reversed(keys)))
    return {c: np.asarray(v)[order] for c, v in table.items()}


def assert_close(a, b, quanta, what, nan_as_zero=()):
    for col, tol in quanta.items():
        x, y = np.asarray(a[col], float), np.asarray(b[col], float)
        if col in nan_as_zero:
            # 4607's "absent" is per dwell (the existence mask): a dwell where no report has the
            # value leaves the field out and it reads back as NaN; a report without it in a
            # dwell where others have it is sent as 0
            x = np.where(np.isnan(x) & ~np.isnan(y), 0.0, x)
        assert x.shape == y.shape, (what, col)
        err = np.abs(x - y)
        assert np.array_equal(np.isnan(x), np.isnan(y)), (what, col)
        assert np.nanmax(err, initial=0.0) <= tol * (1 + 1e-6) + 1e-12, (what, col, np.nanmax(err))


def assert_equal(a, b, what, skip=()):
    for col in a:
        if col in skip:
            continue
        assert col in b, (what, col)
        x, y = np.asarray(a[col]), np.asarray(b[col])
        if x.dtype.kind == "f":
            assert np.array_equal(x, y.astype(float), equal_nan=True), (what, col)
        else:
            assert np.array_equal(x, y), (what, col)


def test_help_is_usable():
    code, out, _ = cli("--help")
    assert code == 0
    for word in ("--to", "4607", "h5", "--origin", "examples:", "D32.7"):
        assert word in out


@pytest.mark.parametrize("edition", ["30", "41"])
def test_4607_round_trip_within_quanta(run, tmp_path, edition):
    out = tmp_path / "d.4607"
    code, stdout, err = cli(run, "--to", "4607", "-o", out, "--edition", edition)
    assert code == 0, err
    assert stdout.strip() == str(out)
    code, _, err = cli(out, "--to", "h5", "-o", tmp_path / "d.h5", "--origin", origin_of(run))
    assert code == 0, err
    det, got = store.read_table(run, "detections"), store.read_table(tmp_path / "d.h5", "detections")
    assert len(det["det_id"]) > 20 and np.any(det["truth_id"] < 0)   # targets and false alarms
    assert_close(by(det, "dwell_id", "det_id"), by(got, "dwell_id", "det_id"),
                 QUANTA_4607_DETECTIONS, "detections", nan_as_zero=("rcs_dbsm", "snr_db"))
    assert_close(store.read_table(run, "dwells"), store.read_table(tmp_path / "d.h5", "dwells"),
                 QUANTA_4607_DWELLS, "dwells")
    with h5py.File(tmp_path / "d.h5") as f:
        assert f.attrs["source_format"] == "4607" and f.attrs["seed"] == -1
        assert {"packets", "missions", "jobs", "dwells", "detections"} <= set(f)


def test_xml_round_trip_is_exact(run, tmp_path):
    code, _, err = cli(run, "--to", "xml", "-o", tmp_path / "d.xml")
    assert code == 0, err
    code, _, err = cli(tmp_path / "d.xml", "--to", "h5")             # default: d.h5
    assert code == 0, err
    got = store.read_table(tmp_path / "d.h5", "detections")
    assert_equal(got, store.read_table(run, "detections"), "detections")
    assert_equal(store.read_table(tmp_path / "d.h5", "dwells"), store.read_table(run, "dwells"),
                 "dwells")


@pytest.mark.parametrize("table, sort", [("detections", ("det_id",)),
                                         ("truth", ("time_s", "vehicle_id")),
                                         ("tracks", ("track_id", "time_s"))])
def test_csv_round_trip_is_exact(run, tmp_path, table, sort):
    code, _, err = cli(run, "--to", "csv", "--table", table, "-o", tmp_path / f"{table}.csv")
    assert code == 0, err
    code, _, err = cli(tmp_path / f"{table}.csv", "--to", "h5", "-o", tmp_path / "t.h5")
    assert code == 0, err                      # the table is recognised from the header
    orig, got = store.read_table(run, table), store.read_table(tmp_path / "t.h5", table)
    assert len(orig[sort[0]]) > 0
    assert_equal(by(orig, *sort), by(got, *sort), table)


def test_geojson_round_trip_is_exact(run, tmp_path):
    code, _, err = cli(run, "--to", "geojson")
    assert code == 0, err
    assert (run.parent / "scene.geojson").is_file()                 # default: beside the run
    code, _, err = cli(run.parent / "scene.geojson", "--to", "h5", "-o", tmp_path / "g.h5")
    assert code == 0, err
    det = store.read_table(run, "detections")
    assert_equal(by(det, "det_id"), by(store.read_table(tmp_path / "g.h5", "detections"),
                                       "det_id"), "detections")
    code, _, err = cli(run, "--to", "geojson", "--table", "truth", "-o", tmp_path / "t.geojson")
    assert code == 0, err
    code, _, err = cli(tmp_path / "t.geojson", "--to", "h5", "-o", tmp_path / "t.h5")
    assert code == 0, err
    truth = store.read_table(run, "truth")
    assert_equal(by(truth, "time_s", "vehicle_id"),
                 by(store.read_table(tmp_path / "t.h5", "truth"), "time_s", "vehicle_id"), "truth")
    nodes = store.read_table(run, "roads/nodes")
    assert_equal(nodes, store.read_table(tmp_path / "g.h5", "roads/nodes"), "nodes")
    with h5py.File(tmp_path / "g.h5") as f:
        assert "clutter_regions" in f


def test_a_foreign_4607_file_without_gmtiflow_free_text(run, tmp_path):
    """Another producer's file: no epoch free text, so time counts from the mission day."""
    from gmtiflow import formats
    from gmtiflow.export import ExportConfig, load_run
    from gmtiflow.export_tables import meta_for, to_4607_tables
    r = load_run(run)
    dw, det = to_4607_tables(r)
    meta = dict(meta_for(ExportConfig(), r), write_epoch_text=False)
    formats.write_4607(tmp_path / "other.gmti", dw, det, meta)
    code, _, err = cli(tmp_path / "other.gmti", "--to", "h5", "-o", tmp_path / "o.h5")
    assert code == 0, err
    got = store.read_table(tmp_path / "o.h5", "dwells")
    # 2026-06-01T08:00:00Z: the reference day starts 8 h before the scene epoch
    assert np.allclose(got["time_s"], store.read_table(run, "dwells")["time_s"] + 8 * 3600,
                       atol=5e-4)
    assert "x_m" not in store.read_table(tmp_path / "o.h5", "detections")   # no origin given


@pytest.mark.parametrize("suffix, content, to, needle", [
    (".4607", None, "h5", "byte offset"),                       # truncated 4607
    (".csv", "time_s,track_id,x_m,y_m,speed\n0,1,0,0,3\n", "h5", "line 1, column 5"),
    (".csv", "time_s,det_id,dwell_id\n0,1,zero\n", "h5", "line 2, column 3"),
    (".csv", "time_s,x_m\n0,1\n", "h5", "line 1"),             # which table?
    (".xml", '<?xml version="1.0"?>\n<GmtiDocument/>', "h5", "line 2"),
    (".geojson", '{"type": "FeatureCollection", "features": [1]}', "h5", "feature 0"),
    (".h5", b"\x89HDF\r\n\x1a\nnot really", "xml", "not a readable HDF5"),
    (".dat", "x", "h5", "suffix"),
])
def test_bad_input_is_one_clear_line_and_no_output(run, tmp_path, suffix, content, to, needle):
    bad = tmp_path / f"bad{suffix}"
    if content is None:
        whole = tmp_path / "whole.4607"
        assert cli(run, "--to", "4607", "-o", whole)[0] == 0
        bad.write_bytes(whole.read_bytes()[:1000])
        whole.unlink()
    elif isinstance(content, bytes):
        bad.write_bytes(content)
    else:
        bad.write_text(content)
    out = tmp_path / f"out.{to}"
    code, stdout, err = cli(bad, "--to", to, "-o", out)
    assert code == 1
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("gmtiflow-convert: error: "), err
    assert str(bad) in lines[0] and needle in lines[0], lines[0]
    assert "Traceback" not in err and stdout == ""
    assert sorted(p.name for p in tmp_path.iterdir()) == [bad.name]


def test_argument_errors_exit_2(run):
    code, _, err = cli(run, "--to", "kml")
    assert code == 2 and "--to" in err


def test_format_to_format_is_refused(run, tmp_path):
    assert cli(run, "--to", "csv", "-o", tmp_path / "d.csv")[0] == 0
    code, _, err = cli(tmp_path / "d.csv", "--to", "xml")
    assert code == 1 and "--to h5" in err
    assert convert.main([str(run), "--to", "h5"]) == 1


@pytest.mark.parametrize("with_origin", [True, False])
def test_4607_to_h5_to_4607_is_byte_identical_and_carries_the_origin(run, tmp_path, with_origin):
    first = tmp_path / "first.4607"
    code, _, err = cli(run, "--to", "4607", "-o", first)
    assert code == 0, err
    extra = ("--origin", origin_of(run)) if with_origin else ()
    code, _, err = cli(first, "--to", "h5", "-o", tmp_path / "c.h5", *extra)
    assert code == 0, err
    with h5py.File(tmp_path / "c.h5") as f:
        assert ("origin_lat_deg" in f.attrs) == with_origin
        if with_origin:
            assert ",".join(str(float(f.attrs[k])) for k in (
                "origin_lat_deg", "origin_lon_deg", "origin_height_m")) == origin_of(run)
    code, _, err = cli(tmp_path / "c.h5", "--to", "4607", "-o", tmp_path / "again.4607")
    assert code == 0, err
    assert (tmp_path / "again.4607").read_bytes() == first.read_bytes()


def test_nul_padded_4607_converts_to_h5_and_back(tmp_path):
    from tests.formats.test_4607_round_trip import PT_MASK, fixture_file
    data = fixture_file(PT_MASK).replace(b"AFRLPLAT  ", b"AFRLPLAT\x00\x00").replace(
        b"hello analyst", b"hello\x00garbage")
    (tmp_path / "nul.4607").write_bytes(data)
    code, _, err = cli(tmp_path / "nul.4607", "--to", "h5", "-o", tmp_path / "nul.h5")
    assert code == 0, err
    assert store.read_table(tmp_path / "nul.h5", "free_texts")["text"].tolist() == ["hello"]
    code, _, err = cli(tmp_path / "nul.h5", "--to", "4607", "-o", tmp_path / "back.4607")
    assert code == 0, err
    # field-identical: the standard's space padding instead of the NULs, text up to the NUL
    assert (tmp_path / "back.4607").read_bytes() == fixture_file(PT_MASK, text=b"hello")


def test_empty_4607_file_is_an_error_not_an_empty_run_file(tmp_path):
    (tmp_path / "empty.4607").write_bytes(b"")
    code, _, err = cli(tmp_path / "empty.4607", "--to", "h5", "-o", tmp_path / "e.h5")
    assert code == 1 and "empty (0 bytes)" in err and err.count("\n") == 1
    assert not (tmp_path / "e.h5").exists()
