"""Faster forms of a few numpy operations, bit for bit the same values (sensor hot paths).

numpy 2 on this project's machines runs some operations far slower than plain arithmetic
(~0.3 ns a value): a boolean-mask gather or an ``out=``/``where=`` ufunc ~5 ns, ``np.mod`` of
floats ~9 ns, ``np.interp`` with random abscissae ~40 ns (a binary search per value).  The
functions here give the same values through cheaper paths; each names the identity it relies
on, and tests/sensor/test_fastnp.py compares them with numpy's own on edge cases.
"""
from __future__ import annotations

import numpy as np


def ratio(num, den, fill: float = 0.0):
    """``num / den`` where ``den > 0``, ``fill`` elsewhere (``np.divide(..., where=den > 0)``):
    the plain division when every ``den`` is positive, the usual case."""
    if np.all(den > 0):
        return num / den
    return np.divide(num, den, out=np.full_like(num, fill), where=den > 0)


_MOD_MIN_SIZE = 2048
"""Below this many values :func:`mod` is ``np.mod`` itself: its three masked passes cost ~10 µs
of numpy calls, more than ``np.mod`` spends on ~2,000 values (measured 2026-11-28: 1.95 against
10.4 µs at 256 values, 24 against 18 µs at 4,096; the tracker's per-dwell handful of angles
called it 14,678 times on the 1,000-vehicle scene)."""


def mod(x, period: float):
    """``np.mod(x, period)`` for a positive float ``period``, through numpy's own steps where
    they are a single operation: r = fmod(x, p) is exact, and numpy adds p when r and p differ
    in sign.  So a value in (0, p) is its own remainder, one in (−p, 0) gives x + p (fmod returns
    x itself) and one in (p, 2p) gives x − p (exact, as fmod's result is); only the others
    (0, ±p, beyond, NaN) go through ``np.mod`` (~10 ns a value here).  Arrays of fewer than
    :data:`_MOD_MIN_SIZE` values go to ``np.mod`` whole."""
    x = np.asarray(x, np.float64)
    if x.ndim != 1 or x.size < _MOD_MIN_SIZE:
        return np.mod(x, period)
    out = x.copy()
    below = np.flatnonzero((x > -period) & (x < 0.0))
    out[below] = x[below] + period
    above = np.flatnonzero((x > period) & (x < 2.0 * period))
    out[above] = x[above] - period
    rest = np.flatnonzero(~((x > -period) & (x < 2.0 * period) & (x != 0.0) & (x != period)))
    out[rest] = np.mod(x[rest], period)
    return out


class PeriodicInterp:
    """``np.interp(x, xp, fp, period=period)`` for float64 tables, bit for bit: the table is
    prepared once as numpy prepares it on every call (knots wrapped into [0, period), sorted,
    padded with one knot each side), and each value's knot j (xp[j] ≤ x < xp[j+1]) is read from a
    grid of equal cells, checked, and searched only where the check fails (cells narrower than
    the knots' spacing hold at most one knot).  The interpolation is numpy's C expression
    ``slope[j] * (x − xp[j]) + fp[j]`` (fp[j] where x == xp[j]; the other end where that is
    NaN), evaluated in the same order; numpy's baseline build has no FMA to contract it.
    """

    def __init__(self, xp, fp, period: float):
        self.period = float(period)
        xp = np.asarray(xp, np.float64) % self.period
        fp = np.asarray(fp, np.float64)
        order = np.argsort(xp)
        xp, fp = xp[order], fp[order]
        self.xp = np.concatenate((xp[-1:] - self.period, xp, xp[0:1] + self.period))
        self.fp = np.concatenate((fp[-1:], fp, fp[0:1]))
        self.slopes = (self.fp[1:] - self.fp[:-1]) / (self.xp[1:] - self.xp[:-1])
        self.upper = np.append(self.xp[1:], np.inf)       # xp[j + 1], +inf after the last knot
        n_cells = int(min(max(64, 4 * len(self.xp)), 1 << 16))
        self.inv_cell = n_cells / self.period
        edges = np.arange(n_cells) * (self.period / n_cells)
        self.cell_knot = np.searchsorted(self.xp, edges, side="right") - 1

    def __call__(self, x):
        x0 = np.asarray(x, np.float64)
        if x0.ndim != 1 or not np.isfinite(x0).all():
            return np.interp(x0, self.xp[1:-1], self.fp[1:-1], period=self.period)
        x = mod(x0, self.period)
        xp, n = self.xp, len(self.xp)
        cell = np.minimum((x * self.inv_cell).astype(np.intp), len(self.cell_knot) - 1)
        j = self.cell_knot[cell]
        j = j + (x >= self.upper[j])
        bad = np.flatnonzero(~((xp[j] <= x) & (x < self.upper[j])))
        if bad.size:
            j[bad] = np.searchsorted(xp, x[bad], side="right") - 1
        jj = np.minimum(j, n - 2)
        out = self.slopes[jj] * (x - xp[jj]) + self.fp[jj]
        at_knot = np.flatnonzero(xp[j] == x)           # also the last knot (j = n − 1)
        out[at_knot] = self.fp[j[at_knot]]
        nan = np.flatnonzero(np.isnan(out))
        if nan.size:        # numpy: try the other end, then a flat segment's value
            jn = jj[nan]
            other = self.slopes[jn] * (x[nan] - xp[jn + 1]) + self.fp[jn + 1]
            flat = np.isnan(other) & (self.fp[jn] == self.fp[jn + 1])
            out[nan] = np.where(flat, self.fp[jn], other)
        return out
