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
    """py-motmetrics' summary.  Its keep pass gives a track two truths held to the truth listed
    first; ours to the closer (docs/evaluation.md), so each step lists its truths by their
    distance to the track they held (read from the accumulator), which makes the two rules
    one."""
    acc = mm.MOTAccumulator(auto_id=True)
    for s in range(n_steps):
        a = np.flatnonzero(truth_at["step"] == s)
        b = tracks_at["step"] == s
        X = np.c_[truth_at["x_m"][a], truth_at["y_m"][a]]
        Y = np.c_[tracks_at["x_m"][b], tracks_at["y_m"][b]]
        D = np.sqrt(((X[:, None, :] - Y[None, :, :]) ** 2).sum(-1))
        D[D >= GATE_M] = np.nan
        oids, hids = truth_at["vehicle_id"][a].tolist(), tracks_at["track_id"][b].tolist()
        held = [D[i, hids.index(acc.m[o])] if acc.m.get(o) in hids else np.nan
                for i, o in enumerate(oids)]
        o = np.lexsort((oids, np.nan_to_num(held, nan=np.inf)))
        acc.update([oids[i] for i in o], hids, D[o])
    names = ["mota", "motp", "idf1", "idp", "idr", "num_switches", "num_false_positives",
             "num_misses", "num_matches"]
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


def dense_scene(rng, n_steps, n_truth, n_tracks, spread_m):
    """Truths and tracks scattered in a square a few gates wide: most steps are ambiguous."""
    truth, tracks = [], []
    for s in range(n_steps):
        truth += [(s, v, *rng.uniform(0, spread_m, 2)) for v in range(n_truth)
                  if rng.uniform() < 0.85]
        tracks += [(s, 100 + int(k), *rng.uniform(0, spread_m, 2))
                   for k in rng.permutation(n_tracks + 3)[:n_tracks] if rng.uniform() < 0.8]
    t, k = (np.array(a, float).reshape(-1, 4) for a in (truth, tracks))
    t, k = t[np.lexsort((t[:, 1], t[:, 0]))], k[np.lexsort((k[:, 1], k[:, 0]))]
    return ({"step": t[:, 0].astype(np.int64), "vehicle_id": t[:, 1].astype(np.int64),
             "x_m": t[:, 2], "y_m": t[:, 3]},
            {"step": k[:, 0].astype(np.int64), "track_id": k[:, 1].astype(np.int64),
             "x_m": k[:, 2], "y_m": k[:, 3]})


def test_a_pair_inside_the_gate_is_never_left_for_a_closer_one():
    """CLEAR-MOT matches as many pairs inside the gate as it can, then the least total
    distance (py-motmetrics: Munkres with the out-of-gate pairs forbidden).  Truth A has track 1
    at 14 m and track 2 at 37 m; truth B has track 1 at 37 m and track 2 beyond the gate.  The
    association used to take only A-1 (on min(d, g)²: 14² + 50² < 37² + 37²), scoring B as a
    miss and track 2 as false although both pairs are inside the gate."""
    truth_at = {"step": np.zeros(2, np.int64), "vehicle_id": np.array([0, 1]),
                "x_m": np.array([47.6, 73.1]), "y_m": np.array([65.5, 77.8])}
    tracks_at = {"step": np.zeros(2, np.int64), "track_id": np.array([1, 2]),
                 "x_m": np.array([36.0, 12.5]), "y_m": np.array([73.9, 77.8])}
    assigned = identity.associate(truth_at, tracks_at, 1, GATE_M)
    assert assigned.tolist() == [2, 1]
    out = clear_mot(truth_at, tracks_at, assigned, 0, GATE_M)
    assert out["false_negatives"] == out["false_positives"] == 0 and out["mota"] == 1.0


@pytest.mark.parametrize("seed", [10, 11])
def test_dense_scenes_match_py_motmetrics(seed):
    """Scenes where truths and tracks crowd within a gate of each other, so the association is
    ambiguous at most steps: the counts (misses, false positives, switches), MOTA, MOTP and IDF1
    equal py-motmetrics' (Euclidean distances, max_d = g); where two truths claim the track
    they held, the closer keeps it (py-motmetrics gives it to the truth listed first; the
    reference lists the truths closest first, see motmetrics_summary)."""
    rng = np.random.default_rng(seed)
    crowded = 0         # truth rows with two or more tracks inside the gate
    for _ in range(60):
        n_steps = int(rng.integers(1, 12))
        truth_at, tracks_at = dense_scene(rng, n_steps, int(rng.integers(1, 6)),
                                          int(rng.integers(1, 6)), float(rng.choice([60, 120])))
        if not len(truth_at["step"]):
            continue
        assigned = identity.associate(truth_at, tracks_at, n_steps, GATE_M)
        idm = identity.identity_metrics(truth_at, assigned, np.arange(n_steps, dtype=float))
        ours = clear_mot(truth_at, tracks_at, assigned, idm["switches"], GATE_M)
        ref = motmetrics_summary(truth_at, tracks_at, n_steps)
        assert (ours["false_negatives"], ours["false_positives"], idm["switches"]) == (
            ref["num_misses"], ref["num_false_positives"], ref["num_switches"])
        for name, ref_name in (("mota", "mota"), ("motp_m", "motp"), ("idf1", "idf1"),
                               ("idp", "idp"), ("idr", "idr")):
            assert ours[name] == pytest.approx(ref[ref_name], rel=1e-12, abs=1e-12,
                                               nan_ok=True), name
        same = truth_at["step"][:, None] == tracks_at["step"][None, :]
        d = np.hypot(truth_at["x_m"][:, None] - tracks_at["x_m"][None, :],
                     truth_at["y_m"][:, None] - tracks_at["y_m"][None, :])
        crowded += int(((same & (d < GATE_M)).sum(axis=1) >= 2).sum())
    assert crowded > 300
