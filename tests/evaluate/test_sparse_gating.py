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
    assert len(ti) > 20
    for found in (kalman.gated_pairs(x[:, :2], HPHt, z, R, h, wrap, gate),
                  kalman.dense_gated_pairs(HPHt, z, R, h, wrap, gate)):
        sti, sdi, snu, sd2 = found
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


def _reference_associate(truth_at, tracks_at, n_steps, gate_m):
    """The per-truth Python loop the vectorised association replaced (the specification)."""
    from scipy.optimize import linear_sum_assignment
    out = np.full(len(truth_at["step"]), -1, np.int64)
    tb = np.searchsorted(truth_at["step"], np.arange(n_steps + 1))
    kb = np.searchsorted(tracks_at["step"], np.arange(n_steps + 1))
    X = np.stack([truth_at["x_m"], truth_at["y_m"]], axis=1)
    Y = np.stack([tracks_at["x_m"], tracks_at["y_m"]], axis=1)
    tid, vid = tracks_at["track_id"], truth_at["vehicle_id"]
    g2, last = float(gate_m) ** 2, {}
    for s in np.flatnonzero((np.diff(tb) > 0) & (np.diff(kb) > 0)):
        a, b, c, d = tb[s], tb[s + 1], kb[s], kb[s + 1]
        D2 = (X[a:b, None, 0] - Y[None, c:d, 0]) ** 2 + (X[a:b, None, 1] - Y[None, c:d, 1]) ** 2
        ids, free_r, free_k, keep = tid[c:d], np.ones(b - a, bool), np.ones(d - c, bool), []
        for r in range(b - a):
            k = np.flatnonzero(ids == last.get(int(vid[a + r]), -99))
            if len(k) and D2[r, k[0]] < g2:
                keep.append((D2[r, k[0]], r, k[0]))
        for _, r, k in sorted(keep):
            if free_k[k]:
                out[a + r] = ids[k]
                free_r[r] = free_k[k] = False
        rr, kk = np.flatnonzero(free_r), np.flatnonzero(free_k)
        if len(rr) and len(kk):     # most pairs inside the gate, then least Σd: the pairs
            sub = D2[np.ix_(rr, kk)]  # beyond cost more than any matching (py-motmetrics' lap)
            inside_all = sub < g2
            d = np.sqrt(sub)
            forbidden = 2 * min(sub.shape) * (np.sqrt(g2) + 1) + 1
            r, k = linear_sum_assignment(np.where(inside_all, d, forbidden))
            inside = sub[r, k] < g2
            out[a + rr[r[inside]]] = ids[kk[k[inside]]]
        for r in np.flatnonzero(out[a:b] >= 0):
            last[int(vid[a + r])] = int(out[a + r])
    return out


@pytest.mark.parametrize("dense_pairs", [4096, 0])
def test_vectorised_association_is_the_per_truth_loop(monkeypatch, dense_pairs):
    from gmtiflow.evaluate import identity
    monkeypatch.setattr(identity, "DENSE_PAIRS", dense_pairs)
    rng = np.random.default_rng(7)
    n, steps = 150, 40
    step = np.repeat(np.arange(steps), n)
    vid = np.tile(np.arange(n), steps)
    pos0, vel = rng.uniform(0, 4000, (n, 2)), rng.normal(0, 8, (n, 2))
    truth_at = {"step": step, "vehicle_id": vid, "x_m": pos0[vid, 0] + vel[vid, 0] * step,
                "y_m": pos0[vid, 1] + vel[vid, 1] * step}
    # tracks: noisy copies with ids changing every 10 steps, some missing, some false
    keep = rng.random(len(step)) > 0.1
    tr_step = np.r_[step[keep], np.repeat(np.arange(steps), 20)]
    tracks_at = {"step": tr_step,
                 "track_id": np.r_[vid[keep] + 1000 * (step[keep] // 10), 10 ** 6 + np.arange(
                     20 * steps)],
                 "x_m": np.r_[truth_at["x_m"][keep] + rng.normal(0, 60, keep.sum()),
                              rng.uniform(0, 4000, 20 * steps)],
                 "y_m": np.r_[truth_at["y_m"][keep] + rng.normal(0, 60, keep.sum()),
                              rng.uniform(0, 4000, 20 * steps)]}
    o = np.argsort(tracks_at["step"], kind="stable")
    tracks_at = {k: v[o] for k, v in tracks_at.items()}
    want = _reference_associate(truth_at, tracks_at, steps, 200.0)
    got = identity.associate(truth_at, tracks_at, steps, 200.0)
    assert np.array_equal(got, want)
    assert (want >= 0).mean() > 0.5 and len(np.unique(want[want >= 0])) > n


@pytest.mark.parametrize("m,n", [(90, 120), (120, 120), (150, 100)])
def test_sparse_ospa_is_the_dense_ospa(monkeypatch, m, n):
    from gmtiflow.evaluate import ospa
    rng = np.random.default_rng(m + n)
    X = rng.uniform(0, 3000, (m, 2))
    Y = np.r_[X[: min(m, n) * 2 // 3] + rng.normal(0, 80, (min(m, n) * 2 // 3, 2)),
              rng.uniform(0, 3000, (n - min(m, n) * 2 // 3, 2))]
    dense = ospa.ospa_gospa(X, Y, 200.0, 2.0)
    monkeypatch.setattr(ospa, "DENSE_PAIRS", 0)
    sparse = ospa.ospa_gospa(X, Y, 200.0, 2.0)
    assert dense["n_assigned"] > 30
    for key in ("rows", "cols"):
        assert np.array_equal(sparse[key], dense[key])
    for key in ("localisation", "missed", "false", "gospa", "n_assigned"):
        assert sparse[key] == dense[key], key
    if m <= n:                                   # bit-identical
        assert sparse["ospa"] == dense["ospa"]
    else:                                        # the same terms summed in another order
        assert sparse["ospa"] == pytest.approx(dense["ospa"], rel=1e-13)


def test_close_pairs_are_every_pair_closer_than_the_cutoff():
    # the cell grid (and the k-d tree used when cell keys would overflow) find exactly the
    # pairs of one step closer than c, whatever their cell; brute force as the reference
    from gmtiflow.evaluate import neighbours
    rng = np.random.default_rng(5)
    X = rng.uniform(-1000, 1000, (400, 2))
    Y = np.r_[X[:200] + rng.normal(0, 150, (200, 2)), rng.uniform(-1000, 1000, (300, 2))]
    Y[7] = [np.nan, 0.0]
    sx, sy = rng.integers(0, 3, 400), rng.integers(0, 3, 500)
    diff = X[:, None, :] - Y[None, :, :]
    D = np.sqrt(np.einsum("ijk,ijk->ij", diff, diff))
    want_r, want_k = np.nonzero((D < 200.0) & (sx[:, None] == sy[None, :]))
    for finder in (neighbours.close_pairs, neighbours.close_pairs_tree):
        r, k, d = finder(X, Y, 200.0, sx, sy)
        assert len(r) > 100
        assert np.array_equal(r, want_r) and np.array_equal(k, want_k)
        assert np.array_equal(d, D[want_r, want_k])
    # the distances are the ones a k-d tree over (x, y, step) reports (IDF1's gate used those)
    from scipy.spatial import cKDTree
    A, B = np.c_[X, sx * 800.0], np.c_[Y, sy * 800.0]
    ok = np.isfinite(B).all(axis=1)
    found = cKDTree(A).sparse_distance_matrix(cKDTree(B[ok]), 200.0, output_type="ndarray")
    tree_d = dict(zip(zip(found["i"].tolist(), np.flatnonzero(ok)[found["j"]].tolist()),
                      found["v"].tolist()))
    r, k, d = neighbours.close_pairs(X, Y, 200.0, sx, sy)
    assert [tree_d[p] for p in zip(r.tolist(), k.tolist())] == d.tolist()


def test_ospa_series_solved_together_is_step_by_step(monkeypatch):
    # the steps above DENSE_PAIRS share one pair search and one assignment: the same numbers as
    # scoring each step on its own
    from gmtiflow.evaluate import ospa
    rng = np.random.default_rng(9)
    n_steps, parts_t, parts_k = 12, [], []
    for s in range(n_steps):
        m, n = int(rng.integers(0, 90)), int(rng.integers(0, 90))
        X = rng.uniform(0, 2000, (m, 2))
        Y = np.r_[X[: min(m, n)] + rng.normal(0, 60, (min(m, n), 2)),
                  rng.uniform(0, 2000, (n - min(m, n), 2))]
        parts_t.append((np.full(m, s), X))
        parts_k.append((np.full(n, s), Y))
    truth_at = {"step": np.concatenate([p[0] for p in parts_t]),
                "x_m": np.concatenate([p[1][:, 0] for p in parts_t]),
                "y_m": np.concatenate([p[1][:, 1] for p in parts_t])}
    tracks_at = {"step": np.concatenate([p[0] for p in parts_k]),
                 "x_m": np.concatenate([p[1][:, 0] for p in parts_k]),
                 "y_m": np.concatenate([p[1][:, 1] for p in parts_k])}
    monkeypatch.setattr(ospa, "DENSE_PAIRS", 100)
    got = ospa.series(truth_at, tracks_at, np.arange(float(n_steps)), 200.0, 2.0)
    assert (got["n_truth"] * got["n_tracks"] > 100).sum() >= 6
    for s in range(n_steps):
        one = ospa.ospa_gospa(parts_t[s][1], parts_k[s][1], 200.0, 2.0)
        for key, col in (("ospa", "ospa_m"), ("gospa", "gospa_m"),
                         ("localisation", "gospa_localisation"), ("missed", "gospa_missed"),
                         ("false", "gospa_false"), ("n_assigned", "n_assigned")):
            assert got[col][s] == one[key], (s, key)
    # the pairs searched once for all steps (evaluate() shares them with IDF1): the same series
    from gmtiflow.evaluate import clearmot, neighbours
    pairs = neighbours.step_pairs(truth_at, tracks_at, 200.0)
    shared = ospa.series(truth_at, tracks_at, np.arange(float(n_steps)), 200.0, 2.0, pairs)
    for col in got:
        assert np.array_equal(shared[col], got[col]), col
    tracks_at["track_id"] = np.arange(len(tracks_at["step"])) % 50
    truth_at["vehicle_id"] = np.arange(len(truth_at["step"])) % 40
    assert clearmot.idtp(truth_at, tracks_at, 200.0, pairs) == clearmot.idtp(truth_at, tracks_at,
                                                                            200.0) > 0


def test_small_and_vectorised_assignment_paths_agree(monkeypatch):
    # the plain-Python path (a dwell's few pairs) and the vectorised one make the same
    # decisions, also with tied costs (stars then go to the solver), costs at the gate, negative
    # costs (IDF1's -counts) and large ids
    from gmtiflow.evaluate import assignment
    rng = np.random.default_rng(11)
    n_multi = 0
    for it in range(600):
        nr, nc = int(rng.integers(1, 8)), int(rng.integers(1, 8))
        flat = rng.choice(nr * nc, int(rng.integers(1, nr * nc + 1)), replace=False)
        rows = flat // nc + int(rng.integers(0, 3)) * (7 if it % 2 else 7000)
        cols = flat % nc
        if it % 3 == 0:
            cost, gate = rng.uniform(0, 10, len(flat)), 9.0
        elif it % 3 == 1:
            cost, gate = rng.integers(0, 4, len(flat)).astype(float), 3.0
        else:
            cost, gate = -rng.integers(1, 4, len(flat)).astype(float), 0.0
        small = assignment.sparse_gated_assignment(rows, cols, cost, gate)
        monkeypatch.setattr(assignment, "_SMALL_PAIRS", 0)
        vector = assignment.sparse_gated_assignment(rows, cols, cost, gate)
        monkeypatch.setattr(assignment, "_SMALL_PAIRS", 512)
        assert np.array_equal(small[0], vector[0]) and np.array_equal(small[1], vector[1])
        n_multi += len(np.unique(rows)) < len(rows)
    assert n_multi > 300



@pytest.mark.parametrize("block_min", [1, 8])
@pytest.mark.parametrize("buffer_entries", [1, 64, 1 << 20])
def test_components_built_in_buffers_give_the_dense_assignment(monkeypatch, buffer_entries,
                                                               block_min):
    # small and large components (up to ~40 rows) built in flat buffers of any size, one
    # component alone or many together: each solved as gated_assignment solves it alone, ties
    # (integer costs) included
    from gmtiflow.evaluate import assignment
    monkeypatch.setattr(assignment, "_SMALL_PAIRS", 0)
    monkeypatch.setattr(assignment, "_BUFFER_ENTRIES", buffer_entries)
    monkeypatch.setattr(assignment, "_BLOCK_MIN", block_min)     # by shape blocks or one by one
    rng = np.random.default_rng(5)
    for integer in (False, True):
        nr, nc, gate = 300, 320, 9.0
        cost = np.full((nr, nc), np.inf)
        for size in (40, 25, 12, 3, 2, 2, 2, 1):
            for _ in range(3 if size > 3 else 12):      # many small ones of one shape
                rs = rng.choice(nr, size, replace=False)
                cs = rng.choice(nc, size + int(rng.integers(0, 3)), replace=False)
                block = rng.uniform(0, 8.9, (len(rs), len(cs)))
                block[rng.random(block.shape) < 0.6] = np.inf
                cost[np.ix_(rs, cs)] = np.floor(block) if integer else block
        r, c = np.nonzero(cost < gate)
        sr, sc = assignment.sparse_gated_assignment(r, c, cost[r, c], gate)
        dr, dc = _per_component(cost, gate)
        assert np.array_equal(sr, dr) and np.array_equal(sc, dc)
        assert len(dr) > 50


def _per_component(cost, gate):
    """gated_assignment of each connected component's own rows and columns (what
    sparse_gated_assignment promises), sorted by row."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    nr, nc = cost.shape
    r, c = np.nonzero(cost < gate)
    graph = coo_matrix((np.ones(len(r)), (r, nr + c)), shape=(nr + nc, nr + nc))
    _, label = connected_components(graph, directed=False)
    out_r, out_c = [], []
    for comp in np.unique(label[r]):
        rs = np.unique(r[label[r] == comp])
        cs = np.unique(c[label[nr + c] == comp])
        a, b = gated_assignment(cost[np.ix_(rs, cs)], gate)
        out_r.append(rs[a])
        out_c.append(cs[b])
    rr, cc = np.concatenate(out_r), np.concatenate(out_c)
    o = np.argsort(rr)
    return rr[o], cc[o]


def test_graph_components_group_as_the_union_find():
    # scipy on the pairs that share a row or column, the lone pairs labelled after them: the
    # same grouping of nodes as the plain union-find (labels may be numbered differently)
    from gmtiflow.evaluate import assignment
    rng = np.random.default_rng(4)
    for _ in range(20):
        nr, nc = int(rng.integers(1, 60)), int(rng.integers(1, 60))
        flat = rng.choice(nr * nc, int(rng.integers(1, min(nr * nc, 90) + 1)), replace=False)
        r_ids, r_idx = np.unique(flat // nc, return_inverse=True)
        c_ids, c_idx = np.unique(flat % nc, return_inverse=True)
        a = assignment._graph_components(r_idx, c_idx, len(r_ids), len(c_ids))
        b = assignment._components(r_idx, c_idx, len(r_ids), len(c_ids))
        assert a[0] == b[0]
        pairs = set(zip(a[1].tolist(), b[1].tolist()))
        assert len(pairs) == a[0]                 # a bijection between the two numberings


def test_chunks_of_steps_give_the_whole_search_and_assignment(monkeypatch):
    # step_pairs and OSPA's assignment by chunks of whole steps: the pairs and the series of
    # one search over all steps
    from gmtiflow.evaluate import neighbours, ospa
    rng = np.random.default_rng(13)
    n_steps = 15
    t_step = np.sort(rng.integers(1, n_steps, 900))
    k_step = np.sort(rng.integers(0, n_steps - 1, 800))
    truth_at = {"step": t_step, "x_m": rng.uniform(0, 3000, 900), "y_m": rng.uniform(0, 3000, 900)}
    tracks_at = {"step": k_step, "x_m": rng.uniform(0, 3000, 800),
                 "y_m": rng.uniform(0, 3000, 800)}
    X = np.c_[truth_at["x_m"], truth_at["y_m"]]
    Y = np.c_[tracks_at["x_m"], tracks_at["y_m"]]
    whole = neighbours.close_pairs(X, Y, 200.0, t_step, k_step)
    monkeypatch.setattr(ospa, "DENSE_PAIRS", 100)
    want = ospa.series(truth_at, tracks_at, np.arange(float(n_steps)), 200.0, 2.0, whole)
    for rows in (1, 150, 400, 10 ** 6):
        monkeypatch.setattr(neighbours, "CHUNK_ROWS", rows)
        chunks = neighbours.step_chunks(t_step, k_step, rows)
        assert chunks[0][0] == chunks[0][2] == 0 and chunks[-1][1::2] == (900, 800)
        assert all(a[1] == b[0] and a[3] == b[2] for a, b in zip(chunks, chunks[1:]))
        got = neighbours.step_pairs(truth_at, tracks_at, 200.0)
        assert all(np.array_equal(a, b) for a, b in zip(got, whole))
        series = ospa.series(truth_at, tracks_at, np.arange(float(n_steps)), 200.0, 2.0, got)
        for col in want:
            assert np.array_equal(series[col], want[col]), (rows, col)
