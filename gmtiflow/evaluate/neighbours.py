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
    empty = np.zeros(0, np.int64)
    sx = np.zeros(len(X), np.int64) if step_x is None else np.asarray(step_x, np.int64)
    sy = np.zeros(len(Y), np.int64) if step_y is None else np.asarray(step_y, np.int64)
    okx, oky = _finite_rows(X), _finite_rows(Y)
    if not len(okx) or not len(oky):
        return empty, empty, np.zeros(0)
    cx = np.floor(_rows(X, okx) / c).astype(np.int64)
    cy = np.floor(_rows(Y, oky) / c).astype(np.int64)
    lo = np.minimum(_column_min(cx), _column_min(cy)) - 1
    span = np.maximum(_column_max(cx), _column_max(cy)) - lo + 2
    s0 = min(int(sx[okx].min()), int(sy[oky].min()))
    n_steps = max(int(sx[okx].max()), int(sy[oky].max())) - s0 + 1
    if n_steps * int(span[0]) * int(span[1]) >= 2 ** 62:     # cell keys would overflow
        return close_pairs_tree(X, Y, c, sx, sy)

    def key(step, cells):
        return ((step - s0) * span[0] + (cells[:, 0] - lo[0])) * span[1] + (cells[:, 1] - lo[1])
    # Neither sort needs to keep ties in order: each (row, column) pair is found once (the
    # nine cells are distinct) and _by_row orders the pairs by their unique (row, column) key,
    # so the unstable sort (~4x faster on 600k keys) gives the same pairs in the same order.
    ky = key(sy[oky], cy)
    order = np.argsort(ky)
    ky, ycol = ky[order], oky[order]
    kx = key(sx[okx], cx)
    ox = np.argsort(kx)                      # sorted needles: a faster binary search
    kx, xrow = kx[ox], okx[ox]
    # The points in cell-key order: the candidates' coordinates are then gathered from nearby
    # addresses.  (np.take: ~10x faster than X[rows] on (n, 2) arrays.)
    Xs, Ys = np.take(X, xrow, axis=0), np.take(Y, ycol, axis=0)
    rows, cols, dists = [], [], []
    for dx in (-1, 0, 1):        # the cells (ix + dx, iy - 1 .. iy + 1): one key range
        first = np.searchsorted(ky, kx + (dx * span[1] - 1), side="left")
        count = np.searchsorted(ky, kx + (dx * span[1] + 1), side="right") - first
        total = int(count.sum())
        if not total:
            continue
        p = np.repeat(np.arange(len(kx)), count)                            # in Xs
        q = np.arange(total) + np.repeat(first - (np.cumsum(count) - count), count)  # in Ys
        D = _distance(np.take(Xs, p, axis=0) - np.take(Ys, q, axis=0))
        inside = np.flatnonzero(D < c)
        rows.append(xrow[p[inside]])
        cols.append(ycol[q[inside]])
        dists.append(D[inside])
    if not rows:
        return empty, empty, np.zeros(0)
    return _by_row(np.concatenate(rows), np.concatenate(cols), np.concatenate(dists), len(Y))


#: :func:`step_pairs` searches whole steps in chunks of about this many rows (truth and track
#: rows): a chunk's arrays stay in the CPU caches.  Measured on the scaling benchmark's 60-step
#: tables (best of 5 CPU): 10k truths (1.2M rows) 134 -> 106 ms at 32k rows a chunk (16k: 106,
#: 64k: 113, 128k: 123 ms); 1k truths 11.0 -> 10.5 ms.
CHUNK_ROWS = 32768


def step_chunks(step_x: np.ndarray, step_y: np.ndarray, rows: int = None):
    """``(x0, x1, y0, y1)`` of each chunk of whole steps of two tables sorted by step: rows
    ``x0:x1`` of the first and ``y0:y1`` of the second, about ``rows`` (default
    :data:`CHUNK_ROWS`) rows in all (at least one step)."""
    rows = CHUNK_ROWS if rows is None else int(rows)
    sx, sy = np.asarray(step_x, np.int64), np.asarray(step_y, np.int64)
    if not len(sx) or not len(sy):
        return [(0, len(sx), 0, len(sy))]
    s0 = min(int(sx[0]), int(sy[0]))
    edges = s0 + np.arange(max(int(sx[-1]), int(sy[-1])) - s0 + 2)
    xb, yb = np.searchsorted(sx, edges), np.searchsorted(sy, edges)
    total = xb + yb
    cut = np.unique(np.r_[0, np.searchsorted(total, np.arange(rows, total[-1], rows)),
                          len(edges) - 1]).tolist()
    xb, yb = xb.tolist(), yb.tolist()
    return [(xb[a], xb[b], yb[a], yb[b]) for a, b in zip(cut[:-1], cut[1:])]


def step_pairs(truth_at, tracks_at, c: float):
    """:func:`close_pairs` of the truth rows and track rows of one grid step (the tables of
    :mod:`gmtiflow.evaluate.align`, sorted by step: step, x_m, y_m): ``(truth row, track row,
    distance)`` of every pair closer than ``c``, sorted by truth row then track row.  Searched
    in chunks of whole steps (:data:`CHUNK_ROWS`): the same pairs in the same order."""
    X = np.stack([truth_at["x_m"], truth_at["y_m"]], axis=1).astype(float, copy=False)
    Y = np.stack([tracks_at["x_m"], tracks_at["y_m"]], axis=1).astype(float, copy=False)
    sx = np.asarray(truth_at["step"], np.int64)
    sy = np.asarray(tracks_at["step"], np.int64)
    if (sx[1:] < sx[:-1]).any() or (sy[1:] < sy[:-1]).any():
        return close_pairs(X, Y, c, sx, sy)
    parts = [close_pairs(X[x0:x1], Y[y0:y1], c, sx[x0:x1], sy[y0:y1]) + (x0, y0)
             for x0, x1, y0, y1 in step_chunks(sx, sy)]
    return (np.concatenate([r + x0 for r, _, _, x0, _ in parts]),
            np.concatenate([k + y0 for _, k, _, _, y0 in parts]),
            np.concatenate([D for _, _, D, _, _ in parts]))


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
    r, k = ia[found["i"].astype(np.int64)], ib[found["j"].astype(np.int64)]
    D = _distance(X[r] - Y[k])
    inside = D < c
    return _by_row(r[inside], k[inside], D[inside], len(Y))


def _distance(diff: np.ndarray) -> np.ndarray:
    """Row lengths ``sqrt(Σ diff²)`` of an (n, d) array of differences (the one formula both
    candidate searches use, so their distances agree bit for bit)."""
    return np.sqrt(np.einsum("ij,ij->i", diff, diff))


def _by_row(r, k, D, n_cols: int):
    """The pairs ``(r, k)`` and their distances sorted by row then column (every pair once)."""
    o = np.argsort(r * max(n_cols, 1) + k)
    return r[o], k[o], D[o]


def _finite_rows(X: np.ndarray) -> np.ndarray:
    """Indices of the rows of X whose coordinates are all finite (column by column: a
    reduction along rows of 2 is ~15x slower in numpy)."""
    fin = np.isfinite(X[:, 0])
    for j in range(1, X.shape[1]):
        fin &= np.isfinite(X[:, j])
    return np.flatnonzero(fin)


def _rows(X: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """``X[rows]``, without the copy when ``rows`` is every row in order."""
    return X if len(rows) == len(X) else X[rows]


def _column_min(a: np.ndarray) -> np.ndarray:
    """Per-column minimum of an (n, d) array, column by column (as :func:`_finite_rows`)."""
    return np.array([a[:, j].min() for j in range(a.shape[1])])


def _column_max(a: np.ndarray) -> np.ndarray:
    """Per-column maximum of an (n, d) array, column by column."""
    return np.array([a[:, j].max() for j in range(a.shape[1])])
