"""Merging of unresolved reports (paper eq. 18, DESIGN §5.6)."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gmtiflow.sensor import merge as mg

DR = 50.0       # range cell, m
DAZ = 0.01      # azimuth cell, rad
DRR = 0.5       # range-rate cell, m/s


def _merge(r, az, *, dwell=None, snr=None, tid=None, **kw):
    n = len(r)
    dwell = np.zeros(n, int) if dwell is None else dwell
    snr = np.ones(n) if snr is None else snr
    tid = np.arange(n) if tid is None else tid
    return mg.merge_reports(dwell, r, az, snr, tid, DR, DAZ, **kw)


# ---------------------------------------------------------------- the probability itself

def test_probability_is_one_half_at_one_cell_in_every_dimension():
    assert mg.merge_probability(DR, 0.0, DR, DAZ) == 0.5
    assert mg.merge_probability(0.0, DAZ, DR, DAZ) == 0.5
    assert mg.merge_probability(0.0, 0.0, DR, DAZ, DRR, DRR) == 0.5
    assert mg.merge_probability(DR, DAZ, DR, DAZ) == 0.25
    # Matches the textbook form exp(-1/2 d^T R_u^-1 d), R_u = A / (2 ln 2).
    d = np.array([30.0, 0.004])
    ru = np.diag([DR ** 2, DAZ ** 2]) / (2 * np.log(2))
    assert mg.merge_probability(*d, DR, DAZ) == pytest.approx(np.exp(-0.5 * d @ np.linalg.solve(ru, d)), rel=1e-12)


# ---------------------------------------------------------------- threshold mode

def test_threshold_one_half_merges_exactly_at_one_cell_and_not_beyond():
    at = _merge([1000.0, 1050.0], [0.5, 0.5], threshold=0.5)
    assert at.group.tolist() == [0, 0] and at.merged.tolist() == [True]
    beyond = _merge([1000.0, 1050.0 + 1e-6], [0.5, 0.5], threshold=0.5)
    assert beyond.group.tolist() == [0, 1]
    stricter = _merge([1000.0, 1050.0], [0.5, 0.5], threshold=0.5 + 1e-12)
    assert stricter.group.tolist() == [0, 1]


def test_far_apart_never_merge_in_either_mode():
    r = np.array([1000.0, 1000.0 + 6 * DR])  # P_u = 2^-36, beyond the draw-mode cut-off
    dwell = np.repeat(np.arange(2000), 2)
    rr = np.tile(r, 2000)
    az = np.full(len(rr), 1.0)
    tid = np.tile([7, 8], 2000)
    for kw in ({"mode": "threshold", "threshold": 1e-10}, {"mode": "draw", "seed": 1}):
        res = mg.merge_reports(dwell, rr, az, np.ones(len(rr)), tid, DR, DAZ, **kw)
        assert not res.merged.any()


def test_same_position_in_different_dwells_never_merge():
    res = _merge([1000.0, 1000.0, 1000.0], [0.3, 0.3, 0.3], dwell=np.array([0, 1, 2]))
    assert res.group.tolist() == [0, 1, 2]


def test_convoy_in_one_cell_becomes_one_report_with_all_ancestors():
    r = 20_000.0 + np.array([0.0, 8.0, 16.0, 24.0, 32.0])      # within one range cell
    az = np.full(5, 1.2) + np.array([0, 1, 2, 1, 0]) * 1e-3
    snr = np.array([10.0, 40.0, 20.0, 5.0, 25.0])
    tid = np.array([11, 12, 13, 14, 15])
    plain = _merge(r, az, snr=snr, tid=tid)
    assert len(plain.range_m) == 1 and plain.n_ancestors.tolist() == [5]
    assert sorted(plain.ancestor_truth_id.tolist()) == tid.tolist()
    assert plain.ancestor_row.tolist() == [0] * 5
    assert plain.truth_id.tolist() == [12] and plain.strongest.tolist() == [1]
    assert plain.snr[0] == pytest.approx(snr.sum())
    assert plain.range_m[0] == pytest.approx(r.mean()) and plain.azimuth_rad[0] == pytest.approx(az.mean())
    power = _merge(r, az, snr=snr, tid=tid, centroid="power")
    assert power.range_m[0] == pytest.approx(np.sum(snr * r) / snr.sum())


def test_no_chaining_every_ancestor_within_one_cell_of_its_report():
    # A-B, B-C, C-D one cell apart (P = 1/2 each): A, B, C merge (each within one cell of
    # their centroid), D does not join (A would be 1.5 cells from the centroid of ABCD);
    # the old transitive one-pass rule made one report of all four.
    res = _merge([1000.0, 1050.0, 1100.0, 1150.0], [0.5] * 4, threshold=0.5)
    assert res.group.tolist() == [0, 0, 0, 1]
    # a long chain 0.9 cells apart never gives a report with an ancestor beyond one cell
    r = 1000.0 + 0.9 * DR * np.arange(60)
    for mode, kw in (("threshold", {}), ("draw", dict(seed=3))):
        for iterate in (False, True):
            res = _merge(r, np.full(60, 0.5), mode=mode, iterate=iterate, **kw)
            sep = np.abs(r - res.range_m[res.group]) / DR
            assert sep.max() <= 1.0 + 1e-9, (mode, iterate, sep.max())
            assert res.n_ancestors.max() <= 3


def test_iterate_until_none_left():
    # A=(0,0) and B=(1,0) cells merge; C=(0.5, 0.95) is 1.07 cells from each (no merge in pass 1)
    # but 0.95 cells from their centroid, so the dense mode takes it in pass 2.
    r = 10_000.0 + DR * np.array([0.0, 1.0, 0.5])
    az = 0.2 + DAZ * np.array([0.0, 0.0, 0.95])
    one = _merge(r, az, iterate=False)
    assert one.group.tolist() == [0, 0, 1] and one.passes == 1
    dense = _merge(r, az, iterate=True)
    assert dense.group.tolist() == [0, 0, 0] and dense.passes == 2
    assert dense.range_m[0] == pytest.approx(r.mean())  # centroid of the original ancestors


def test_azimuth_differences_wrap_through_north():
    res = _merge([5000.0, 5000.0], [0.002, 2 * np.pi - 0.002])
    assert res.merged.tolist() == [True]
    assert 0.0 <= res.azimuth_rad[0] < 2 * np.pi
    assert min(res.azimuth_rad[0], 2 * np.pi - res.azimuth_rad[0]) < 1e-12


def test_range_rate_separates_targets_in_the_same_cell():
    r, az = [1000.0, 1000.0], [0.5, 0.5]
    res = mg.merge_reports([0, 0], r, az, [1, 1], [1, 2], DR, DAZ, range_rate_mps=[0.0, 3 * DRR],
                           range_rate_cell_mps=DRR)
    assert res.group.tolist() == [0, 1]
    res = mg.merge_reports([0, 0], r, az, [1, 1], [1, 2], DR, DAZ, range_rate_mps=[0.0, DRR],
                           range_rate_cell_mps=DRR)
    assert res.group.tolist() == [0, 0] and res.range_rate_mps[0] == pytest.approx(DRR / 2)


def test_unmerged_reports_keep_their_values_bit_for_bit():
    rg = np.random.default_rng(3)
    r = rg.uniform(1e4, 5e4, 300)
    az = rg.uniform(0, 2 * np.pi, 300)
    res = _merge(r, az)
    single = ~res.merged
    assert np.array_equal(res.range_m[single], r[res.strongest[single]])
    assert np.array_equal(res.azimuth_rad[single], az[res.strongest[single]])


def test_cells_must_be_constant_within_a_dwell():
    with pytest.raises(ValueError, match="constant within a dwell"):
        mg.merge_reports([0, 0], [1, 2], [0, 0], [1, 1], [1, 2], [50.0, 60.0], DAZ)
    ok = mg.merge_reports([0, 1], [1, 2], [0, 0], [1, 1], [1, 2], [50.0, 60.0], DAZ)
    assert len(ok.range_m) == 2


def test_empty_input():
    res = _merge(np.zeros(0), np.zeros(0))
    assert len(res.group) == 0 and len(res.range_m) == 0 and res.passes == 0


# ---------------------------------------------------------------- draw mode

def _binomial_ok(k, n, p, z=4.5):
    return abs(k - n * p) <= z * np.sqrt(n * p * (1 - p))


@pytest.mark.parametrize("cells, p", [((1.0, 0.0), 0.5), ((1.0, 1.0), 0.25), ((0.5, 0.0), 2 ** -0.25)])
def test_draw_mode_merges_with_probability_p_u(cells, p):
    n = 4000
    dwell = np.repeat(np.arange(n), 2)
    r = np.tile([30_000.0, 30_000.0 + cells[0] * DR], n)
    az = np.tile([0.7, 0.7 + cells[1] * DAZ], n)
    tid = np.tile([3, 4], n)
    res = mg.merge_reports(dwell, r, az, np.ones(2 * n), tid, DR, DAZ, mode="draw", seed=2024)
    k = int(res.merged.sum())
    assert _binomial_ok(k, n, p), (k, n * p)


def test_draw_is_common_random_numbers_per_pair_of_targets():
    base = dict(mode="draw", seed=5)
    n = 500
    dwell = np.repeat(np.arange(n), 2)
    r = np.tile([30_000.0, 30_050.0], n)
    az = np.full(2 * n, 0.7)
    tid = np.tile([3, 4], n)
    a = mg.merge_reports(dwell, r, az, np.ones(2 * n), tid, DR, DAZ, **base)
    # Add a far-away target to every dwell: the pair's decisions do not change.
    dwell2 = np.concatenate([dwell, np.arange(n)])
    r2 = np.concatenate([r, np.full(n, 45_000.0)])
    az2 = np.concatenate([az, np.full(n, 0.7)])
    tid2 = np.concatenate([tid, np.full(n, 99)])
    b = mg.merge_reports(dwell2, r2, az2, np.ones(3 * n), tid2, DR, DAZ, **base)
    assert np.array_equal(a.group[0::2] == a.group[1::2], b.group[0:2 * n:2] == b.group[1:2 * n:2])
    c = mg.merge_reports(dwell, r, az, np.ones(2 * n), tid, DR, DAZ, mode="draw", seed=6)
    assert not np.array_equal(a.merged, c.merged)


def test_pair_id_keys_the_draw_when_truth_ids_repeat():
    n = 4000
    dwell = np.repeat(np.arange(n), 2)
    r = np.tile([30_000.0, 30_000.0 + DR], n)
    az = np.full(2 * n, 0.7)
    tid = np.full(2 * n, -1)                        # two false alarms per dwell
    pid = np.tile([1_000_001, 1_000_002], n)
    res = mg.merge_reports(dwell, r, az, np.ones(2 * n), tid, DR, DAZ, mode="draw", seed=8, pair_id=pid)
    assert _binomial_ok(int(res.merged.sum()), n, 0.5)
    again = mg.merge_reports(dwell, r, az, np.ones(2 * n), tid, DR, DAZ, mode="draw", seed=8,
                             pair_id=pid + 10)
    assert not np.array_equal(res.merged, again.merged)


def test_draw_mode_needs_a_seed():
    with pytest.raises(ValueError, match="seed"):
        _merge([1.0, 2.0], [0.0, 0.0], mode="draw")


# ---------------------------------------------------------------- kd-tree vs brute force

def _brute_force(dwell, r, az, snr, tid, *, mode, threshold, seed, iterate, p_min=1e-9):
    """The documented rule, pair by pair: accepted pairs of the original reports; rounds in
    which candidate group pairs (sparse: linked by an accepted original pair, best P_u; dense
    after the first round: the current reports re-tested) are kept only if every ancestor
    lies within one cell of the merged centroid, and each group's best candidate under the
    order (-P_u, lo, hi) merges when it is also the partner's best."""
    n = len(r)
    label = np.arange(n)
    ident0 = mg.report_identity(tid)
    pts = np.column_stack([r / DR, az / DAZ])

    def decide(p, d, ia, ib):
        if mode == "threshold":
            return p >= threshold
        return p >= p_min and mg.draw_uniform(seed, d, ia, ib) < p

    acc = {}
    for i in range(n):
        for j in range(i + 1, n):
            if dwell[i] == dwell[j]:
                p = np.exp2(-np.sum((pts[i] - pts[j]) ** 2))
                if decide(p, dwell[i], ident0[i], ident0[j]):
                    acc[(i, j)] = p
    first = True
    while True:
        groups = sorted(set(label.tolist()))
        cand = {}
        if iterate and not first:
            cen = {g: pts[label == g].mean(axis=0) for g in groups}
            gid = {g: np.bitwise_xor.reduce(ident0[label == g]) for g in groups}
            for a in groups:
                for b in groups:
                    if a < b and dwell[label == a][0] == dwell[label == b][0]:
                        p = np.exp2(-np.sum((cen[a] - cen[b]) ** 2))
                        if decide(p, dwell[label == a][0], gid[a], gid[b]):
                            cand[(a, b)] = p
        else:
            for (i, j), p in acc.items():
                a, b = sorted((label[i], label[j]))
                if a != b:
                    cand[(a, b)] = max(cand.get((a, b), 0.0), p)
        first = False
        valid = {}
        for (a, b), p in cand.items():
            m = pts[(label == a) | (label == b)]
            if np.max(np.sum((m - m.mean(axis=0)) ** 2, axis=1)) <= 1.0 + 1e-9:
                valid[(a, b)] = p
        if not valid:
            break
        order = sorted(valid, key=lambda k: (-valid[k], k[0], k[1]))
        best = {}
        for rank, (a, b) in enumerate(order):
            best.setdefault(a, rank)
            best.setdefault(b, rank)
        for rank, (a, b) in enumerate(order):
            if best[a] == rank and best[b] == rank:
                label[label == b] = a
    return mg._canonical(label)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(n=st.integers(0, 40), n_dwells=st.integers(1, 4), spread=st.floats(0.5, 6.0),
       mode=st.sampled_from(["threshold", "draw"]), threshold=st.floats(0.05, 0.95),
       iterate=st.booleans(), seed=st.integers(0, 2 ** 31))
def test_kdtree_equals_brute_force(n, n_dwells, spread, mode, threshold, iterate, seed):
    g = np.random.default_rng(seed)
    dwell = g.integers(0, n_dwells, n)
    r = 20_000.0 + g.uniform(0, spread * DR, n)
    az = 1.0 + g.uniform(0, spread * DAZ, n)
    snr = g.uniform(1, 100, n)
    tid = g.permutation(1000)[:n]
    fast = mg.merge_reports(dwell, r, az, snr, tid, DR, DAZ, mode=mode, threshold=threshold,
                            seed=seed, iterate=iterate, circular_azimuth=False)
    slow = _brute_force(dwell, r, az, snr, tid, mode=mode, threshold=threshold, seed=seed, iterate=iterate)
    assert np.array_equal(fast.group, slow)
    # no chaining: every ancestor within one cell of its merged report
    if n:
        sep2 = ((r - fast.range_m[fast.group]) / DR) ** 2 + ((az - fast.azimuth_rad[fast.group]) / DAZ) ** 2
        assert np.all(sep2 <= 1.0 + 1e-9)
    if iterate and mode == "threshold" and len(fast.range_m) > 1:
        # Dense mode leaves no pair of output reports in a dwell at or above the threshold
        # whose merge would keep every ancestor within one cell (the rounds end when none is left)
        for a in range(len(fast.range_m)):
            for b in range(a + 1, len(fast.range_m)):
                if fast.dwell_id[a] != fast.dwell_id[b]:
                    continue
                p = mg.merge_probability(fast.range_m[a] - fast.range_m[b],
                                         fast.azimuth_rad[a] - fast.azimuth_rad[b], DR, DAZ)
                m = (fast.group == a) | (fast.group == b)
                cr, ca = r[m].mean(), az[m].mean()
                ok = np.all(((r[m] - cr) / DR) ** 2 + ((az[m] - ca) / DAZ) ** 2 <= 1.0 + 1e-9)
                assert not (p >= threshold * (1 + 1e-9) and ok), (a, b, p)


# ---------------------------------------------------------------- the fast paths, against the plain ones

def _pairs_as_set(i, j, p):
    order = np.lexsort((j, i))
    return i[order], j[order], p[order]


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(n=st.integers(0, 300), n_dwells=st.integers(1, 6), spread=st.floats(0.5, 60.0),
       dims=st.integers(2, 3), crowd=st.booleans(), seed=st.integers(0, 2 ** 31))
def test_sweep_finds_the_kdtree_pairs_bit_for_bit(n, n_dwells, spread, dims, crowd, seed):
    """The range sweep gives the kd-tree's pairs and P_u's, whatever the crowding (a crowded
    chunk, with many reports at one range, goes to the tree itself after its passes)."""
    g = np.random.default_rng(seed)
    pts = g.uniform(0.0, spread, (n, dims)) + 4000.0
    if crowd and n:
        pts[: n // 2, 0] = 4000.0 + np.round(pts[: n // 2, 0] - 4000.0) * 0.0   # one range
    pts[g.random(n) < 0.1] = pts[0] if n else 0.0        # exact duplicates
    rank = np.sort(g.integers(0, n_dwells, n))
    radius = mg.cutoff_cells("draw")
    fast = _pairs_as_set(*mg._near_pairs(pts, rank, radius))
    tree = _pairs_as_set(*mg._near_pairs_tree(pts, rank, radius))
    for a, b in zip(fast, tree):
        assert a.dtype == b.dtype and a.tobytes() == b.tobytes()
    assert np.all(rank[fast[0]] == rank[fast[1]]) and np.all(fast[0] < fast[1])


def test_sweep_keeps_a_pair_exactly_at_the_cut_off():
    # threshold 0.5: the cut-off is one cell, and a pair one cell apart merges
    pts = np.array([[10.0, 0.0], [11.0, 0.0], [10.0, 1.0], [12.0 + 1e-6, 0.0]])
    i, j, p = mg._near_pairs(pts, np.zeros(4, np.int64), mg.cutoff_cells("threshold", 0.5))
    assert sorted(zip(i.tolist(), j.tolist())) == [(0, 1), (0, 2)]
    assert p.tolist() == [0.5, 0.5]


def test_canonical_numbers_groups_by_their_first_member():
    label = np.array([5, 5, 2, 9, 2, 0, 9])
    assert mg._canonical(label).tolist() == [0, 0, 1, 2, 1, 3, 2]
    big = np.array([10 ** 9, 3, 10 ** 9])          # far beyond the row count: np.unique's path
    assert mg._canonical(big).tolist() == [0, 1, 0]
    g = np.random.default_rng(3)
    for _ in range(20):
        lab = g.integers(0, 50, 200)
        _, first, inv = np.unique(lab, return_index=True, return_inverse=True)
        rank = np.empty(len(first), np.int64)
        rank[np.argsort(first, kind="stable")] = np.arange(len(first))
        assert np.array_equal(mg._canonical(lab), rank[inv])


def test_group_edges_keep_the_most_probable_link_per_pair_of_groups():
    a = np.array([3, 1, 2, 1, 4, 2, 0])
    b = np.array([1, 3, 2, 0, 2, 4, 1])
    p = np.array([0.2, 0.7, 0.9, 0.4, 0.1, 0.3, 0.4])
    lo, hi, best = mg._group_edges(a, b, p)
    assert list(zip(lo.tolist(), hi.tolist(), best.tolist())) == [
        (0, 1, 0.4), (1, 3, 0.7), (2, 4, 0.3)]        # (2, 2) is no link


def test_decide_draws_as_draw_uniform_per_pair():
    g = np.random.default_rng(5)
    n = 500
    dwell = g.integers(0, 40, n)
    ident = mg.report_identity(g.permutation(10 * n)[:n])
    ident[7] = ident[8]                               # equal identities: either order
    i = g.integers(0, n, 3000)
    j = g.integers(0, n, 3000)
    i[:2], j[:2] = (7, 8), (8, 7)
    p = g.random(3000)
    got = mg._decide(p, "draw", 0.5, 11, dwell, ident, i, j)
    want = mg.draw_uniform(11, dwell[i], ident[i], ident[j]) < p
    assert np.array_equal(got, want) and 0 < got.sum() < len(got)


def test_strongest_ancestor_is_the_first_of_the_highest_snr_in_input_order():
    # three reports in one cell, two at the top SNR: the first of those is the strongest;
    # a NaN SNR takes the sorting path (NaN sorts last: never the strongest)
    r = [1000.0, 1001.0, 1002.0, 5000.0, 5001.0]
    az = [0.5] * 5
    for snr, want in (([2.0, 5.0, 5.0, 1.0, 1.0], [1, 3]), ([np.nan, 5.0, 4.0, 1.0, 3.0], [1, 4])):
        res = _merge(r, az, snr=np.array(snr), tid=np.array([10, 11, 12, 13, 14]),
                     mode="threshold", threshold=1e-3)
        assert res.group.tolist() == [0, 0, 0, 1, 1]
        assert res.strongest.tolist() == want
        assert res.truth_id.tolist() == [10 + w for w in want]


@pytest.mark.parametrize("n, sort", [(0, True), (1, True), (2, False), (1000, True),
                                     (1000, False), (30_000, True)])
def test_dwell_groups_are_np_uniques_first_index_and_inverse(n, sort):
    """merge_reports' per-dwell grouping: read off where the dwell changes when the reports
    come in dwell order (the sensor's), np.unique's values either way."""
    d = np.random.default_rng(n).integers(0, max(1, n // 10), n).astype(np.int64)
    if sort:
        d.sort()
    first, rank = mg._dwell_groups(d)
    _, first0, rank0 = np.unique(d, return_index=True, return_inverse=True)
    assert first.dtype == first0.dtype and rank.dtype == rank0.dtype
    assert np.array_equal(first, first0) and np.array_equal(rank, rank0.ravel())
