"""Gated global nearest-neighbour assignment (one ``linear_sum_assignment`` per call).

Rows (tracks) may stay unassigned: the cost matrix is augmented with one private "miss" column per
row whose cost is the gate, so a pair is only chosen when its cost is below the gate and when
assigning it lowers the total cost (Blackman & Popoli 1999, §6.5; the usual GNN formulation).
Pairs outside the gate get a cost larger than any gated solution and are never returned.
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import linear_sum_assignment


def gated_assignment(cost: np.ndarray, gate: float):
    """Optimal one-to-one assignment of rows to columns with cost < ``gate``.

    Returns ``(rows, cols)``, integer arrays of the assigned pairs, sorted by row.  Minimises the
    sum of assigned costs plus ``gate`` for every unassigned row.  Deterministic.
    """
    cost = np.asarray(cost, float)
    nr, nc = cost.shape
    empty = np.zeros(0, dtype=np.int64)
    if nr == 0 or nc == 0:
        return empty, empty
    inside = np.isfinite(cost) & (cost < gate)
    if not inside.any():
        return empty, empty
    # Only rows and columns with at least one gated pair take part (keeps the problem small).
    rows_in = np.flatnonzero(inside.any(axis=1))
    cols_in = np.flatnonzero(inside.any(axis=0))
    sub = cost[np.ix_(rows_in, cols_in)]
    sub_in = inside[np.ix_(rows_in, cols_in)]
    n = len(rows_in)
    big = float(gate) * (n + 1) + 1.0
    aug = np.full((n, len(cols_in) + n), big)
    aug[:, :len(cols_in)] = np.where(sub_in, sub, big)
    aug[np.arange(n), len(cols_in) + np.arange(n)] = gate
    r, c = linear_sum_assignment(aug)
    real = c < len(cols_in)
    r, c = r[real], c[real]
    keep = sub_in[r, c]
    return rows_in[r[keep]].astype(np.int64), cols_in[c[keep]].astype(np.int64)


def sparse_gated_assignment(rows: np.ndarray, cols: np.ndarray, cost: np.ndarray, gate: float):
    """:func:`gated_assignment` of the pairs ``(rows[i], cols[i])`` with ``cost[i] < gate`` (every
    other pair outside the gate), solved per connected component of the pairs' graph: one pair
    alone is assigned at once, larger components go through :func:`gated_assignment` on their
    own rows and columns.  The optimum is the dense one (components share no gated pair, and
    the dense problem never takes an out-of-gate pair); cost linear in the pairs for sparse
    gates.  Returns ``(rows, cols)`` sorted by row."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    rows, cols = np.asarray(rows, np.int64), np.asarray(cols, np.int64)
    cost = np.asarray(cost, float)
    empty = np.zeros(0, np.int64)
    if not len(rows):
        return empty, empty
    if len(np.unique(rows)) == len(rows) and len(np.unique(cols)) == len(cols):
        o = np.argsort(rows, kind="stable")      # every pair its own component
        return rows[o], cols[o]
    r_ids, r_idx = np.unique(rows, return_inverse=True)
    c_ids, c_idx = np.unique(cols, return_inverse=True)
    nr, nc = len(r_ids), len(c_ids)
    graph = coo_matrix((np.ones(len(rows)), (r_idx, nr + c_idx)), shape=(nr + nc, nr + nc))
    _, label = connected_components(graph, directed=False)
    pair_label = label[r_idx]
    n_pairs = np.bincount(pair_label, minlength=label.max() + 1)
    single = n_pairs[pair_label] == 1
    out_r, out_c = [r_ids[r_idx[single]]], [c_ids[c_idx[single]]]
    multi = np.flatnonzero(~single)
    if len(multi):
        order = multi[np.argsort(pair_label[multi], kind="stable")]
        bounds = np.flatnonzero(np.diff(pair_label[order])) + 1
        for grp in np.split(order, bounds):
            gr, ir = np.unique(r_idx[grp], return_inverse=True)
            gc, ic = np.unique(c_idx[grp], return_inverse=True)
            sub = np.full((len(gr), len(gc)), np.inf)
            sub[ir, ic] = cost[grp]
            a, b = gated_assignment(sub, gate)
            out_r.append(r_ids[gr[a]])
            out_c.append(c_ids[gc[b]])
    rr, cc = np.concatenate(out_r), np.concatenate(out_c)
    o = np.argsort(rr, kind="stable")
    return rr[o], cc[o]
