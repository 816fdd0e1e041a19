"""export.blind=true: no truth in any export (every file read back and grepped); the same run
without it does carry truth, so the test can fail."""
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.slow

from gmtiflow import formats, store
from gmtiflow.evaluate.protocol import TRUTH_DETECTION_COLUMNS

ROOT = Path(__file__).resolve().parents[2]
TRUTH_WORDS = TRUTH_DETECTION_COLUMNS + ("vehicle_id", "\"truth\"", "truth_application")


def run_cli(out, *overrides):
    env = dict(os.environ, HYDRA_FULL_ERROR="0")
    cmd = [sys.executable, "-m", "gmtiflow.cli", f"hydra.run.dir={out}", "scene.duration_s=30",
           "report.enabled=false", "progress=false", "export=all",
           "export.csv_tables=[detections,truth,tracks]", *overrides]
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, env=env, timeout=300)
    assert proc.returncode == 0, proc.stderr
    return out


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    base = tmp_path_factory.mktemp("blind")
    return run_cli(base / "open"), run_cli(base / "blind", "export.blind=true")


def exports(out):
    return sorted(p for p in out.iterdir() if p.is_file() and p.name != "run.h5"
                  and p.suffix in (".4607", ".xml", ".csv", ".geojson"))


def truth_in(path):
    """Truth found in one export: column/property names in text, the 4607 truth tag decoded."""
    if path.suffix == ".4607":
        det = formats.read_4607(path)["detections"]
        assert len(det["x_m"] if "x_m" in det else det["lat_deg"]) > 0
        found = [c for c in ("truth_id", "truth_application", "rcs_dbsm") if c in det
                 and np.any(np.asarray(det[c]) != -1) and np.any(np.isfinite(
                     np.asarray(det[c], float)))]
        return found
    text = path.read_text(encoding="utf-8")
    return [w for w in TRUTH_WORDS if w in text]


def test_the_open_exports_carry_truth(runs):
    open_dir, _ = runs
    names = {p.name for p in exports(open_dir)}
    assert {"detections.4607", "detections.xml", "detections.csv", "truth.csv",
            "scene.geojson"} <= names
    for name in ("detections.4607", "detections.xml", "detections.csv", "scene.geojson"):
        assert truth_in(open_dir / name), name


def test_blind_exports_carry_no_truth(runs):
    open_dir, blind_dir = runs
    files = exports(blind_dir)
    assert {p.name for p in files} == {p.name for p in exports(open_dir)} - {"truth.csv",
                                                                             "truth.geojson"}
    for path in files:
        assert truth_in(path) == [], path.name
    # the detections themselves are all there (each dwell's by measured slant range, the
    # order export.blind gives them), and truth stays in run.h5 for scoring
    a = formats.read_detections_csv(open_dir / "detections.csv")
    b = formats.read_detections_csv(blind_dir / "detections.csv")
    by_range = np.lexsort((a["azimuth_rad"], a["range_m"], a["dwell_id"]))
    for c in ("dwell_id", "range_m", "azimuth_rad", "x_m", "y_m", "range_rate_mps"):
        assert np.array_equal(a[c][by_range], b[c]), c
    assert len(b["x_m"]) > 0
    assert np.array_equal(np.sort(a["det_id"]), np.sort(b["det_id"]))
    assert np.any(by_range != np.arange(len(by_range)))     # the scene has reports to reorder
    assert "truth_id" in store.read_table(blind_dir / "run.h5", "detections")
    assert len(store.read_table(blind_dir / "run.h5", "truth")["time_s"]) > 0
