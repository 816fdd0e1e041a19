r"""Merging of unresolved reports within a dwell (paper §5.3, eq. 18; DESIGN §5.6).

Two reports *i*, *j* of the same dwell are merged with probability

.. math::

    P_u(i, j) = \exp\!\left(-\tfrac12\, d^\top R_u^{-1} d\right), \qquad
    R_u = A / (2 \ln 2), \qquad A = \mathrm{diag}(\Delta r^2, \Delta\phi^2[, \Delta\dot r^2]),

with *d* the differences in range, azimuth (and optionally range rate) and Δ the resolution cell
sizes. Writing :math:`s^2 = \sum_k (d_k/\Delta_k)^2` (the separation in cells) this is exactly
:math:`P_u = 2^{-s^2}`: ½ at one cell apart, ¼ at √2 cells. We evaluate it as ``exp2(-s²)``
so that ``P_u`` is exactly 0.5 at exactly one cell.

Decision per pair (``mode``):

* ``"threshold"``: merge when ``P_u >= threshold`` (a pair exactly at the threshold merges);
* ``"draw"``: merge when ``u < P_u``, with *u* a counter-based uniform
  (:func:`gmtiflow.rng.pair_uniform`) keyed by ``counter_key(seed, "sensor", "merge")`` and the
  counters (dwell id, identity of the lower report, identity of the higher report), where a
  report's identity is a hash of its truth id, or of ``pair_id`` when given (a merged report:
  the XOR of its ancestors' hashes). The draw of a pair therefore depends only on the seed, the dwell and the two targets
  (common random numbers: adding a far-away target changes nothing here).

No chaining.  A merged report's ancestors all lie within one resolution cell of it (separation
s ≤ 1 in the scaled metric, range rate included when given): merges are made in rounds; in each
round a candidate pair of (possibly merged) reports is kept only if every original ancestor of
both lies within one cell of their merged centroid, and each report merges with its most
probable kept candidate when that candidate's best is it too (a matching under one global order
of the pairs, P_u descending, then the lower and higher report number: the globally most probable
kept pair always merges, so every round merges something until none is left).  A line of
targets one cell apart therefore becomes reports of at most three, not one report of all of them
(the paper's transitive one pass gave up to 54 ancestors in one report, 8 cells from a member).

Passes (``iterate``):

* ``False`` (sparse): the pair decisions are made once, on the original reports; the rounds then
  merge groups linked by an accepted original pair (priority: its P_u).
* ``True`` (dense): after the first round the current reports (merged ones at their centroids)
  are tested again, until a round merges nothing. In draw mode a pair of unchanged reports
  keeps its draw, so it is not re-rolled; a merged report has a new identity and a new draw.

``passes`` counts the rounds that merged something.

Merged report: at the centroid of its (original) ancestors in range, azimuth and range rate —
``centroid="plain"`` (default; the paper's "geometrical average", DESIGN §5.6) or ``"power"``
(weighted by linear SNR, closer to where a processor's peak interpolation lands); SNR = the sum of
the ancestors' linear SNRs (incoherent power sum); truth id = the strongest ancestor's (ties: the
first in input order); dwell = the ancestors' dwell.

Azimuth: with ``circular_azimuth=True`` (default; world azimuths in [0, 2π)) differences are taken
modulo 2π and merged azimuths are returned in [0, 2π); with ``False`` (antenna scan angles)
values are used as they are. Within a dwell, azimuths are unwrapped around the dwell's first
report, which is exact as long as a dwell spans less than π (a beam does).

Neighbour search: a sweep along range over the scaled coordinates ``(r/Δr, φ/Δφ[, ṙ/Δṙ])``,
the reports sorted by (dwell, range) and each compared with its successors while they are within
the cut-off radius in range, so only nearby pairs of the same dwell are ever formed (the pairs
of one :class:`scipy.spatial.cKDTree` over those coordinates plus a separating dwell coordinate,
queried with :meth:`~scipy.spatial.cKDTree.query_pairs`, which takes over when many reports share
a range). Cut-off: threshold mode ``s_max = sqrt(log2(1/threshold))`` (exact:
every pair that could pass is found); draw mode ``s_max = sqrt(log2(1/p_min))`` with
``p_min = 1e-9`` by default (≈ 5.5 cells): pairs further apart, whose merge probability is below
1e-9, are never merged.

Cell sizes may be scalars or per-report arrays, but must be constant within a dwell (azimuth
cells vary from dwell to dwell with the scan angle); this is checked.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from gmtiflow import rng
from gmtiflow.sensor import fastnp

MODES = ("threshold", "draw")
CENTROIDS = ("plain", "power")
TWO_PI = 2.0 * np.pi


@dataclass(frozen=True)
class MergeResult:
    """Outcome of :func:`merge_reports`: m output reports built from n input reports.

    ``group[i]`` is the output row of input report *i* (output rows are ordered by their first
    input report, so an input without merges keeps its relative order). The per-output arrays
    have length m. ``ancestor_row``/``ancestor_truth_id`` list one row per (merged output report,
    ancestor) — only for outputs with more than one ancestor — ready for
    ``/detection_ancestors`` once rows are mapped to det ids.
    """

    group: np.ndarray            # (n,) int64
    dwell_id: np.ndarray         # (m,) int64
    range_m: np.ndarray          # (m,)
    azimuth_rad: np.ndarray      # (m,)
    range_rate_mps: Optional[np.ndarray]  # (m,) or None when not given
    snr: np.ndarray              # (m,) linear, summed over ancestors
    truth_id: np.ndarray         # (m,) int64, strongest ancestor's
    strongest: np.ndarray        # (m,) int64 index of the strongest ancestor in the input
    n_ancestors: np.ndarray      # (m,) int64
    ancestor_row: np.ndarray     # (k,) int64 output row
    ancestor_truth_id: np.ndarray  # (k,) int64
    ancestor_index: np.ndarray   # (k,) int64 input index of the ancestor
    passes: int                  # passes run (0 when there was nothing to compare)

    @property
    def merged(self) -> np.ndarray:
        """(m,) bool: the output report has more than one ancestor."""
        return self.n_ancestors > 1


def merge_probability(d_range_m, d_azimuth_rad, range_cell_m, azimuth_cell_rad,
                      d_range_rate_mps=None, range_rate_cell_mps=None) -> np.ndarray:
    """Eq. (18): ``P_u = exp(-½ dᵀ R_u⁻¹ d) = 2^(-s²)``, s the separation in resolution cells."""
    s2 = (np.asarray(d_range_m) / range_cell_m) ** 2 + (np.asarray(d_azimuth_rad) / azimuth_cell_rad) ** 2
    if d_range_rate_mps is not None:
        s2 = s2 + (np.asarray(d_range_rate_mps) / range_rate_cell_mps) ** 2
    return np.exp2(-s2)


def cutoff_cells(mode: str, threshold: float = 0.5, p_min: float = 1e-9) -> float:
    """Neighbour-search radius in cells: beyond it no pair can be (threshold) or is (draw) merged."""
    p = threshold if mode == "threshold" else p_min
    return float(np.sqrt(np.log2(1.0 / p)))


def report_identity(truth_id) -> np.ndarray:
    """uint64 identity of original reports for the draw-mode counters: a hash of the truth id.

    A merged report's identity is the XOR of its ancestors' identities (order-free).
    """
    return rng.pair_hash(rng.counter_key(0, "merge-identity"), np.asarray(truth_id, dtype=np.int64))


def draw_uniform(seed: int, dwell_id, identity_a, identity_b) -> np.ndarray:
    """The draw-mode uniform of a pair (symmetric in a, b): merge when it is below ``P_u``."""
    a = np.asarray(identity_a, dtype=np.uint64).view(np.int64)
    b = np.asarray(identity_b, dtype=np.uint64).view(np.int64)
    return rng.pair_uniform(rng.counter_key(seed, "sensor", "merge"), dwell_id,
                            np.minimum(a, b), np.maximum(a, b))


def _per_report(value, n: int, name: str) -> np.ndarray:
    arr = np.broadcast_to(np.asarray(value, dtype=float), (n,))
    if np.any(~np.isfinite(arr)) or np.any(arr <= 0):
        raise ValueError(f"{name} must be finite and > 0")
    return arr


def _group_reduce_xor(values: np.ndarray, label: np.ndarray, m: int) -> np.ndarray:
    order = np.argsort(label, kind="stable")
    lab = label[order]
    starts = np.flatnonzero(np.r_[True, lab[1:] != lab[:-1]])
    out = np.zeros(m, dtype=np.uint64)
    out[lab[starts]] = np.bitwise_xor.reduceat(values[order], starts)
    return out


def _canonical(label: np.ndarray) -> np.ndarray:
    """Relabel groups 0..m-1 in order of their first member."""
    label = np.asarray(label)
    n = len(label)
    if n == 0 or label.min() < 0 or label.max() >= 4 * n + 64:
        _, first, inverse = np.unique(label, return_index=True, return_inverse=True)
        rank = np.empty(len(first), dtype=np.int64)
        rank[np.argsort(first, kind="stable")] = np.arange(len(first))
        return rank[inverse.ravel()]
    # without a sort: each label's first member, then the groups numbered in the order of
    # their first members (the positions where a member is its group's first, ascending)
    first = np.full(int(label.max()) + 1, n, np.int64)
    np.minimum.at(first, label, np.arange(n, dtype=np.int64))
    leads = np.flatnonzero(first[label] == np.arange(n))
    rank = np.empty(len(first), dtype=np.int64)
    rank[label[leads]] = np.arange(len(leads), dtype=np.int64)
    return rank[label]


def merge_reports(dwell_id, range_m, azimuth_rad, snr, truth_id, range_cell_m, azimuth_cell_rad,
                  range_rate_mps=None, range_rate_cell_mps=None, *, mode: str = "threshold",
                  threshold: float = 0.5, seed: Optional[int] = None, iterate: bool = False,
                  centroid: str = "plain", circular_azimuth: bool = True,
                  p_min: float = 1e-9, pair_id=None) -> MergeResult:
    """Merge unresolved reports of the same dwell (see the module doc for the model).

    Parameters
    ----------
    dwell_id, range_m, azimuth_rad, snr, truth_id : (n,) arrays
        Candidate reports (``snr`` linear power; ``truth_id`` −1 allowed for false alarms).
    range_cell_m, azimuth_cell_rad : float or (n,) array
        Resolution cell sizes Δr, Δφ (constant within a dwell).
    range_rate_mps, range_rate_cell_mps : (n,) array and float, optional
        Give both to include range rate in the separation.
    mode : "threshold" | "draw"
    threshold : float in (0, 1]
        Threshold mode: merge when ``P_u >= threshold``.
    seed : int
        Root seed; required in draw mode.
    iterate : bool
        False: one pass, connected groups (sparse). True: repeat until no pair merges (dense).
    centroid : "plain" | "power"
    circular_azimuth : bool
    p_min : float
        Draw mode: pairs with ``P_u < p_min`` are not searched for (and never merge).
    pair_id : (n,) int array, optional
        Draw mode: the ids that key a pair's draw (default ``truth_id``). They should be unique
        within a dwell; give them when several reports share a truth id (false alarms, −1).
    """
    if mode not in MODES:
        raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
    if centroid not in CENTROIDS:
        raise ValueError(f"centroid must be one of {CENTROIDS}, got {centroid!r}")
    if mode == "threshold" and not (0.0 < threshold <= 1.0):
        raise ValueError(f"threshold must be in (0, 1], got {threshold!r}")
    if mode == "draw":
        if seed is None:
            raise ValueError("draw mode needs the run's seed")
        if not (0.0 < p_min < 1.0):
            raise ValueError(f"p_min must be in (0, 1), got {p_min!r}")
    if (range_rate_mps is None) != (range_rate_cell_mps is None):
        raise ValueError("give both range_rate_mps and range_rate_cell_mps, or neither")

    dwell_id = np.asarray(dwell_id, dtype=np.int64).ravel()
    n = len(dwell_id)
    range_m = np.asarray(range_m, dtype=float).ravel()
    azimuth_rad = np.asarray(azimuth_rad, dtype=float).ravel()
    snr = np.asarray(snr, dtype=float).ravel()
    truth_id = np.asarray(truth_id, dtype=np.int64).ravel()
    use_rr = range_rate_mps is not None
    columns = [range_m, azimuth_rad, snr, truth_id]
    if use_rr:
        range_rate_mps = np.asarray(range_rate_mps, dtype=float).ravel()
        columns.append(range_rate_mps)
    if any(len(c) != n for c in columns):
        raise ValueError("all report arrays must have the same length")

    # Per-dwell reference (first report of the dwell) for unwrapping and the cell-size check.
    first, dw_rank = _dwell_groups(dwell_id)
    ref = first[dw_rank]
    cells = [_per_report(range_cell_m, n, "range_cell_m"), _per_report(azimuth_cell_rad, n, "azimuth_cell_rad")]
    if use_rr:
        cells.append(_per_report(range_rate_cell_mps, n, "range_rate_cell_mps"))
    for c, name in zip(cells, ("range_cell_m", "azimuth_cell_rad", "range_rate_cell_mps")):
        if np.any(c != c[ref]):
            raise ValueError(f"{name} must be constant within a dwell")
    az = azimuth_rad
    if circular_azimuth and n:
        a0 = azimuth_rad[ref]
        az = a0 + (fastnp.mod(azimuth_rad - a0 + np.pi, TWO_PI) - np.pi)
    values = [range_m, az] + ([range_rate_mps] if use_rr else [])
    scaled0 = np.column_stack([v / c for v, c in zip(values, cells)]) if n else np.zeros((0, len(values)))
    weight = snr if centroid == "power" else np.ones(n)
    if np.any(weight <= 0) or np.any(~np.isfinite(weight)):
        raise ValueError("snr must be finite and > 0 for power-weighted centroids")

    radius = cutoff_cells(mode, threshold, p_min)
    if pair_id is not None:
        pair_id = np.asarray(pair_id, dtype=np.int64).ravel()
        if len(pair_id) != n:
            raise ValueError("pair_id must have one entry per report")
    ident0 = report_identity(truth_id if pair_id is None else pair_id) if mode == "draw" else None

    label = np.arange(n, dtype=np.int64)
    passes = 0
    if n > 1:
        # pass 1: every pair of original reports within the cut-off, decided once
        i, j, p = _near_pairs(scaled0, dw_rank, radius)
        accept = _decide(p, mode, threshold, seed, dwell_id, ident0, i, j)
        a = np.flatnonzero(accept)        # index gathers (a boolean mask's cost ~4x more)
        edges = (np.take(i, a), np.take(j, a), np.take(p, a))
        cols = [np.ascontiguousarray(scaled0[:, k]) for k in range(scaled0.shape[1])]
        wcols = [weight * c for c in cols]          # weight * scaled0[:, k], once
        while True:
            m = int(label.max()) + 1
            if iterate and passes > 0:
                # dense: re-test the current reports (merged ones at their centroids)
                pts = _centroids(label, m, weight, scaled0)
                g_rank = np.zeros(m, dtype=np.int64)
                g_rank[label] = dw_rank
                gi, gj, gp = _near_pairs(pts, g_rank, radius)
                g_dwell = np.zeros(m, dtype=np.int64)
                g_dwell[label] = dwell_id
                ident = _group_reduce_xor(ident0, label, m) if mode == "draw" else None
                ok = _decide(gp, mode, threshold, seed, g_dwell, ident, gi, gj)
                ok = np.flatnonzero(ok)
                gi, gj, gp = np.take(gi, ok), np.take(gj, ok), np.take(gp, ok)
                by_pair = False
            else:
                # sparse (and the first dense pass): the accepted pairs of original reports
                # link their current groups, with the pair's probability as priority
                gi, gj, gp = _group_edges(label[edges[0]], label[edges[1]], edges[2])
                by_pair = True          # ordered by (lo, hi), lo < hi
            if len(gi) == 0:
                break
            passes += 1
            pairs = _merge_round(label, m, weight, cols, wcols, gi, gj, gp, by_pair)
            if pairs is None:
                break
            label = _relabel(label, m, *pairs)

    return _build(label, dwell_id, range_m, az, azimuth_rad, range_rate_mps if use_rr else None, snr,
                  truth_id, weight, circular_azimuth, passes)


def _dwell_groups(dwell_id) -> tuple:
    """``(first, rank)``: each distinct dwell's first report and each report's dwell rank, as
    ``np.unique(dwell_id, return_index=True, return_inverse=True)`` gives them; for reports
    already in dwell order (the sensor's) from where the dwell changes, without a sort."""
    dwell_id = np.asarray(dwell_id).ravel()
    if len(dwell_id) < 2 or not bool(np.all(dwell_id[1:] >= dwell_id[:-1])):
        _, first, rank = np.unique(dwell_id, return_index=True, return_inverse=True)
        return first, rank.ravel()
    new = np.empty(len(dwell_id), bool)
    new[0] = True
    np.not_equal(dwell_id[1:], dwell_id[:-1], out=new[1:])
    rank = np.cumsum(new) - 1
    return np.flatnonzero(new), rank


def _near_pairs(pts: np.ndarray, rank: np.ndarray, radius: float):
    """Pairs (i < j) of points of the same dwell within ``radius`` cells, and their P_u.

    A sweep along the first coordinate (range): the points sorted by (dwell, range), each
    compared with its k-th successor for k = 1, 2, ... while some successor is within the
    cut-off in range (each pass only at the positions still within it at the previous one);
    a pair within the cut-off in every coordinate is kept.  The same pairs as the kd-tree's
    ``query_pairs`` over the scaled coordinates plus a separating dwell coordinate
    (:func:`_near_pairs_tree`; tested), at a third of its cost on the dense peer scene; when
    the range windows are very full (many points at one range) the tree takes over."""
    n = len(pts)
    if n < 2:
        z = np.zeros(0, dtype=np.int64)
        return z, z, np.zeros(0)
    cut = radius * (1.0 + 1e-9) + 1e-12          # the tree's query radius
    cols = [np.ascontiguousarray(pts[:, k]) for k in range(pts.shape[1])]
    lows = [float(c.min()) for c in cols]
    span = max(float(c.max()) - low for c, low in zip(cols, lows))     # np.ptp(pts, 0).max()
    sep = span + 2.0 * cut + 1.0                  # dwells apart by more than any window
    # key = rank·sep + (x − x_min) is non-decreasing in x within a dwell (rounding is
    # monotone) and within a few ulps of it: the window is widened by that much.  Points of
    # different dwells are more than sep − span > window apart in it, so never compared.
    key = rank * sep + (cols[0] - lows[0])
    window = cut + 8.0 * (np.spacing(abs(float(key.max()))) + np.spacing(span + 1.0))
    order = np.argsort(key)
    ks = key[order]
    sorted_cols = [np.take(c, order) for c in cols]
    cut2 = cut * cut
    pos = np.arange(n - 1)
    found_at, found_k, found_s2 = [], [], []
    k = 1
    while pos.size:
        if k > _SWEEP_MAX_PASSES:
            return _near_pairs_tree(pts, rank, radius)
        if pos[-1] + k >= n:
            pos = pos[:np.searchsorted(pos, n - k)]        # pos ascending: those with pos + k < n
        nxt = pos + k
        # index arrays, not boolean masks (numpy's mask gathers cost ~5x more)
        close = np.flatnonzero(np.take(ks, nxt) - np.take(ks, pos) <= window)
        pos, nxt = np.take(pos, close), np.take(nxt, close)
        if pos.size:
            d = np.take(sorted_cols[0], nxt) - np.take(sorted_cols[0], pos)
            s2 = d * d
            for c in sorted_cols[1:]:
                d = np.take(c, nxt) - np.take(c, pos)
                s2 += d * d        # (x_i − x_j)² = (x_j − x_i)² exactly: either order
            near = np.flatnonzero(s2 <= cut2)
            found_at.append(np.take(pos, near))
            found_k.append(np.full(near.size, k, np.int64))
            found_s2.append(np.take(s2, near))
        k += 1
    at = np.concatenate(found_at) if found_at else np.zeros(0, np.int64)
    a = np.take(order, at)
    b = np.take(order, at + np.concatenate(found_k)) if found_k else a
    s2 = np.concatenate(found_s2) if found_s2 else np.zeros(0)
    i, j = np.minimum(a, b).astype(np.int64), np.maximum(a, b).astype(np.int64)
    return i, j, np.exp2(-s2)


#: Sweep passes after which :func:`_near_pairs` leaves a crowded chunk to the kd-tree.
_SWEEP_MAX_PASSES = 64


def _near_pairs_tree(pts: np.ndarray, rank: np.ndarray, radius: float):
    """:func:`_near_pairs` by a kd-tree over the scaled coordinates plus a dwell coordinate
    that separates dwells (``query_pairs``)."""
    if len(pts) < 2:
        z = np.zeros(0, dtype=np.int64)
        return z, z, np.zeros(0)
    span = np.ptp(pts, axis=0).max()
    sep = span + 2.0 * radius + 1.0  # larger than any within-dwell distance + the radius
    from scipy.spatial import cKDTree     # imported here: scipy.spatial is slow to import
    tree = cKDTree(np.column_stack([pts, rank * sep]))
    pairs = tree.query_pairs(radius * (1.0 + 1e-9) + 1e-12, output_type="ndarray")
    if len(pairs) == 0:
        z = np.zeros(0, dtype=np.int64)
        return z, z, np.zeros(0)
    i, j = pairs[:, 0].astype(np.int64), pairs[:, 1].astype(np.int64)
    same = rank[i] == rank[j]            # always true by construction; kept as a guard
    i, j = i[same], j[same]
    return i, j, np.exp2(-np.sum((pts[i] - pts[j]) ** 2, axis=1))


def _decide(p, mode, threshold, seed, dwell, ident, i, j) -> np.ndarray:
    """Eq. 18's decision per pair (i, j) of points with dwells ``dwell`` and identities
    ``ident``: threshold, or a counter-based draw below P_u.

    The draw is :func:`draw_uniform` of the pair (dwell, lower identity, higher identity), bit
    for bit, with each point's counters mixed once and gathered per pair
    (:class:`gmtiflow.rng.Counters`) instead of mixed again for every pair it is in."""
    if mode == "threshold":
        return p >= threshold
    ids = np.asarray(ident, dtype=np.uint64).view(np.int64)
    a, b = np.take(ids, i), np.take(ids, j)
    mixed_id = rng.mix_counter(ids)
    i_low = a <= b
    low = np.where(i_low, i, j)            # the point holding the lower identity
    high = np.where(i_low, j, i)
    mixed = [np.take(mixed_id, low), np.take(mixed_id, high)]
    u = rng.Counters(mixed=mixed, lead=(rng.mix_counter(dwell), i)).uniform(
        rng.counter_key(seed, "sensor", "merge"))
    return u < p


def _centroids(label, m, weight, scaled0):
    wsum = np.bincount(label, weights=weight, minlength=m)
    return np.column_stack([np.bincount(label, weights=weight * scaled0[:, k], minlength=m) / wsum
                            for k in range(scaled0.shape[1])])


def _group_edges(a, b, p):
    """Distinct group pairs (lo < hi) linked by accepted report pairs, with the highest P_u,
    ordered by (lo, hi)."""
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    keep = lo != hi
    keep = np.flatnonzero(keep)
    lo, hi, p = np.take(lo, keep), np.take(hi, keep), np.take(p, keep)
    if len(lo) == 0:
        return lo, hi, p
    span = int(hi.max()) + 1
    key = lo * span + hi                    # (lo, hi) as one integer, in the same order
    order = np.argsort(key)
    key, p = key[order], p[order]
    first = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    best = np.maximum.reduceat(p, first)
    key = key[first]
    return key // span, key % span, best


def _merge_round(label, m, weight, cols, wcols, gi, gj, gp, by_pair=False):
    """One round of merges without chaining: drop candidate group pairs whose merged report
    would have an ancestor more than one resolution cell from its centroid, then merge every
    pair that is each group's most probable candidate (a matching).  The globally most probable
    valid pair is always chosen, so each round merges something while valid pairs remain.
    Returns the (a, b) groups to merge, or None.

    ``cols`` are the scaled coordinates (one array per axis), ``wcols`` them times the
    weights; ``by_pair``: the candidates come ordered by (lo, hi).  Only the members of the
    candidates' groups are read (their sums in input order, as over every report)."""
    lo, hi = np.minimum(gi, gj), np.maximum(gi, gj)
    # --- the no-chaining test, exact over every ancestor of both groups -------------------
    involved = np.zeros(m, bool)
    involved[lo] = True
    involved[hi] = True
    rows = np.flatnonzero(involved[label])         # their members, in input order
    lab = label[rows]
    order = rows[np.argsort(lab, kind="stable")]   # grouped, input order within a group
    count = np.bincount(lab, minlength=m)
    start = np.cumsum(count) - count
    wsum = np.bincount(lab, weights=weight[rows], minlength=m)
    den = wsum[lo] + wsum[hi]
    centre = [(wx[lo] + wx[hi]) / den for wx in
              (np.bincount(lab, weights=w[rows], minlength=m) for w in wcols)]
    k_q = count[lo] + count[hi]
    q = np.repeat(np.arange(len(lo)), k_q)
    within = np.arange(int(k_q.sum())) - np.repeat(np.cumsum(k_q) - k_q, k_q)
    in_lo = within < count[lo][q]
    last = max(len(order) - 1, 0)
    member = np.where(in_lo, order[np.minimum(start[lo][q] + within, last)],
                      order[np.minimum(start[hi][q] + within - count[lo][q], last)])
    d = cols[0][member] - centre[0][q]
    d2 = d * d
    for c, ce in zip(cols[1:], centre[1:]):
        d = c[member] - ce[q]
        d2 += d * d
    worst = np.zeros(len(lo))
    np.maximum.at(worst, q, d2)
    ok = worst <= 1.0 + 1e-9
    ok = np.flatnonzero(ok)
    lo, hi, gp = np.take(lo, ok), np.take(hi, ok), np.take(gp, ok)
    if len(lo) == 0:
        return None
    # --- matching: each group's best candidate under one global order of the pairs --------
    # (P_u descending, then lo, then hi; from (lo, hi) order a stable sort on −P_u gives it)
    rank = np.empty(len(lo), dtype=np.int64)
    by = np.argsort(-gp, kind="stable") if by_pair else np.lexsort((hi, lo, -gp))
    rank[by] = np.arange(len(lo))
    best = np.full(m, np.iinfo(np.int64).max)
    np.minimum.at(best, lo, rank)
    np.minimum.at(best, hi, rank)
    chosen = (best[lo] == rank) & (best[hi] == rank)
    return lo[chosen], hi[chosen]


def _relabel(label, m, a, b):
    """Groups ``b`` join groups ``a`` (disjoint pairs); labels renumbered 0..m'-1 in the order
    of the groups kept (``np.unique``'s ranks of the targets, without its sort: every target
    is a kept group, as no ``a`` is also a ``b``)."""
    target = np.arange(m)
    target[b] = a
    kept = np.ones(m, bool)
    kept[b] = False
    new = np.cumsum(kept) - 1
    return new[target][label].astype(np.int64)


def _build(label, dwell_id, range_m, az, az_in, range_rate_mps, snr, truth_id, weight, circular, passes):
    n = len(label)
    label = _canonical(label) if n else label
    m = int(label.max()) + 1 if n else 0
    count = np.bincount(label, minlength=m).astype(np.int64)
    # Strongest ancestor: the first in the order by group, then descending SNR, then input
    # order; a single report is its own (only the merged groups' members are sorted)
    single = count == 1
    strongest = np.zeros(m, np.int64)
    alone = np.flatnonzero(single[label])
    strongest[label[alone]] = alone
    anc = np.flatnonzero(~single[label])            # the members of merged groups
    lab = label[anc]
    by_group = anc[np.argsort(lab, kind="stable")]  # by group, then input order
    if anc.size:
        s_grp = snr[by_group]
        if np.isnan(s_grp).any():
            order = anc[np.lexsort((anc, -snr[anc], lab))]
            lead = np.flatnonzero(np.r_[True, label[order][1:] != label[order][:-1]])
            strongest[label[order[lead]]] = order[lead]
        else:   # each group's first member of its highest SNR (that order's first)
            g = label[by_group]
            starts = np.flatnonzero(np.r_[True, g[1:] != g[:-1]])
            top = np.repeat(np.maximum.reduceat(s_grp, starts), np.diff(np.r_[starts, len(g)]))
            at = np.flatnonzero(s_grp == top)
            first = at[np.r_[True, g[at[1:]] != g[at[:-1]]]]
            strongest[g[first]] = by_group[first]
    # Means of the merged groups (bincount over their members alone: the same sums, in the
    # same order); singletons keep their values bit for bit (no (w·x)/w round trip).
    wsum = np.bincount(lab, weights=weight[anc], minlength=m)

    def mean(v):
        return np.bincount(lab, weights=weight[anc] * v[anc], minlength=m) / wsum

    with np.errstate(invalid="ignore", divide="ignore"):   # 0/0 at the singletons: replaced
        r_out = mean(range_m)
        a_out = mean(az)
        rr_out = mean(range_rate_mps) if range_rate_mps is not None else None
        if circular:            # the merged groups' (the others are replaced below)
            merged_rows = np.flatnonzero(~single)
            a_out[merged_rows] = fastnp.mod(a_out[merged_rows], TWO_PI)
    r_out[single] = range_m[strongest[single]]
    a_out[single] = az_in[strongest[single]]
    if rr_out is not None:
        rr_out[single] = range_rate_mps[strongest[single]]
    anc = by_group
    return MergeResult(
        group=label, dwell_id=dwell_id[strongest], range_m=r_out, azimuth_rad=a_out,
        range_rate_mps=rr_out, snr=np.bincount(label, weights=snr, minlength=m),
        truth_id=truth_id[strongest], strongest=strongest, n_ancestors=count,
        ancestor_row=label[anc], ancestor_truth_id=truth_id[anc], ancestor_index=anc.astype(np.int64),
        passes=passes)
