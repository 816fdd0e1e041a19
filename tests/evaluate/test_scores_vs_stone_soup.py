"""A real run's per-step GOSPA against Stone Soup's GOSPAMetric (software we did not write),
with truth and tracks brought to the evaluation instants by a plain loop written from
docs/evaluation.md ("Time base", "Scored window"), on the run's own grid and on a 0.37 s grid
(instants between the truth samples, truth interpolated by np.interp)."""
import datetime
from collections import Counter

import numpy as np
import pytest

from gmtiflow.evaluate import evaluate
from gmtiflow.evaluate.config import MetricsConfig
from gmtiflow.store import read_table

ss = pytest.importorskip("stonesoup.metricgenerator.ospametric")
from stonesoup.types.array import StateVector  # noqa: E402
from stonesoup.types.state import State  # noqa: E402

EPOCH = datetime.datetime(2026, 1, 1)


def at(t):
    return EPOCH + datetime.timedelta(seconds=float(t))


def states_by_docs(truth, tracks, grid, cfg, until_s):
    """Truth at each instant inside a vehicle's sampled span (linear), and each confirmed
    track at the instants from its first row on while its last row at or before is at most
    max_extrapolation_s old, extrapolated at its velocity; after its last row, held to
    instants less than track_end_hold_s later, or max_extrapolation_s when that row is
    within max_extrapolation_s of the last dwell."""
    truth_states, track_states = [], []
    for v in np.unique(truth["vehicle_id"]):
        s = truth["vehicle_id"] == v
        t = truth["time_s"][s]
        for g in grid[(grid >= t.min() - 1e-9) & (grid <= t.max() + 1e-9)]:
            truth_states.append(State(StateVector([np.interp(g, t, truth["x_m"][s]),
                                                   np.interp(g, t, truth["y_m"][s])]),
                                      timestamp=at(g)))
    conf = tracks["confirmed"]
    for tid in np.unique(tracks["track_id"][conf]):
        s = conf & (tracks["track_id"] == tid)
        tt, x, y, vx, vy = (tracks[k][s] for k in ("time_s", "x_m", "y_m", "vx_mps", "vy_mps"))
        alive = tt[-1] >= until_s - cfg.max_extrapolation_s - 1e-9
        for g in grid:
            if g < tt[0] - 1e-9:
                continue
            if alive and g > tt[-1] + cfg.max_extrapolation_s + 1e-9:
                continue
            if not alive and g > tt[-1] + 1e-9 and g >= tt[-1] + cfg.track_end_hold_s - 1e-9:
                continue
            j = np.searchsorted(tt, g + 1e-9, side="right") - 1
            if g - tt[j] > cfg.max_extrapolation_s + 1e-9:
                continue
            dt = max(g - tt[j], 0.0)
            track_states.append(State(StateVector([x[j] + vx[j] * dt, y[j] + vy[j] * dt]),
                                      timestamp=at(g)))
    return truth_states, track_states


@pytest.mark.parametrize("eval_dt_s", [None, 0.37])
def test_gospa_per_step_is_stone_soups(run, eval_dt_s):
    cfg = MetricsConfig(eval_dt_s=eval_dt_s)
    truth, tracks, dwells = (read_table(run, n) for n in ("truth", "tracks", "dwells"))
    since, until = float(dwells["time_s"].min()), float(dwells["time_s"].max())
    steps = evaluate(cfg, truth, tracks, since_s=since, until_s=until)["metrics/ospa"]
    grid = steps["time_s"]
    assert grid[-1] <= until + 1e-9 and (eval_dt_s is None or grid[-1] > until - eval_dt_s)
    truth_states, track_states = states_by_docs(truth, tracks, grid, cfg, until)
    ids = list(range(len(track_states))), list(range(len(truth_states)))
    ref = ss.GOSPAMetric(c=cfg.cutoff_m, p=cfg.order_p).compute_over_time(
        track_states, ids[0], truth_states, ids[1])
    by_time = {m.timestamp: m.value for m in ref.value}
    empty = {"distance": 0.0, "localisation": 0.0, "missed": 0.0, "false": 0.0}
    for name, col in (("distance", "gospa_m"), ("localisation", "gospa_localisation"),
                      ("missed", "gospa_missed"), ("false", "gospa_false")):
        want = np.array([by_time.get(at(g), empty)[name] for g in grid], float)
        np.testing.assert_allclose(steps[col], want, rtol=1e-12, atol=1e-9, err_msg=col)
    count = Counter(s.timestamp for s in truth_states)
    n_truth = np.array([count[at(g)] for g in grid])
    assert np.array_equal(steps["n_truth"], n_truth) and steps["n_tracks"].sum() > 50
