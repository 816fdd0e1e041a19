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
