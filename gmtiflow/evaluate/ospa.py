"""OSPA and GOSPA (α = 2) between truth and track positions, per time step.

For truth positions ``X`` (m of them) and track positions ``Y`` (n), cut-off ``c`` and order
``p``, with ``d_c(x, y) = min(‖x − y‖, c)``:

OSPA (Schuhmacher, Vo & Vo 2008), with ``m ≤ n`` (swap otherwise):

.. math::  \\bar d_p^{(c)}(X, Y) = \\Bigl(\\frac{1}{n}\\bigl(\\min_π \\sum_{i=1}^{m}
           d_c(x_i, y_{π(i)})^p + c^p (n - m)\\bigr)\\Bigr)^{1/p},

0 when both sets are empty.  GOSPA with α = 2 (Rahmathullah, García-Fernández & Svensson 2017):

.. math::  d_p^{(c,2)}(X, Y) = \\Bigl(\\min_γ \\sum_{(i,j)∈γ} ‖x_i − y_j‖^p
           + \\frac{c^p}{2}(|X| − |γ|) + \\frac{c^p}{2}(|Y| − |γ|)\\Bigr)^{1/p},

γ ranging over partial assignments of pairs closer than ``c``.  The three sums are reported as
they are (p-th powers, as Stone Soup does): *localisation* ``Σ‖x−y‖^p``, *missed*
``c^p/2 · #missed truths``, *false* ``c^p/2 · #false tracks``, and GOSPA = (loc + missed +
false)^{1/p}.

One optimal assignment serves both: ``linear_sum_assignment`` on ``min(‖x−y‖, c)^p`` (a
rectangular matrix built by numpy broadcasting).  A pair at or beyond ``c`` costs ``c^p``, exactly
what leaving both ends unassigned costs in GOSPA, so such pairs are counted as one missed and one
false; and the same pairing minimises OSPA's sum.
"""
from __future__ import annotations

from typing import Mapping

import numpy as np
from scipy.optimize import linear_sum_assignment

from gmtiflow.evaluate.neighbours import close_pairs
from gmtiflow.tables import Table


#: Up to this many (truth, track) pairs a step is solved with one dense assignment (as the
#: formulas above say); above, pairs closer than ``c`` come from a cell grid and are assigned per
#: connected component (linear in the objects at a fixed density).  The pairs and
#: ``localisation``, ``missed``, ``false``, GOSPA are identical either way, OSPA too when there
#: are at least as many tracks as truths; with more truths than tracks OSPA's sum adds the same
#: terms in another order (a difference in the last bits).
DENSE_PAIRS = 4096


def ospa_gospa(X: np.ndarray, Y: np.ndarray, c: float, p: float) -> dict:
    """OSPA and GOSPA between point sets ``X`` (m, d) and ``Y`` (n, d).

    Returns a dict: ``ospa``, ``gospa``, ``localisation``, ``missed``, ``false`` (p-th power
    sums), ``n_assigned`` and the pairs ``(rows, cols)`` closer than ``c``.
    """
    X = np.asarray(X, float)
    Y = np.asarray(Y, float)
    X = X.reshape(0, 2) if X.size == 0 else X
    Y = Y.reshape(0, 2) if Y.size == 0 else Y
    m, n = len(X), len(Y)
    cp = float(c) ** p
    rows = cols = np.zeros(0, np.int64)
    loc = 0.0
    capped_sum = 0.0
    if m * n > DENSE_PAIRS:
        rows, cols, loc, capped_sum = _sparse_sums(X, Y, float(c), p)
    elif m and n:
        diff = X[:, None, :] - Y[None, :, :]
        D = np.sqrt(np.einsum("ijk,ijk->ij", diff, diff))
        C = np.minimum(D, c) ** p
        r, k = linear_sum_assignment(C)
        capped_sum = float(C[r, k].sum())
        inside = D[r, k] < c
        rows, cols = r[inside], k[inside]
        loc = float(C[rows, cols].sum())
    return _result(m, n, rows, cols, loc, capped_sum, cp, p)


def _sparse_sums(X: np.ndarray, Y: np.ndarray, c: float, p: float):
    """The assigned pairs closer than ``c``, their sum and OSPA's capped sum, without the dense
    (m, n) matrix: pairs closer than ``c`` from a cell grid, one optimal assignment per connected
    component (minimising Σ(d^p − c^p) over the pairs, which is the dense problem: a pair at or
    beyond ``c`` costs c^p, what leaving both unassigned costs); every other assigned row adds
    c^p."""
    from gmtiflow.evaluate.assignment import sparse_gated_assignment
    m, n = len(X), len(Y)
    r, k, D = close_pairs(X, Y, c)
    C = D ** p
    cp = _cp(c, p)
    rows, cols = sparse_gated_assignment(r, k, C, cp)
    at = np.searchsorted(r * n + k, rows * n + cols)
    return (rows, cols) + _sums(m, n, rows, C[at], cp)


def _cp(c: float, p: float) -> float:
    """c^p as the dense path's ``np.minimum(D, c) ** p`` gives it."""
    return float((np.full(1, c) ** p)[0])


def _sums(m: int, n: int, rows: np.ndarray, C_assigned: np.ndarray, cp: float):
    """(localisation, OSPA's capped sum) of a step from its assigned rows and their costs."""
    loc = float(C_assigned.sum())
    if m <= n:       # every truth row is assigned: its pair's term, else c^p, in row order
        terms = np.full(m, cp)
        terms[rows] = C_assigned
    else:            # n of the truths are assigned: the pairs' terms and n − k times c^p
        terms = np.concatenate([C_assigned, np.full(n - len(rows), cp)])
    return loc, float(terms.sum())


def _result(m: int, n: int, rows, cols, loc: float, capped_sum: float, cp: float, p: float):
    """:func:`ospa_gospa`'s dict from a step's assignment (``cp``: c^p as Python computes it)."""
    n_ass = len(rows)
    missed = cp / 2.0 * (m - n_ass)
    false = cp / 2.0 * (n - n_ass)
    big = max(m, n)
    ospa = 0.0 if big == 0 else ((capped_sum + cp * abs(n - m)) / big) ** (1.0 / p)
    gospa = (loc + missed + false) ** (1.0 / p)
    return {"ospa": ospa, "gospa": gospa, "localisation": loc, "missed": missed, "false": false,
            "n_assigned": n_ass, "rows": rows, "cols": cols}


def _assign_by_chunks(r, k, C, cp: float, step_x, step_y):
    """:func:`~gmtiflow.evaluate.assignment.sparse_gated_assignment` of the pairs ``(r, k)``
    (sorted by row) of steps sorted by step, chunk by chunk of whole steps
    (:func:`~gmtiflow.evaluate.neighbours.step_chunks`): the same pairs, sorted by row (a
    component never spans two steps, and the chunks' rows follow each other)."""
    from gmtiflow.evaluate.assignment import sparse_gated_assignment
    from gmtiflow.evaluate.neighbours import step_chunks
    out_r, out_c = [np.zeros(0, np.int64)], [np.zeros(0, np.int64)]
    for x0, x1, _, _ in step_chunks(step_x, step_y):
        a, b = np.searchsorted(r, [x0, x1])
        if b > a:
            rows, cols = sparse_gated_assignment(r[a:b], k[a:b], C[a:b], cp)
            out_r.append(rows)
            out_c.append(cols)
    return np.concatenate(out_r), np.concatenate(out_c)


def series(truth_at: Mapping[str, np.ndarray], tracks_at: Mapping[str, np.ndarray],
           grid: np.ndarray, c: float, p: float, pairs=None) -> Table:
    """OSPA/GOSPA at every grid step from the outputs of :mod:`gmtiflow.evaluate.align`.

    Columns: time_s, ospa_m, gospa_m, gospa_localisation, gospa_missed, gospa_false (the
    p-th power sums, unit m^p), n_truth, n_tracks, n_assigned.

    ``truth_at`` and ``tracks_at`` are sorted by ``step``.  Each step is :func:`ospa_gospa` of
    its objects; the steps above :data:`DENSE_PAIRS` pairs are solved together (one pair
    search, and :func:`~gmtiflow.evaluate.assignment.sparse_gated_assignment` by chunks of
    whole steps: their components never span two steps), with the same pairs and sums.
    ``pairs``: :func:`~gmtiflow.evaluate.neighbours.step_pairs` at ``c`` when the caller has
    them already (those of the big steps are the pairs the search would find).
    """
    n = len(grid)
    c, p = float(c), float(p)
    tb = np.searchsorted(truth_at["step"], np.arange(n + 1))
    kb = np.searchsorted(tracks_at["step"], np.arange(n + 1))
    X = np.stack([truth_at["x_m"], truth_at["y_m"]], axis=1).astype(float, copy=False)
    Y = np.stack([tracks_at["x_m"], tracks_at["y_m"]], axis=1).astype(float, copy=False)
    out = {name: np.zeros(n) for name in ("ospa_m", "gospa_m", "gospa_localisation",
                                          "gospa_missed", "gospa_false")}
    n_truth = np.diff(tb).astype(np.int64)
    n_tracks = np.diff(kb).astype(np.int64)
    n_ass = np.zeros(n, np.int64)
    big = n_truth * n_tracks > DENSE_PAIRS
    cp = _cp(c, p)
    if big.any():
        in_x = np.repeat(big, n_truth)
        in_y = np.repeat(big, n_tracks)
        if pairs is None:
            xi, yi = np.flatnonzero(in_x), np.flatnonzero(in_y)
            r, k, D = close_pairs(X[xi], Y[yi], c, np.asarray(truth_at["step"])[xi],
                                   np.asarray(tracks_at["step"])[yi])
            r, k = xi[r], yi[k]             # global rows, still sorted by (row, column)
        else:
            keep = in_x[pairs[0]]           # the pairs of the big steps
            r, k, D = (a[keep] for a in pairs)
        C = D ** p
        rows, cols = _assign_by_chunks(r, k, C, cp, truth_at["step"], tracks_at["step"])
        ny = max(len(Y), 1)
        at = np.searchsorted(r * ny + k, rows * ny + cols)
        C_ass = C[at]
        ab = np.searchsorted(rows, tb)      # the assigned rows of each step
    for s in range(n):
        if big[s]:
            lo, hi = ab[s], ab[s + 1]
            rs = rows[lo:hi] - tb[s]
            res = _result(int(n_truth[s]), int(n_tracks[s]), rs, cols[lo:hi] - kb[s],
                          *_sums(int(n_truth[s]), int(n_tracks[s]), rs, C_ass[lo:hi], cp),
                          c ** p, p)
        else:
            res = ospa_gospa(X[tb[s]:tb[s + 1]], Y[kb[s]:kb[s + 1]], c, p)
        out["ospa_m"][s] = res["ospa"]
        out["gospa_m"][s] = res["gospa"]
        out["gospa_localisation"][s] = res["localisation"]
        out["gospa_missed"][s] = res["missed"]
        out["gospa_false"][s] = res["false"]
        n_ass[s] = res["n_assigned"]
    return {"time_s": np.asarray(grid, float), **out, "n_truth": n_truth, "n_tracks": n_tracks,
            "n_assigned": n_ass}
