"""The scored window is the tracker's: from its first dwell to its last, on the truth's own
time step, whether or not a vehicle is on the road.

Found 2026-11-28 (metrics audit): the evaluation grid was the truth table's sample times, and
/truth has rows only for vehicles on the road, so the instants before the first vehicle
started, after the last one left and between were not on the grid: a tracker's false tracks
there cost nothing (no OSPA/GOSPA step, no CLEAR-MOT false positive)."""
import numpy as np
import pytest

from gmtiflow.evaluate.config import MetricsConfig
from gmtiflow.evaluate.stage import evaluate, summary_value
from tests.evaluate.helpers import line, track_table, truth_table

C = MetricsConfig().cutoff_m


def score(truth, tracks, since_s, until_s):
    return evaluate(MetricsConfig(), truth, tracks, since_s=since_s, until_s=until_s)


def perfect(truth, vid, tid):
    s = truth["vehicle_id"] == vid
    return [(tid, t, x, y) for t, x, y in zip(truth["time_s"][s], truth["x_m"][s],
                                              truth["y_m"][s])]


@pytest.mark.parametrize("where, truth_spans, false_times", [
    ("before the first vehicle", {0: (30, 60)}, np.arange(5.5, 20.6, 0.5)),
    ("between two vehicles", {0: (0, 20), 1: (40, 60)}, np.arange(24.5, 32.6, 0.5)),
    ("after the last vehicle", {0: (0, 30)}, np.arange(40.5, 48.6, 0.5)),
])
def test_false_tracks_count_wherever_no_vehicle_is_on_the_road(where, truth_spans,
                                                               false_times):
    truth = truth_table({v: line(np.arange(a, b + 1.0), 1000.0 * v, 0.0, 10.0, 0.0)
                         for v, (a, b) in truth_spans.items()})
    good = sum((perfect(truth, v, 100 + v) for v in truth_spans), [])
    bad = [(9, t, 5e4, 5e4) for t in false_times]
    clean = score(truth, track_table(good), 0.016, 60.0)
    out = score(truth, track_table(good + bad), 0.016, 60.0)
    steps = out["metrics/ospa"]
    # the grid: the truth's 1 s step from the first dwell's to the last's, tracks or not
    assert steps["time_s"].tolist() == list(np.arange(1.0 if 0 not in
                                                      [a for a, _ in truth_spans.values()]
                                                      else 0.0, 61.0))
    assert clean["metrics/ospa"]["time_s"].tolist() == steps["time_s"].tolist()
    assert summary_value(clean, "ospa_mean_m") == 0.0 and summary_value(clean, "mota") == 1.0
    # the false track is scored from its first row on, and less than track_end_hold_s (1 s)
    # after its last one: the instants a + 1 .. b + 1 of rows a + 0.5 .. b + 0.5
    held = (steps["time_s"] > false_times[0]) & (steps["time_s"] < false_times[-1] + 1.0)
    assert held.sum() == len(false_times) // 2 + 1, where
    np.testing.assert_array_equal(steps["ospa_m"][held], C)
    np.testing.assert_array_equal(steps["gospa_false"][held], C ** 2 / 2)
    np.testing.assert_array_equal(steps["ospa_m"][~held], 0.0)
    gt = len(truth["time_s"])
    assert summary_value(out, "mota") == pytest.approx(1.0 - held.sum() / gt, abs=1e-12)
    assert summary_value(out, "idf1") == pytest.approx(2 * gt / (2 * gt + held.sum()),
                                                       abs=1e-12)


def test_without_a_window_the_grid_is_the_truth_span_as_before():
    truth = truth_table({0: line(np.arange(30.0, 61.0), 0.0, 0.0, 10.0, 0.0)})
    out = evaluate(MetricsConfig(), truth, track_table(perfect(truth, 0, 3)))
    assert out["metrics/ospa"]["time_s"].tolist() == list(np.arange(30.0, 61.0))


def test_a_regular_grid_spans_the_window_too():
    truth = truth_table({0: line(np.arange(30.0, 61.0), 0.0, 0.0, 10.0, 0.0)})
    cfg = MetricsConfig(eval_dt_s=2.5)
    out = evaluate(cfg, truth, track_table([(9, 3.0, 5e4, 0.0)]), since_s=0.0, until_s=60.0)
    t = out["metrics/ospa"]["time_s"]
    assert t[0] == 0.0 and t[-1] == 60.0 and np.allclose(np.diff(t), 2.5)
    assert out["metrics/ospa"]["ospa_m"][t == 2.5] == 0.0     # before the track's first row
    assert out["metrics/ospa"]["ospa_m"][t == 5.0] == 0.0     # 2 s after it (hold 1 s)
    assert (out["metrics/ospa"]["n_truth"][t < 30.0] == 0).all()


def test_a_run_with_late_vehicles_scores_from_its_first_dwell(tmp_path):
    from gmtiflow import pipeline
    from gmtiflow.evaluate.cli import score as cli_score
    from gmtiflow.store import read_table
    from tests.conftest import compose_app
    run = pipeline.run(compose_app([
        "vehicles=random", "vehicles.random.count=2", "vehicles.random.start_time_min_s=40",
        "vehicles.random.start_time_max_s=50", "scene.duration_s=90", "progress=false",
        "report.enabled=false", "export=none"]), tmp_path)
    truth, dwells = read_table(run, "truth"), read_table(run, "dwells")
    steps = read_table(run, "metrics/ospa")
    assert truth["time_s"].min() >= 40.0
    assert steps["time_s"][0] - dwells["time_s"].min() < 1.0 + 1e-9
    assert steps["time_s"][-1] <= dwells["time_s"].max() < steps["time_s"][-1] + 1.0
    # gmtiflow-evaluate scores the run's own tracks on the same grid, to the same numbers
    again = cli_score(run, run)
    np.testing.assert_array_equal(again["metrics/ospa"]["time_s"], steps["time_s"])
    np.testing.assert_array_equal(again["metrics"]["value"], read_table(run, "metrics")["value"])
