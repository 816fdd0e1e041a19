"""``gmtiflow-report RUN_DIR --tracks T.csv [--baseline]`` end to end: the run report for an
external tracker's tracks, scored against the run's truth, and the side-by-side page."""
import csv
import re
import shutil
import subprocess
import sys

import numpy as np
import pytest

from gmtiflow import store
from gmtiflow.report.run_report import PAGES


def report(*args):
    proc = subprocess.run([sys.executable, "-m", "gmtiflow.report.cli", *map(str, args)],
                          capture_output=True, text=True, timeout=300)
    return proc.returncode, proc.stdout, proc.stderr


def pages(pdf):
    return len(re.findall(rb"/Type\s*/Page[^s]", pdf.read_bytes()))


def page_text(pdf, page):
    if shutil.which("pdftotext") is None:
        pytest.skip("pdftotext (poppler-utils) not installed")
    return subprocess.run(["pdftotext", "-f", str(page), "-l", str(page), str(pdf), "-"],
                          capture_output=True, text=True, check=True).stdout


def shifted(src, dst, dx_m):
    rows = list(csv.DictReader(src.open()))
    with dst.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        for r in rows:
            r["x_m"] = repr(float(r["x_m"]) + dx_m)
            w.writerow(r)
    return dst


def test_external_tracks_get_the_run_report_and_a_side_by_side(run, tracks_csv, tmp_path):
    out = tmp_path / "mine.pdf"
    code, stdout, err = report(run.parent, "--tracks", tracks_csv, "--baseline", "-o", out)
    assert code == 0, err
    assert stdout.strip().splitlines()[-1] == str(out)
    scored = out.with_suffix(".h5")
    # the baseline's own tracks, exported and scored as external tracks: the same numbers
    expected, got = store.read_table(run, "metrics"), store.read_table(scored, "metrics")
    assert list(got["name"]) == list(expected["name"])
    assert np.array_equal(got["value"], expected["value"], equal_nan=True)
    # every other table is the run's
    for table in ("truth", "detections", "dwells", "looks"):
        a, b = store.read_table(run, table), store.read_table(scored, table)
        assert set(a) == set(b), table
        for c in a:
            assert np.array_equal(a[c], b[c], equal_nan=a[c].dtype.kind == "f"), (table, c)
    assert store.read_attrs(store.open_run(scored))["tracks_file"] == str(tracks_csv)
    # the run report (the same pages as the run's own) plus the side-by-side after the title
    assert pages(out) == len(PAGES) + 1
    title = page_text(out, 1)                           # long paths wrap on the page
    assert "external tracks: " in title and "baseline.csv" in title
    side = page_text(out, 2)
    assert "Side by side" in side and "baseline.csv" in side and "nn_kalman" in side
    assert "OSPA mean (m)" in side and "IDF1" in side


@pytest.mark.slow
def test_worse_tracks_score_worse_on_the_same_truth(run, tracks_csv, tmp_path):
    bad = shifted(tracks_csv, tmp_path / "off.csv", 150.0)
    code, _, err = report(run, "--tracks", bad, "--baseline")     # run.h5 works too
    assert code == 0, err
    out = run.parent / "report_off.pdf"                             # default name, beside the run
    assert out.is_file()

    def value(path, name):
        m = store.read_table(path, "metrics")
        return float(m["value"][list(m["name"]).index(name)])
    assert value(out.with_suffix(".h5"), "ospa_mean_m") > value(run, "ospa_mean_m") + 5
    assert value(out.with_suffix(".h5"), "position_rmse_m") > 100


def test_bad_track_file_is_one_error_and_no_report(run, tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("time_s,track_id,x_m,y_m\n0,1,0,0\n0,1,5,5\n")
    out = tmp_path / "bad.pdf"
    code, stdout, err = report(run.parent, "--tracks", bad, "-o", out)
    assert code == 1
    assert err.startswith("gmtiflow-report: error: ") and "bad.csv" in err
    assert len(err.strip().splitlines()) == 1
    assert not out.exists() and not out.with_suffix(".h5").exists()
    code, _, err = report(run.parent, "--baseline")
    assert code == 2 and "--baseline goes with --tracks" in err
