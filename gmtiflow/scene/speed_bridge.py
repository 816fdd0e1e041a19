r"""The speed bridge of a free-cruise step: the vehicle's speed between two grid points of its
speed noise (DESIGN §3; :mod:`gmtiflow.scene.motion` decides which steps carry it).

In a *free cruise* step (the speed heads for its cruise c plus the noise σξ and nothing clips
it) the speed is not the straight line between c + σξ_k and c + σξ_{k+1}: that line's variance,
σ²q(f) with :math:`q(f) = 1 - \kappa f(1-f)`, :math:`\kappa = 2(1-\rho)`, f = u/Δt, dips to
σ²(1+ρ)/2 mid-step (0.71 σ with T_c = 0).  Instead

.. math::
    v(u) = c + \sigma\,\frac{(1-f)\xi_k + f\xi_{k+1}}{\sqrt{q(f)}} ,

the linear interpolation normalised by its own standard deviation: exactly N(c, σ²) at every
instant, equal to the grid values at f = 0 and 1, and smooth inside the step.  The difference
from the straight line, δ(f) = L(f)(q^{-1/2} − 1) with L = σ((1-f)ξ_k + fξ_{k+1}), is a bridge
(zero at both ends); its integral (closed form, :func:`bridge`) is added to s, and its
derivative to the acceleration, so v = ds/dt and a = dv/dt still hold exactly.  A step may carry
it only where it keeps v ≥ 0 (min(v_k, v_{k+1}) ≥ :data:`GUARD` max |σξ|) and the acceleration
within the vehicle's limits at every instant of the step: with g = f − ½,
A = σ(ξ_k + ξ_{k+1})/2, B = σ(ξ_{k+1} − ξ_k) and m = 1 − κ/4 the bridged speed's rate is
dv/du = (Bm − Aκg)/((κg² + m)^{3/2} Δt), whose extremes over the step are at its ends or where
2Aκg² − 3Bmg − Am = 0 (:func:`within_limits`, screened by :func:`drop_past_limits`).

Units: x0, x1 = σξ in m/s; f the fraction of the step, in [0, 1]; κ dimensionless in [0, 2].
"""
from __future__ import annotations

import math

import numpy as np

GUARD = np.sqrt(2.0) - 1.0
"""The largest q^{-1/2} − 1 (κ ≤ 2): the bridge keeps v ≥ 0 where
min(v_k, v_{k+1}) ≥ GUARD · max |σξ|."""


def _asinh_ratio(z):
    """asinh(z)/z, 1 at z = 0 (series below 1e-4)."""
    z = np.asarray(z, float)
    small = np.abs(z) < 1e-4
    safe = np.where(small, 1.0, z)
    return np.where(small, 1.0 - z * z / 6.0, np.arcsinh(safe) / safe)


def bridge_constants(kappa):
    """The parts of :func:`bridge` that depend on κ alone, per profile: m, √m, √(κ/m) and
    asinh(z)/z at z = −½√(κ/m) (the lower end of the integral)."""
    m = 1.0 - 0.25 * kappa
    rk = np.sqrt(kappa / m)
    return m, np.sqrt(m), rk, _asinh_ratio(-0.5 * rk)


def within_limits(a, x0, x1, kappa, dt, amax, dmax):
    """Whether a step of constant acceleration ``a`` (its straight line from σξ_k = ``x0`` to
    σξ_{k+1} = ``x1``, slope (x1 − x0)/Δt) stays within [−dmax, amax] at every instant once
    the bridge is added (module doc): the bridged speed's rate in f is
    N(g) = (Bm − Aκg)(κg² + m)^{-3/2}, g = f − ½ (the derivative of (A + Bg) q^{-1/2}), whose
    extremes on [−½, ½] are at the ends (N = Bm ∓ Aκ/2) or at the roots of
    N' ∝ 2Aκg² − 3Bmg − Am (taken in the cancellation-free form, clipped to the step)."""
    aa = 0.5 * (x0 + x1)
    b = x1 - x0
    m = 1.0 - 0.25 * kappa

    def n_of(g):
        return (b * m - aa * kappa * g) / (kappa * g * g + m) ** 1.5

    qa, qb, qc = 2.0 * aa * kappa, -3.0 * b * m, -aa * m
    root = np.sqrt(qb * qb - 4.0 * qa * qc)
    qq = -0.5 * (qb + np.where(qb < 0, -root, root))
    with np.errstate(divide="ignore", invalid="ignore"):
        r1 = np.where(qa != 0, qq / qa, 0.0)
        r2 = np.where(qq != 0, qc / qq, 0.0)
    r1 = np.clip(np.nan_to_num(r1), -0.5, 0.5)
    r2 = np.clip(np.nan_to_num(r2), -0.5, 0.5)
    ends = (n_of(-0.5), n_of(0.5), n_of(r1), n_of(r2))
    hi = np.maximum(np.maximum(ends[0], ends[1]), np.maximum(ends[2], ends[3]))
    lo = np.minimum(np.minimum(ends[0], ends[1]), np.minimum(ends[2], ends[3]))
    return (a + (hi - b) / dt <= amax) & (a + (lo - b) / dt >= -dmax)


def rate_bounds(kappa):
    """(e₁, e₂) per profile: |N − B| ≤ |B| e₁ + max(|x0|, |x1|) e₂ over a whole step, N the
    bridged speed's rate in f (:func:`within_limits`), e₁ = m^{-1/2} − 1,
    e₂ = κ/(2m^{3/2}) (|g| ≤ ½, q ≥ m)."""
    m = 1.0 - 0.25 * kappa
    return 1.0 / np.sqrt(m) - 1.0, 0.5 * kappa / (m * np.sqrt(m))


def drop_past_limits(free, a, x0, x1, kappa, e1, e2, dt, amax, dmax):
    """``free`` without the steps whose bridge would cross a limit (arrays broadcast to
    ``free``'s shape; ``e1``, ``e2`` of :func:`rate_bounds`).  The bound screens: only
    the free steps it does not keep inside the limits get the exact test of
    :func:`within_limits` (the same answers, for a few steps)."""
    beta = (np.abs(x1 - x0) * e1 + np.maximum(np.abs(x0), np.abs(x1)) * e2) / dt
    idx = np.nonzero(free & ((a + beta > amax) | (a - beta < -dmax)))
    if idx[0].size:
        a, x0, x1, kappa, amax, dmax = (np.broadcast_to(v, free.shape)[idx]
                                        for v in (a, x0, x1, kappa, amax, dmax))
        ok = within_limits(a, x0, x1, kappa, dt, amax, dmax)
        free = free.copy()
        free[tuple(i[~ok] for i in idx)] = False
    return free


def bridge(x0, x1, kappa, f, const=None):
    """The free-cruise speed bridge of a step (module doc): δ(f), dδ/df and ∫_0^f δ df'.

    ``x0``, ``x1`` = σξ_k, σξ_{k+1} (m/s), ``kappa`` = 2(1 − ρ) in [0, 2], ``f`` in [0, 1].
    With g = f − ½, q = κg² + m (m = 1 − κ/4), L = A + Bg (A = (x0 + x1)/2, B = x1 − x0):
    ∫ L q^{-1/2} dg = A asinh(g√(κ/m))/√κ + (B/κ)√q, written stably for κ → 0 as
    A g m^{-1/2} asinh(z)/z and B(g² − ¼)/(√q + 1) from g = −½.
    ``const``: :func:`bridge_constants` of ``kappa`` (the same values, computed once per
    profile instead of per row).
    """
    g = f - 0.5
    if const is None:
        const = bridge_constants(kappa)
    m, sm, rk, ratio_low = const
    q = kappa * g * g + m
    rq = 1.0 / np.sqrt(q)
    a = 0.5 * (x0 + x1)
    b = x1 - x0
    lin = a + b * g
    delta = lin * (rq - 1.0)
    d_delta = b * (rq - 1.0) - lin * kappa * g * rq ** 3
    prim_g = a * g / sm * _asinh_ratio(g * rk)
    prim_low = a * -0.5 / sm * ratio_low
    integral_n = prim_g - prim_low + b * (g * g - 0.25) / (np.sqrt(q) + 1.0)
    integral_l = x0 * f + 0.5 * b * f * f
    return delta, d_delta, integral_n - integral_l


def bridge_exact(x0, x1, kappa, f):
    """δ(f) and ∫_0^f δ df' of :func:`bridge` for the Newton steps of
    :meth:`gmtiflow.scene.profiles.Profiles.times_at`, bit for bit the same as the one-float
    form written with the math module (kept as the oracle in
    tests/scene/test_truth_kinematics.py): the same operations in the same order, asinh from
    the math module."""
    g = f - 0.5
    m = 1.0 - 0.25 * kappa
    q = kappa * g * g + m
    rq = 1.0 / np.sqrt(q)
    a, b = 0.5 * (x0 + x1), x1 - x0
    lin = a + b * g
    rk = np.sqrt(kappa / m)
    sm = np.sqrt(m)

    def prim(gg):
        z = gg * rk
        ratio = 1.0 - z * z / 6.0
        big = np.flatnonzero(~(np.abs(z) < 1e-4))
        if big.size:
            zb = z[big].tolist()
            ratio[big] = np.asarray([math.asinh(v) for v in zb]) / z[big]
        return a * gg / sm * ratio

    half = np.full_like(g, -0.5)
    integral = (prim(g) - prim(half) + b * (g * g - 0.25) / (np.sqrt(q) + 1.0)
                - (x0 * f + 0.5 * b * f * f))
    return lin * (rq - 1.0), integral
