"""The baseline's sparse gating (k-d tree candidates, assignment per connected component) gives
exactly what the dense matrices give: the same pairs, bit-identical distances, the same tracks."""
import numpy as np
import pytest

from gmtiflow.evaluate import kalman
from gmtiflow.evaluate import tracker as tracker_mod
from gmtiflow.evaluate.assignment import gated_assignment, sparse_gated_assignment
from gmtiflow.evaluate.config import TrackerConfig
from gmtiflow.evaluate.synthetic import straight_scene


def _problem(rng, nt, nd, spread_m=3000.0):
    x = np.zeros((nt, 4))
    x[:, :2] = rng.uniform(0, spread_m, (nt, 2))
    x[:, 2:] = rng.normal(0, 10, (nt, 2))
    P = np.tile(np.diag([400.0, 400.0, 25.0, 25.0]), (nt, 1, 1))
    P[:, 0, 1] = P[:, 1, 0] = rng.uniform(-100, 100, nt)
    z = np.zeros((nd, 3))
    z[:, :2] = np.r_[x[: nd // 2, :2] + rng.normal(0, 30, (min(nd // 2, nt), 2)),
                     rng.uniform(0, spread_m, (nd - min(nd // 2, nt), 2))]
    z[:, 2] = rng.normal(0, 5, nd)
    R = np.zeros((nd, 3, 3))
    R[:, 0, 0], R[:, 1, 1], R[:, 2, 2] = rng.uniform(25, 900, nd), rng.uniform(25, 900, nd), 0.01
    h = np.zeros((nt, 3))
    h[:, :2] = x[:, :2]
    h[:, 2] = rng.normal(0, 5, nt)
    H = np.zeros((nt, 3, 4))
    H[:, 0, 0] = H[:, 1, 1] = 1.0
    H[:, 2, 2:] = rng.normal(0, 1, (nt, 2))
    return x, P, H, h, z, R, np.full(nd, 20.0)


@pytest.mark.parametrize("seed", range(4))
def test_gated_pairs_are_the_dense_pairs_bit_for_bit(seed):
    rng = np.random.default_rng(seed)
    x, P, H, h, z, R, wrap = _problem(rng, 120, 150)
    gate = 16.27
    nu_all, HPHt, d2_all = kalman.innovations(x, P, H, h, z, R, wrap, gate)
    ti, di = np.nonzero(d2_all < gate)
    sti, sdi, snu, sd2 = kalman.gated_pairs(x[:, :2], HPHt, z, R, h, wrap, gate)
    assert len(ti) > 20
    assert np.array_equal(sti, ti) and np.array_equal(sdi, di)
    assert np.array_equal(sd2, d2_all[ti, di]) and np.array_equal(snu, nu_all[ti, di])


@pytest.mark.parametrize("seed", range(6))
def test_sparse_assignment_is_the_dense_assignment(seed):
    rng = np.random.default_rng(seed)
    nr, nc, gate = 60, 70, 9.0
    cost = np.full((nr, nc), np.inf)
    # clusters of competing pairs (components of several rows and columns) and lone pairs
    for _ in range(25):
        rs = rng.choice(nr, rng.integers(1, 4), replace=False)
        cs = rng.choice(nc, rng.integers(1, 4), replace=False)
        cost[np.ix_(rs, cs)] = rng.uniform(0, 12, (len(rs), len(cs)))
    r, c = np.nonzero(cost < gate)
    sr, sc = sparse_gated_assignment(r, c, cost[r, c], gate)
    dr, dc = gated_assignment(cost, gate)
    assert np.array_equal(sr, dr) and np.array_equal(sc, dc)
    assert len(dr) > 5


def test_tracks_do_not_depend_on_the_dense_threshold(monkeypatch):
    scene = straight_scene(n_vehicles=40, n_revisits=30, revisit_s=5.0, spacing_m=150.0,
                           clutter_per_dwell=15.0, n_beams=3, seed=3)
    cfg = TrackerConfig()
    dense = tracker_mod.track(cfg, scene["detections"], scene["dwells"])
    monkeypatch.setattr(tracker_mod, "DENSE_PAIRS", 0)            # every dwell the k-d tree way
    sparse = tracker_mod.track(cfg, scene["detections"], scene["dwells"])
    assert set(dense) == set(sparse) and len(dense["track_id"]) > 500
    for k in dense:
        assert np.array_equal(dense[k], sparse[k]), k
