"""gmtiflow-evaluate end to end: our own baseline tracks exported to CSV, re-imported and scored
give the run's /metrics; bad track files are one clear error with no output."""
import csv
import subprocess
import sys

import numpy as np
import pytest

from gmtiflow import convert, store
from gmtiflow.evaluate import cli as evaluate_cli


def cli(*args):
    proc = subprocess.run([sys.executable, "-m", "gmtiflow.evaluate.cli", *map(str, args)],
                          capture_output=True, text=True, timeout=120)
    return proc.returncode, proc.stdout, proc.stderr


def test_baseline_tracks_through_csv_score_as_the_run(run, tracks_csv, tmp_path):
    out = tmp_path / "scores.h5"
    code, stdout, err = cli(tracks_csv, run, "-o", out)
    assert code == 0, err
    expected = store.read_table(run, "metrics")
    assert expected["value"][list(expected["name"]).index("n_tracks")] > 0
    got = store.read_table(out, "metrics")
    assert list(got["name"]) == list(expected["name"])
    assert np.array_equal(got["value"], expected["value"], equal_nan=True)
    for table in ("metrics/ospa", "metrics/track_errors", "metrics/association"):
        a, b = store.read_table(run, table), store.read_table(out, table)
        for col in a:
            assert np.array_equal(a[col], b[col], equal_nan=a[col].dtype.kind == "f"), (table, col)
    # the summary is printed as a table
    assert stdout.splitlines()[0].split() == ["metric", "value", "unit"]
    assert any(line.split()[0] == "ospa_mean_m" for line in stdout.splitlines()[1:-1])
    assert stdout.strip().endswith(f"wrote {out}")


def test_csv_output_and_hdf5_track_input(run, tracks_csv, tmp_path):
    h5 = tmp_path / "tracks.h5"
    assert convert.main([str(tracks_csv), "--to", "h5", "-o", str(h5)]) == 0
    code, _, err = cli(h5, run, "--csv")
    assert code == 0, err
    out = tmp_path / "tracks.metrics.csv"                       # default name beside TRACKS
    rows = list(csv.DictReader(out.open()))
    expected = store.read_table(run, "metrics")
    assert [r["name"] for r in rows] == list(expected["name"])
    assert np.array_equal([float(r["value"]) for r in rows], expected["value"], equal_nan=True)


def _bad(path, text):
    path.write_text(text)
    return path


@pytest.mark.parametrize("text, needle", [
    ("time_s,track_id,x_m,y_m,heading\n0,1,0,0,1\n", "unknown column 'heading'"),
    ("time_s,track_id,x_m,y_m\n2,1,0,0\n1,1,5,0\n", "goes back in time"),
    ("time_s,track_id,x_m,y_m\n1,7,0,0\n1,7,5,0\n", "ids collide"),
    ("time_s,track_id,x_m,y_m\n1,7,0,nan\n", "not a finite number"),
    ("time_s,track_id,x_m\n1,7,0\n", "missing column 'y_m'"),
    ("track_id,x_m,y_m\n1,0,0\n", "missing the time"),
    ("time_utc,track_id,x_m,y_m\n08:00,1,0,0\n", "not an ISO-8601 time"),
])
def test_bad_track_files_are_one_error_and_no_output(run, tmp_path, text, needle):
    bad = _bad(tmp_path / "mine.csv", text)
    code, stdout, err = cli(bad, run)
    assert code == 1
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("gmtiflow-evaluate: error: ") and \
        str(bad) in lines[0] and needle in lines[0], err
    assert stdout == ""
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine.csv"]


def test_xml_tracks_and_a_missing_run_are_clear_errors(run, tmp_path):
    code, _, err = cli(_bad(tmp_path / "t.xml", "<x/>"), run)
    assert code == 1 and "no XML track form" in err
    code, _, err = cli(_bad(tmp_path / "t.csv", "time_s,track_id,x_m,y_m\n"), tmp_path / "no.h5")
    assert code == 1 and "no such run file" in err
    assert evaluate_cli.main([str(tmp_path / "t.csv"), str(run), "-o",
                              str(tmp_path / "t.csv")]) == 1       # would overwrite its input


def test_help_is_usable():
    code, out, _ = cli("--help")
    assert code == 0 and "TRACKS" in out and "RUN.h5" in out and "--csv" in out


def _csv(path, table):
    cols = list(table)
    lines = [",".join(cols)]
    for i in range(len(table[cols[0]])):
        lines.append(",".join(v if isinstance(v, str) else repr(float(v))
                              for v in (table[c][i] for c in cols)))
    path.write_text("\n".join(lines) + "\n")
    return path


def test_time_utc_and_lat_lon_score_as_time_s_and_enu(run, tracks_csv, tmp_path):
    from datetime import datetime, timedelta, timezone

    from gmtiflow import formats, frames
    tracks = formats.read_tracks_csv(tracks_csv)
    with store.open_run(run) as f:
        epoch = str(f.attrs["scene_epoch_utc"])
        origin = frames.Origin(float(f.attrs["origin_lat_deg"]), float(f.attrs["origin_lon_deg"]),
                               float(f.attrs["origin_height_m"]))
    t0 = datetime.fromisoformat(epoch.replace("Z", "+00:00"))
    lat, lon, h = frames.enu_to_geodetic(origin, tracks["x_m"], tracks["y_m"],
                                         np.zeros(len(tracks["x_m"])))
    other = {"time_utc": [(t0 + timedelta(seconds=float(t))).astimezone(timezone.utc)
                          .strftime("%Y-%m-%dT%H:%M:%S.%fZ") for t in tracks["time_s"]],
             "track_id": [str(int(i)) for i in tracks["track_id"]],
             "lat_deg": lat, "lon_deg": lon, "height_m": h,
             "vx_mps": tracks["vx_mps"], "vy_mps": tracks["vy_mps"],
             "confirmed": ["true" if c else "false" for c in tracks["confirmed"]]}
    plain = {k: tracks[k] for k in ("time_s", "track_id", "x_m", "y_m", "vx_mps", "vy_mps")}
    plain["track_id"] = [str(int(i)) for i in tracks["track_id"]]
    plain["confirmed"] = other["confirmed"]
    a = evaluate_cli.score(_csv(tmp_path / "enu.csv", plain), run)["metrics"]
    b = evaluate_cli.score(_csv(tmp_path / "geo.csv", other), run)["metrics"]
    assert np.isfinite(a["value"]).sum() > 10
    assert a["value"][list(a["name"]).index("n_tracks")] > 0
    assert np.allclose(a["value"], b["value"], rtol=1e-6, atol=1e-6, equal_nan=True)


@pytest.mark.parametrize("shift, needle", [
    ("unix_s", "Unix seconds"), ("unix_ms", "Unix milliseconds"),
    ("epoch_ms", "milliseconds from the epoch")])
def test_times_in_the_wrong_unit_are_one_error_naming_the_unit(run, tracks_csv, tmp_path, shift,
                                                               needle):
    from datetime import datetime

    from gmtiflow import formats
    tracks = formats.read_tracks_csv(tracks_csv)
    with store.open_run(run) as f:
        epoch = str(f.attrs["scene_epoch_utc"])
    unix = datetime.fromisoformat(epoch.replace("Z", "+00:00")).timestamp()
    t = tracks["time_s"]
    tracks["time_s"] = {"unix_s": t + unix, "unix_ms": (t + unix) * 1e3,
                        "epoch_ms": t * 1e3}[shift]
    path = _csv(tmp_path / "mine.csv", {k: tracks[k] for k in ("time_s", "x_m", "y_m")}
                | {"track_id": [str(int(i)) for i in tracks["track_id"]]})
    code, _, err = cli(path, run, "-o", tmp_path / "m.h5")
    assert code == 1 and needle in err and "time_s" in err, err
    assert not (tmp_path / "m.h5").exists()


def test_a_text_file_named_h5_is_called_not_hdf5(run, tmp_path):
    """It said "expected a track .csv or an .h5 file with /tracks, got suffix '.h5'"."""
    code, _, err = cli(_bad(tmp_path / "t.h5", "time_s,track_id,x_m,y_m\n"), run)
    assert code == 1 and "t.h5: not an HDF5 file (no HDF5 signature)" in err, err
    assert "got suffix" not in err
