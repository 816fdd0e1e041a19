r"""The position noise ("wander") of a vehicle: a smooth process in continuous time.

Each vehicle's offset from its route point, in the road frame (along, across, up), is a
*normalised cubic B-spline* of independent Gaussian knot values c_k ~ N(0, σ²) spaced h apart:

.. math::
    n(t) = \frac{\sum_k B_k(x)\, c_k}{\sqrt{\sum_k B_k(x)^2}}, \qquad x = (t - t_0)/h ,

with B_k the uniform cubic B-spline basis (four non-zero terms).  The numerator alone would
have a variance that dips between knots (as the old linear interpolation of grid draws did:
0.71–0.82 σ between steps); dividing by √(Σ B_k²) makes n(t) exactly N(0, σ²) at *every*
instant, and the result is twice continuously differentiable, so the truth velocity and
acceleration are the exact derivatives (quotient rule, below).  h = ``position_noise_corr_s``
(knots one correlation time apart; correlation 0.84 at lag h/2, 0.49 at h, 0.05 at 2h, 0 from
3h), or the motion step Δt when that is longer (0: the paper's independent noise per step,
now smooth between steps; :func:`knot_spacing_s`).
The wander's own speed is of order σ/h (0.2 m/s along the road for the default 1 m and 5 s).

Derivatives, with N = Σ B c, Q = Σ B², primes d/dx: n' = N' Q^{-1/2} − ½ N Q' Q^{-3/2},
n'' = N'' Q^{-1/2} − N' Q' Q^{-3/2} + ¾ N Q'² Q^{-5/2} − ½ N Q'' Q^{-3/2}; d/dt = (1/h) d/dx.

The road frame turns smoothly through a corner (:func:`corner_heading`): within
:data:`CORNER_BLEND_M` of a vertex (at most half of either adjacent segment) the frame's heading
goes from one segment's to the next with a smoothstep in arc length, so the offset, and with it
the position, has no jump at corners and its rate (the truth velocity) none either.

Knot values come from ``rng.stream(seed, "truth", "vehicle", name, "wander")``, drawn
knot-major for the vehicle's own time span only (from its start time to the scene's end), so
cost and memory follow the trip, and a longer scene extends, never changes, them.
"""
from __future__ import annotations

import math

import numpy as np

CORNER_BLEND_M = 10.0
_CHUNK = 500_000       # rows per block when evaluating (bounded temporaries)


def knot_spacing_s(corr_s, dt_s: float) -> np.ndarray:
    """h per vehicle: its correlation time, but at least the motion step (arrays).

    The motion step is the finest time the truth resolves: a correlation time shorter than it
    (0, the paper's independent noise per step, included) gives knots one step apart.  Spacing
    them ``corr_s`` apart would cost (end - t0)/corr_s knots a vehicle: 1e8 for 1e-6 s, and an
    overflow for a value such as 1e-300 that the config accepts as > 0."""
    return np.maximum(np.asarray(corr_s, float), float(dt_s))


def n_knots(t0_s, end_s, h_s) -> np.ndarray:
    """Knots covering [t0, end] per vehicle (x from 0 to (end − t0)/h, plus the spline's 3
    neighbours; arrays)."""
    span = np.maximum(np.asarray(end_s, float) - t0_s, 0.0) / h_s
    return np.ceil(span - 1e-9).astype(np.int64) + 4


def _basis(x, second: bool = True):
    """Uniform cubic B-spline weights (4, n) at fractions x and their first two derivatives
    (the second None unless ``second``)."""
    y = 1.0 - x
    x2, x3 = x * x, x * x * x
    b, d1 = (np.empty((4,) + np.shape(x)) for _ in range(2))
    # each row's last operation writes into its row (no stacked copies)
    np.divide(y * y * y, 6.0, out=b[0])
    np.divide(3.0 * x3 - 6.0 * x2 + 4.0, 6.0, out=b[1])
    np.divide(-3.0 * x3 + 3.0 * x2 + 3.0 * x + 1.0, 6.0, out=b[2])
    np.divide(x3, 6.0, out=b[3])
    np.multiply(-0.5 * y, y, out=d1[0])
    np.subtract(1.5 * x2, 2.0 * x, out=d1[1])
    np.add(-1.5 * x2 + x, 0.5, out=d1[2])
    np.multiply(0.5, x2, out=d1[3])
    if not second:
        return b, d1, None
    d2 = np.empty((4,) + np.shape(x))
    d2[0] = y
    np.subtract(3.0 * x, 2.0, out=d2[1])
    np.subtract(1.0, 3.0 * x, out=d2[2])
    d2[3] = x
    return b, d1, d2


def evaluate(time_s, vehicle, knots, offset, t0_s, h_s, knots_t=None, second: bool = True):
    """Offsets n, rates ṅ and accelerations n̈, each (n, 3), of vehicles ``vehicle`` (n,) at
    ``time_s`` (n,): ``knots`` (K, 3) all vehicles' knot values, ``offset`` (N + 1,) each
    vehicle's first knot row, ``t0_s`` and ``h_s`` (N,) its time origin and knot spacing;
    ``knots_t``: the knots as a contiguous (3, K) array instead (kept by the caller across
    calls); ``second`` False: n̈ is None, its work skipped (n and ṅ are the same values).

    Computed axis by axis on (3, n) arrays (long inner loops) and returned as (n, 3) views."""
    t = np.asarray(time_s, float)
    whole = 0 < t.size <= _CHUNK       # one block: its arrays are the results
    if not whole:
        n = np.zeros((3, t.size))
        nd = np.zeros((3, t.size))
        ndd = np.zeros((3, t.size)) if second else None
    if knots_t is None:
        knots_t = np.ascontiguousarray(np.asarray(knots, float).T)
    for i0 in range(0, t.size, _CHUNK):
        sl = slice(i0, i0 + _CHUNK)
        v = vehicle[sl]
        h = h_s[v]
        first = offset[v]
        count = offset[v + 1] - first
        u = np.clip((t[sl] - t0_s[v]) / h, 0.0, (count - 4).astype(float) + 1.0 - 1e-12)
        i = np.floor(u).astype(np.int64)
        x = u - i
        b, b1, b2 = _basis(x, second)
        q = np.sum(b * b, axis=0)
        q1 = 2.0 * np.sum(b * b1, axis=0)
        rq = 1.0 / np.sqrt(q)
        base = first + i
        num = np.zeros((3, len(v)))
        num1 = np.zeros((3, len(v)))
        num2 = np.zeros((3, len(v))) if second else None
        for k in range(4):
            c = np.take(knots_t, base + k, axis=1)     # (4x faster than [:, base + k])
            num += b[k] * c
            num1 += b1[k] * c
            if second:
                num2 += b2[k] * c
        r1, r3 = rq, rq ** 3
        n_b = num * r1
        nd_b = (num1 * r1 - 0.5 * num * q1 * r3) / h
        ndd_b = None
        if second:
            q2 = 2.0 * np.sum(b1 * b1 + b * b2, axis=0)
            ndd_b = (num2 * r1 - num1 * q1 * r3 + 0.75 * num * q1 * q1 * rq ** 5
                     - 0.5 * num * q2 * r3) / (h * h)
        if whole:
            return n_b.T, nd_b.T, None if ndd_b is None else ndd_b.T
        n[:, sl], nd[:, sl] = n_b, nd_b
        if second:
            ndd[:, sl] = ndd_b
    return n.T, nd.T, None if ndd is None else ndd.T


def segment_headings(xyz_m: np.ndarray) -> np.ndarray:
    """Heading (rad, clockwise from north) of each segment of a polyline; a segment without
    horizontal extent takes the previous one's (the first such: the next one's, else 0)."""
    d = np.diff(np.asarray(xyz_m, float), axis=0)
    horiz = np.hypot(d[:, 0], d[:, 1])
    psi = np.arctan2(d[:, 0], d[:, 1])
    ok = horiz > 0
    if not np.any(ok):
        return np.zeros(len(d))
    idx = np.where(ok, np.arange(len(d)), -1)
    idx = np.maximum.accumulate(idx)
    idx[idx < 0] = np.flatnonzero(ok)[0]
    return psi[idx]


def corner_blends(s_m: np.ndarray, psi: np.ndarray):
    """Per vertex of a polyline: the blend half-width b (m) and the turn Δψ (rad, wrapped to
    (−π, π]) from the incoming to the outgoing segment; 0 at the two end vertices."""
    seg = np.diff(np.asarray(s_m, float))
    nv = len(s_m)
    b = np.zeros(nv)
    turn = np.zeros(nv)
    if nv > 2:
        b[1:-1] = np.minimum(CORNER_BLEND_M, 0.5 * np.minimum(seg[:-1], seg[1:]))
        turn[1:-1] = np.mod(psi[1:] - psi[:-1] + math.pi, 2.0 * math.pi) - math.pi
    return b, turn


def _smoothstep(x):
    return x * x * (3.0 - 2.0 * x), 6.0 * x * (1.0 - x), 6.0 - 12.0 * x


def corner_heading(s, s_j, s_j1, psi_j, b_j, turn_j, b_j1, turn_j1):
    """Heading ψ(s) of the road frame on segment j = [s_j, s_j1] (heading ψ_j), with its
    derivatives dψ/ds and d²ψ/ds²: ψ_j in the middle, a smoothstep across the blend of vertex
    j (from the previous heading, ψ_j − turn_j) and of vertex j + 1 (towards ψ_j + turn_j1)."""
    psi = np.array(psi_j, float, copy=True)
    d1 = np.zeros_like(psi)
    d2 = np.zeros_like(psi)
    near_start = (s - s_j) < b_j
    if np.any(near_start):
        i = np.flatnonzero(near_start)
        x = (s[i] - s_j[i] + b_j[i]) / (2.0 * b_j[i])          # in [0.5, 1]
        f, f1, f2 = _smoothstep(x)
        psi[i] = psi_j[i] - turn_j[i] + turn_j[i] * f
        d1[i] = turn_j[i] * f1 / (2.0 * b_j[i])
        d2[i] = turn_j[i] * f2 / (2.0 * b_j[i]) ** 2
    near_end = ~near_start & ((s_j1 - s) < b_j1)
    if np.any(near_end):
        i = np.flatnonzero(near_end)
        x = (b_j1[i] - (s_j1[i] - s[i])) / (2.0 * b_j1[i])    # in [0, 0.5]
        f, f1, f2 = _smoothstep(x)
        psi[i] = psi_j[i] + turn_j1[i] * f
        d1[i] = turn_j1[i] * f1 / (2.0 * b_j1[i])
        d2[i] = turn_j1[i] * f2 / (2.0 * b_j1[i]) ** 2
    return psi, d1, d2


def world_offset(n, nd, ndd, psi, dpsi_ds, d2psi_ds2, speed, accel, sin_cos=None):
    """Offset, velocity and acceleration (each (k, 3), ENU) of the wander in a frame turning
    with heading ψ(s(t)): along A = (sin ψ, cos ψ, 0), across C = (−cos ψ, sin ψ, 0) (left), up.
    ``sin_cos``: (sin ψ, cos ψ) when the caller has them (else computed from ``psi``);
    ``ndd`` None: no acceleration (None; ``d2psi_ds2`` and ``accel`` are not read).

    With ω = ψ'·v and ω' = ψ''·v² + ψ'·a (A' = −ωC, C' = ωA):
    velocity (ṅ_a + ω n_c) A + (ṅ_c − ω n_a) C + ṅ_u U;
    acceleration (n̈_a + ω' n_c + 2ω ṅ_c − ω² n_a) A + (n̈_c − ω' n_a − 2ω ṅ_a − ω² n_c) C + n̈_u U.
    """
    sp, cp = (np.sin(psi), np.cos(psi)) if sin_cos is None else sin_cos
    w = dpsi_ds * speed
    na, nc, nu = n.T
    va, vc, vu = nd.T

    def world(c_a, c_c, c_u):      # (k, 3), as a view of a (3, k) array (long rows)
        out = np.empty((3,) + np.shape(c_a))
        np.subtract(c_a * sp, c_c * cp, out=out[0])
        np.add(c_a * cp, c_c * sp, out=out[1])
        out[2] = c_u
        return out.T

    off = world(na, nc, nu)
    vel = world(va + w * nc, vc - w * na, vu)
    if ndd is None:
        return off, vel, None
    wd = d2psi_ds2 * speed * speed + dpsi_ds * accel
    aa, ac, au = ndd.T
    acc = world(aa + wd * nc + 2.0 * w * vc - w * w * na,
                ac - wd * na - 2.0 * w * va - w * w * nc, au)
    return off, vel, acc
