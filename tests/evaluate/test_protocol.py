"""The tracker protocol: batches (blind, time order, empty dwells, several sensors), a user's
tracker by import path through the CLI, errors that name the user's class and dwell."""
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from gmtiflow import store
from gmtiflow.errors import ConfigError
from gmtiflow.evaluate.config import TrackerConfig
from gmtiflow.evaluate.protocol import (BLIND_DETECTION_COLUMNS, TRUTH_DETECTION_COLUMNS,
                                        TrackerError, batches, load_tracker, stream)
from gmtiflow.evaluate.synthetic import gmti_scene, straight_scene
from gmtiflow.evaluate.tracker import track
from tests.evaluate.helpers import check_truth_free_order

ROOT = Path(__file__).resolve().parents[2]
USER = "tests.evaluate.user_trackers"


def run_cli(tmp_path, *overrides):
    env = dict(os.environ, HYDRA_FULL_ERROR="0")
    cmd = [sys.executable, "-m", "gmtiflow.cli", f"hydra.run.dir={tmp_path}",
           "scene.duration_s=40", "report.enabled=false", "export=none", "progress=false",
           *overrides]
    return subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, env=env, timeout=300)


@pytest.fixture(scope="module")
def scene():
    return gmti_scene(n_vehicles=6, n_revisits=12, pd=0.5, seed=5)


def test_batches_are_blind_in_time_order_and_include_empty_dwells(scene):
    det, dw = scene["detections"], scene["dwells"]
    assert set(TRUTH_DETECTION_COLUMNS) & set(det), "the scene should carry truth to drop"
    got = list(batches(det, dw))
    assert len(got) == len(dw["dwell_id"])
    times = np.array([b.time_s for b in got])
    assert np.all(np.diff(times) >= 0)
    n_det = np.array([b.n_detections for b in got])
    assert n_det.sum() == len(det["dwell_id"])
    assert (n_det == 0).any(), "dwells that saw nothing are batches too"
    for b in got:
        assert set(b.detections) <= set(BLIND_DETECTION_COLUMNS)
        assert np.all(b.detections["dwell_id"] == b.dwells["dwell_id"][0])
        assert np.all(b.detections["sensor_id"] == 0)
        k = np.flatnonzero(dw["dwell_id"] == b.dwells["dwell_id"][0])[0]
        assert b.dwells["platform_x_m"][0] == dw["platform_x_m"][k]
        # the detections of a dwell are the table's, by measured slant range
        mine = np.flatnonzero(det["dwell_id"] == b.dwells["dwell_id"][0])
        mine = mine[np.argsort(det["range_m"][mine], kind="stable")]
        assert np.array_equal(b.detections["x_m"], det["x_m"][mine])


def test_a_dwells_reports_come_by_range_not_by_truth():
    """The synthetic table (like run.h5) lists a dwell's reports by truth (false alarms, then
    targets by vehicle id) with det_ids to match; a tracker must see neither that order nor
    det_ids that follow it."""
    scene = straight_scene(n_vehicles=4, n_revisits=20, clutter_per_dwell=3.0,
                           clutter_half_width_m=1500.0, seed=3)
    det, dw = scene["detections"], scene["dwells"]
    seen = [b.detections for b in batches(det, dw)]
    seen = {k: np.concatenate([s[k] for s in seen]) for k in seen[0]}
    mixed, truth_ordered = check_truth_free_order(seen, det)
    assert mixed >= 15 and truth_ordered < mixed / 2, (mixed, truth_ordered)
    # the baseline gets the same batches: its tracks whichever order the table had
    shuffled = {k: v[::-1] for k, v in det.items()}
    a, b = track(TrackerConfig(), det, dw), track(TrackerConfig(), shuffled, dw)
    assert len(a["track_id"]) > 50
    for k in a:
        assert np.array_equal(a[k], b[k]), k


def test_revisit_batches_hold_whole_revisits_and_give_the_baseline_the_same_tracks(scene):
    det, dw = scene["detections"], scene["dwells"]
    per_rev = list(batches(det, dw, per="revisit"))
    assert len(per_rev) == len(np.unique(dw["revisit_id"]))
    for b in per_rev:
        assert len(np.unique(b.dwells["revisit_id"])) == 1 and b.dwells["revisit_end"][-1]
        assert not b.dwells["revisit_end"][:-1].any()
    a = track(TrackerConfig(), det, dw)
    b = track(TrackerConfig(per="revisit"), det, dw)
    assert a.keys() == b.keys() and len(a["track_id"]) > 50
    for k in a:
        assert np.array_equal(a[k], b[k]), k


def test_several_sensors_interleave_in_time_with_their_own_geometry():
    # two sensors whose dwell ids collide: every detection must land with its own sensor's dwell
    dw = {"dwell_id": np.array([0, 1, 0, 1]), "sensor_id": np.array([0, 0, 1, 1]),
          "time_s": np.array([0.0, 2.0, 1.0, 3.0]), "revisit_id": np.array([0, 1, 0, 1])}
    for i, c in enumerate(("platform_x_m", "platform_y_m", "platform_z_m", "platform_vx_mps",
                           "platform_vy_mps", "platform_vz_mps")):
        dw[c] = np.array([100.0, 101.0, 200.0, 201.0]) + i
    det = {"dwell_id": np.array([1, 0, 1, 0]), "sensor_id": np.array([1, 1, 0, 0]),
           "x_m": np.array([11.0, 10.0, 1.0, 0.0]), "y_m": np.zeros(4),
           "truth_id": np.array([5, 6, 7, 8])}
    got = list(batches(det, dw))
    assert [b.time_s for b in got] == [0.0, 1.0, 2.0, 3.0]
    assert [int(b.dwells["sensor_id"][0]) for b in got] == [0, 1, 0, 1]
    assert [b.detections["x_m"].tolist() for b in got] == [[0.0], [10.0], [1.0], [11.0]]
    assert [float(b.dwells["platform_x_m"][0]) for b in got] == [100.0, 200.0, 101.0, 201.0]
    assert all("truth_id" not in b.detections for b in got)
    per_rev = list(batches(det, dw, per="revisit"))
    assert [b.n_dwells for b in per_rev] == [1, 1, 1, 1]   # revisits of two sensors interleave


def test_stream_of_a_run_file_equals_the_in_memory_batches(tmp_path):
    proc = run_cli(tmp_path)
    assert proc.returncode == 0, proc.stderr
    run = tmp_path / "run.h5"
    det, dw = store.read_table(run, "detections"), store.read_table(run, "dwells")
    import gmtiflow
    streamed = list(gmtiflow.stream(run))              # the public entry point
    assert len(streamed) == len(dw["dwell_id"]) > 0
    assert sum(b.n_detections for b in streamed) == len(det["det_id"])
    assert all(not set(b.detections) & set(TRUTH_DETECTION_COLUMNS) for b in streamed)
    # each dwell's reports by measured range, det_ids not following run.h5's order (targets
    # by vehicle id, then false alarms)
    seen = {k: np.concatenate([b.detections[k] for b in streamed])
            for k in streamed[0].detections}
    mixed, truth_ordered = check_truth_free_order(seen, det)
    assert mixed > 0 and truth_ordered < mixed, (mixed, truth_ordered)
    assert "area_range_m" in streamed[0].dwells          # footprint centre from the origin
    again = list(stream(run, per="revisit"))
    assert sum(b.n_dwells for b in again) == len(streamed)


def test_a_users_tracker_class_runs_through_the_cli_and_is_scored(tmp_path):
    log = tmp_path / "seen.json"
    mine = run_cli(tmp_path / "mine", "tracker=python", f"tracker.target={USER}.RecordingTracker",
                    f"+tracker.params.log_path={log}", "+tracker.params.confirm_m=3")
    assert mine.returncode == 0, mine.stderr
    seen = json.loads(log.read_text())
    assert seen["reset"] == 1 and seen["finished"] == 1 and seen["origin"]
    assert seen["truth_columns"] == [] and "sigma_range_m" in seen["columns"]
    assert np.all(np.diff(seen["times"]) >= 0)
    run = tmp_path / "mine" / "run.h5"
    dw = store.read_table(run, "dwells")
    assert sorted(seen["dwell_ids"]) == sorted(dw["dwell_id"].tolist())
    assert 0 in seen["n_det"]
    assert "target: tests.evaluate.user_trackers.RecordingTracker" in store.read_text(run, "config")
    # the user's class wraps the baseline: the same tracks and the same scores as the built-in
    base = run_cli(tmp_path / "base")
    assert base.returncode == 0, base.stderr
    for table in ("tracks", "metrics"):
        a = store.read_table(run, table)
        b = store.read_table(tmp_path / "base" / "run.h5", table)
        for k in a:
            assert np.array_equal(a[k], b[k], equal_nan=a[k].dtype.kind == "f"), (table, k)
    m = store.read_table(run, "metrics")
    assert m["value"][list(m["name"]).index("n_tracks")] > 0


def test_a_bug_in_the_users_tracker_names_the_class_and_the_dwell(tmp_path, scene):
    proc = run_cli(tmp_path, "tracker=python", f"tracker.target={USER}.FailsAtDwell",
                    "+tracker.params.n=3")
    assert proc.returncode == 1
    assert f"{USER}.FailsAtDwell.update() raised at dwell" in proc.stderr
    assert "batch 2" in proc.stderr and "KeyError" in proc.stderr
    assert not (tmp_path / "run.h5").exists()
    with pytest.raises(TrackerError, match=r"FailsAtDwell.update\(\) raised at dwell 4 "):
        track(TrackerConfig(target=f"{USER}.FailsAtDwell", params={"n": 5}),
              scene["detections"], scene["dwells"])


def test_missing_target_and_bad_trackers_are_config_errors(tmp_path, scene):
    proc = run_cli(tmp_path, "tracker=python")
    assert proc.returncode == 1 and "tracker.target" in proc.stderr
    with pytest.raises(ConfigError, match="cannot import module 'nope'"):
        load_tracker("nope.Tracker")
    with pytest.raises(ConfigError, match="has no 'Nothing'"):
        load_tracker(f"{USER}.Nothing")
    with pytest.raises(ConfigError, match="lacks the tracker method.*update"):
        load_tracker(f"{USER}.NoUpdate")
    with pytest.raises(ConfigError, match="tracker.params"):
        load_tracker(f"{USER}.PlotTracker", {"unknown_m": 1})


def test_a_plot_tracker_without_time_or_velocity_is_accepted(scene):
    out = track(TrackerConfig(target=f"{USER}:PlotTracker"), scene["detections"],
                scene["dwells"])
    det = scene["detections"]
    assert len(out["track_id"]) == len(det["det_id"])
    i = np.searchsorted(det["det_id"], out["track_id"])
    assert np.array_equal(out["time_s"], det["time_s"][i])
