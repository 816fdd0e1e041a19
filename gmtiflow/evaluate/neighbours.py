"""Pairs of points closer than a distance, per time step: the candidate search shared by the
metrics (OSPA/GOSPA pairs within the cut-off, IDF1 co-occurrences within the gate).

Distances are ``sqrt(dx² + dy²)`` computed by numpy, the same value bit for bit as the
Euclidean distance ``scipy.spatial.cKDTree`` reports for the same two points (tested)."""
from __future__ import annotations

import numpy as np


def close_pairs(X: np.ndarray, Y: np.ndarray, c: float, step_x=None, step_y=None):
    """The (row of X, row of Y) pairs closer than ``c`` (and of one step, when ``step_x``,
    ``step_y`` are given), sorted by row then column, and their distances.

    Candidates from a grid of ``c``-sized cells (per step): every pair closer than ``c`` lies in
    one of the 3 × 3 cells around the row's own, found by binary search in the columns' sorted
    cell keys (no tree; linear in the rows and candidates); then the exact distance test."""
    m, n = len(X), len(Y)
    empty = np.zeros(0, np.int64)
    sx = np.zeros(m, np.int64) if step_x is None else np.asarray(step_x, np.int64)
    sy = np.zeros(n, np.int64) if step_y is None else np.asarray(step_y, np.int64)
    okx = np.flatnonzero(np.isfinite(X).all(axis=1))
    oky = np.flatnonzero(np.isfinite(Y).all(axis=1))
    if not len(okx) or not len(oky):
        return empty, empty, np.zeros(0)
    cx = np.floor(X[okx] / c).astype(np.int64)
    cy = np.floor(Y[oky] / c).astype(np.int64)
    lo = np.minimum(cx.min(axis=0), cy.min(axis=0)) - 1
    span = np.maximum(cx.max(axis=0), cy.max(axis=0)) - lo + 2
    s0 = min(int(sx[okx].min()), int(sy[oky].min()))
    n_steps = max(int(sx[okx].max()), int(sy[oky].max())) - s0 + 1
    if n_steps * int(span[0]) * int(span[1]) >= 2 ** 62:     # cell keys would overflow
        return close_pairs_tree(X, Y, c, sx, sy)

    def key(step, cells):
        return ((step - s0) * span[0] + (cells[:, 0] - lo[0])) * span[1] + (cells[:, 1] - lo[1])
    # Neither sort needs to keep ties in order: each (row, column) pair is found once (the
    # nine cells are distinct) and _within orders the pairs by their unique (row, column) key,
    # so the unstable sort (~4x faster on 600k keys) gives the same pairs in the same order.
    ky = key(sy[oky], cy)
    order = np.argsort(ky)
    ky = ky[order]
    kx = key(sx[okx], cx)
    ox = np.argsort(kx)                      # sorted needles: a faster binary search
    kx, xrow = kx[ox], okx[ox]
    rows, cols = [], []
    for dx in (-1, 0, 1):        # the cells (ix + dx, iy - 1 .. iy + 1): one key range
        first = np.searchsorted(ky, kx + (dx * span[1] - 1), side="left")
        count = np.searchsorted(ky, kx + (dx * span[1] + 1), side="right") - first
        total = int(count.sum())
        if not total:
            continue
        start = np.repeat(first - (np.cumsum(count) - count), count)
        rows.append(np.repeat(xrow, count))
        cols.append(oky[order[np.arange(total) + start]])
    if not rows:
        return empty, empty, np.zeros(0)
    return _within(X, Y, np.concatenate(rows), np.concatenate(cols), c)


def close_pairs_tree(X, Y, c, sx, sy):
    """:func:`close_pairs` from a k-d tree (the step lifted into a third coordinate 4c apart),
    for coordinates too far apart for integer cell keys."""
    from scipy.spatial import cKDTree
    A = np.column_stack([X, np.asarray(sx, float) * (4.0 * c)])
    B = np.column_stack([Y, np.asarray(sy, float) * (4.0 * c)])
    fin_a, fin_b = np.isfinite(A).all(axis=1), np.isfinite(B).all(axis=1)
    ia, ib = np.flatnonzero(fin_a), np.flatnonzero(fin_b)
    found = cKDTree(A[ia]).sparse_distance_matrix(cKDTree(B[ib]), c * (1.0 + 1e-9),
                                                  output_type="ndarray")
    return _within(X, Y, ia[found["i"].astype(np.int64)], ib[found["j"].astype(np.int64)], c)


def _within(X, Y, r, k, c):
    """The candidate pairs ``(r, k)`` closer than ``c``, sorted by row then column, and their
    distances (the exact test both candidate searches end with)."""
    o = np.argsort(r * max(len(Y), 1) + k)
    r, k = r[o], k[o]
    diff = X[r] - Y[k]
    D = np.sqrt(np.einsum("ij,ij->i", diff, diff))
    inside = D < c
    return r[inside], k[inside], D[inside]
