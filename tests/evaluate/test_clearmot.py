"""MOTA / MOTP / IDF1 against py-motmetrics (software we did not write) on random scenes whose
association is unambiguous (objects ≥ 4 gates apart), with misses, false tracks, id switches
and tracks handing over."""
import numpy as np
import pytest

from gmtiflow.evaluate import identity
from gmtiflow.evaluate.clearmot import clear_mot

mm = pytest.importorskip("motmetrics")

GATE_M = 50.0


def random_scene(seed, n_truth=6, n_steps=60):
    rng = np.random.default_rng(seed)
    truth, tracks = [], []
    next_id = 100
    for v in range(n_truth):
        base = np.array([v * 400.0, rng.uniform(-1000, 1000)])
        vel = rng.uniform(-5, 5, 2)
        tid = next_id
        next_id += 1
        for s in range(n_steps):
            p = base + vel * s
            truth.append((s, v, *p))
            if rng.uniform() < 0.15:                 # missed
                continue
            if rng.uniform() < 0.03:                 # the track is replaced by a new id
                tid = next_id
                next_id += 1
            err = rng.normal(0, 8.0, 2)
            tracks.append((s, tid, *(p + err)))
    for s in range(n_steps):                         # false tracks far from everything
        for _ in range(rng.poisson(0.5)):
            tracks.append((s, 900 + int(rng.integers(0, 3)), rng.uniform(5e4, 6e4), 0.0))
    t = np.array(truth)
    k = np.array(tracks)
    # one false track id may appear twice at a step: keep the first
    _, first = np.unique(k[:, 0] * 10000 + k[:, 1], return_index=True)
    k = k[np.sort(first)]
    truth_at = {"step": t[:, 0].astype(np.int64), "vehicle_id": t[:, 1].astype(np.int64),
                "x_m": t[:, 2], "y_m": t[:, 3]}
    o = np.lexsort((k[:, 1], k[:, 0]))
    k = k[o]
    tracks_at = {"step": k[:, 0].astype(np.int64), "track_id": k[:, 1].astype(np.int64),
                 "x_m": k[:, 2], "y_m": k[:, 3]}
    o = np.lexsort((truth_at["vehicle_id"], truth_at["step"]))
    truth_at = {c: v[o] for c, v in truth_at.items()}
    return truth_at, tracks_at, n_steps


def motmetrics_summary(truth_at, tracks_at, n_steps):
    acc = mm.MOTAccumulator(auto_id=True)
    for s in range(n_steps):
        a = truth_at["step"] == s
        b = tracks_at["step"] == s
        X = np.c_[truth_at["x_m"][a], truth_at["y_m"][a]]
        Y = np.c_[tracks_at["x_m"][b], tracks_at["y_m"][b]]
        D = np.sqrt(((X[:, None, :] - Y[None, :, :]) ** 2).sum(-1))
        D[D >= GATE_M] = np.nan
        acc.update(truth_at["vehicle_id"][a].tolist(), tracks_at["track_id"][b].tolist(), D)
    names = ["mota", "motp", "idf1", "idp", "idr", "num_switches", "num_false_positives",
             "num_misses"]
    return mm.metrics.create().compute(acc, metrics=names, name="x").iloc[0]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_mota_motp_idf1_match_py_motmetrics(seed):
    truth_at, tracks_at, n_steps = random_scene(seed)
    assigned = identity.associate(truth_at, tracks_at, n_steps, GATE_M)
    grid = np.arange(n_steps, dtype=float)
    idm = identity.identity_metrics(truth_at, assigned, grid)
    ours = clear_mot(truth_at, tracks_at, assigned, idm["switches"], GATE_M)
    ref = motmetrics_summary(truth_at, tracks_at, n_steps)
    assert idm["switches"] == ref["num_switches"] > 0
    assert ours["false_negatives"] == ref["num_misses"] > 0
    assert ours["false_positives"] == ref["num_false_positives"] > 0
    for ours_name, ref_name in (("mota", "mota"), ("motp_m", "motp"), ("idf1", "idf1"),
                                ("idp", "idp"), ("idr", "idr")):
        assert ours[ours_name] == pytest.approx(ref[ref_name], rel=1e-12, abs=1e-12), ours_name


def test_perfect_tracks_score_one_and_zero():
    truth_at, _, n_steps = random_scene(3)
    tracks_at = {"step": truth_at["step"], "track_id": truth_at["vehicle_id"] + 7,
                 "x_m": truth_at["x_m"], "y_m": truth_at["y_m"]}
    assigned = identity.associate(truth_at, tracks_at, n_steps, GATE_M)
    out = clear_mot(truth_at, tracks_at, assigned, 0, GATE_M)
    assert out["mota"] == 1.0 and out["idf1"] == 1.0 and out["motp_m"] == 0.0
