r"""Platform-target geometry on a round earth: slant range, line of sight, grazing angle and
range rates (DESIGN §5, step 1).

Points are 3-tuples of arrays ``(x, y, z)`` in the scene's *map* coordinates
(:mod:`gmtiflow.frames`): (x, y) an azimuthal equidistant map of the earth's surface, z the
height above it.  The earth is a sphere of radius R (``radius_m``: the mean earth radius plus
the origin's height, :func:`gmtiflow.frames.sphere_radius_m`).  For a platform P and a target T
with map separation (Δx, Δy), ground distance d = √(Δx² + Δy²) (taken as the great-circle
distance), central angle θ = d/R, a = R + z_P, b = R + z_T, the target in the platform's own
local ENU frame (east, north, up at P) is

.. math::
    \mathbf{o}_P = \big(b \sin\theta\,\hat u_x,\; b \sin\theta\,\hat u_y,\;
                   (z_T - z_P) - 2 b \sin^2(\theta/2)\big), \qquad \hat u = (Δx, Δy)/d ,

so the slant range is the law of cosines, R_s² = a² + b² − 2ab cos θ = (a − b)² + 4ab sin²(θ/2),
and the line of sight ℓ = o_P/R_s (the frame in which the antenna axes, the platform velocity and
the field of view are expressed).  The same vector seen in the *target's* local frame,
ℓ_T = −o_T/R_s with o_T the platform from the target (roles swapped, direction −û), is what the
target's own velocity (horizontal in its own frame) is projected on.  The grazing angle at the
target is ψ = asin(−ℓ_T,up) (above the target's horizontal); it is 0 at the geometric horizon.
Velocities are map rates (d/dt of the map coordinates, as the scene's tables give them); the
range rate uses the true velocities (:func:`true_velocity`), so that ṙ is d/dt of the slant
range.  ``radius_m=None`` gives the flat local frame (o = T − P), for comparisons only.

Accuracy against WGS-84 ECEF (pymap3d) end to end, map coordinates from
:func:`gmtiflow.frames.geodetic_to_enu`: slant range within ~1e-5 of itself (millimetres at the
default 30 km stand-off, ≤ 6 m at the 580 km horizon of 20 km altitude); the flat frame was
14 m off at the default scene (tests/sensor/test_curved_earth.py).

Sign convention: range rate ṙ = (v_t − v_p)·ℓ with ℓ the unit line of sight from the platform
to the target, positive when the range grows (receding).  The main-lobe clutter at the target's
position (the ground, at rest) has ṙ_MLC = −v_p·ℓ, so ṙ − ṙ_MLC = v_t·ℓ is the target's own
radial speed: zero for a stopped or tangentially moving target.
"""
from __future__ import annotations

import numpy as np

from gmtiflow.sensor.antenna import dot

#: Ranges below this are treated as this (m): keeps R⁻⁴ and ℓ finite at R → 0.
MIN_RANGE_M = 1e-3


#: The sphere of the geometry when none is given: the mean earth radius (origin at 0 m).
DEFAULT_RADIUS_M = 6_371_008.8


def _curvature(d2, radius_m):
    """(sin θ/θ, 1 − cos θ) for θ² = d²/R²: even power series (no sqrt or trig; error below
    θ^8/362880, 2e-13 at θ = 0.1, the 640 km the horizon allows) when θ ≤ 0.5, else exact."""
    t2 = d2 / (radius_m * radius_m)
    if t2.size == 0 or float(np.max(t2)) <= 0.25:
        sinc = 1.0 - t2 * (1.0 / 6.0 - t2 * (1.0 / 120.0 - t2 * (1.0 / 5040.0)))
        vers = t2 * (0.5 - t2 * (1.0 / 24.0 - t2 * (1.0 / 720.0 - t2 * (1.0 / 40320.0))))
        return sinc, vers
    theta = np.sqrt(t2)
    small = theta < 1e-4
    safe = np.where(small, 1.0, theta)
    sinc = np.where(small, 1.0 - t2 / 6.0, np.sin(safe) / safe)
    return sinc, 2.0 * np.sin(0.5 * theta) ** 2


def offsets(platform_xyz, target_xyz, radius_m=DEFAULT_RADIUS_M, target_frame: bool = True):
    """(o_P, o_T): the target from the platform in the platform's local ENU frame and the
    platform from the target in the target's local frame (module doc), each a 3-tuple (m);
    ``target_frame=False``: o_T is not computed (None)."""
    o_p, t_h, t_up, _ = _offsets(platform_xyz, target_xyz, radius_m, target_frame)
    if t_h is None:
        return o_p, None
    return o_p, (-t_h[0], -t_h[1], t_up)


def _offsets(platform_xyz, target_xyz, radius_m, target_frame: bool = True):
    """o_P, and o_T as ``(Δx·k_T, Δy·k_T)`` (its horizontal part *negated*: o_T's is −Δ·k_T,
    and (−Δx)·k_T = −(Δx·k_T) exactly) and its up component (None, None without the target
    frame), and the squared map separation d² = Δx² + Δy² (None when flat).  Flat
    (``radius_m`` None): k_T = 1."""
    dx = np.asarray(target_xyz[0], float) - np.asarray(platform_xyz[0], float)
    dy = np.asarray(target_xyz[1], float) - np.asarray(platform_xyz[1], float)
    zp = np.asarray(platform_xyz[2], float)
    zt = np.asarray(target_xyz[2], float)
    if radius_m is None:
        dz = zt - zp
        return (dx, dy, dz), (dx, dy), -dz, None
    d2 = dx * dx + dy * dy
    sinc, vers = _curvature(d2, radius_m)
    b = radius_m + zt
    s_r = sinc / radius_m
    kp = b * s_r                        # b sin θ / d
    dz = zt - zp
    o_p = (dx * kp, dy * kp, dz - b * vers)
    if not target_frame:
        return o_p, None, None, d2
    a = radius_m + zp
    kt = a * s_r
    return o_p, (dx * kt, dy * kt), -dz - a * vers, d2


def slant_range(platform_xyz, target_xyz, radius_m=DEFAULT_RADIUS_M):
    """Slant range (m) by the law of cosines, √((a − b)² + 4ab sin²(θ/2)) (module doc)."""
    o_p, _ = offsets(platform_xyz, target_xyz, radius_m)
    return np.sqrt(o_p[0] * o_p[0] + o_p[1] * o_p[1] + o_p[2] * o_p[2])


def grazing_angle_rad(platform_xyz, target_xyz, radius_m=DEFAULT_RADIUS_M):
    """ψ: elevation of the platform above the target's local horizontal (rad; < 0 below the
    geometric horizon).  With ``radius_m`` = k·R (4/3 earth) the refracted grazing angle."""
    _, o_t = offsets(platform_xyz, target_xyz, radius_m)
    rng = np.sqrt(o_t[0] * o_t[0] + o_t[1] * o_t[1] + o_t[2] * o_t[2])
    return np.arcsin(np.clip(o_t[2] / np.maximum(rng, MIN_RANGE_M), -1.0, 1.0))


def _unit(o, sign=1.0):
    """Length of ``o`` and ``sign``·o/|o| (straight down, (0, 0, −1), below MIN_RANGE_M)."""
    rng = np.sqrt(o[0] * o[0] + o[1] * o[1] + o[2] * o[2])
    inv = 1.0 / np.maximum(rng, MIN_RANGE_M)
    small = rng < MIN_RANGE_M
    if sign < 0:
        inv = -inv           # (−o)·inv = o·(−inv) exactly: IEEE products are sign-symmetric
    los = (o[0] * inv, o[1] * inv, o[2] * inv)
    if np.any(small):
        los = (np.where(small, 0.0, los[0]), np.where(small, 0.0, los[1]),
               np.where(small, -1.0, los[2]))
    return rng, los


def target_line_of_sight(platform_xyz, target_xyz, radius_m=DEFAULT_RADIUS_M):
    """Unit LOS platform → target expressed in the *target's* local ENU frame (ℓ_T)."""
    _, o_t = offsets(platform_xyz, target_xyz, radius_m)
    return _unit(o_t, -1.0)[1]


def line_of_sight(platform_xyz, target_xyz, radius_m=DEFAULT_RADIUS_M):
    """Slant range (m) and unit LOS from platform to target in the platform's local frame.

    At zero range the LOS is taken straight down (0, 0, −1) so that nothing is NaN.
    """
    o_p, _ = offsets(platform_xyz, target_xyz, radius_m)
    return _unit(o_p)


def pair_offsets(platform_xyz, target_xyz, radius_m=DEFAULT_RADIUS_M) -> tuple:
    """What :func:`lines_of_sight` computes first, for a caller that also wants o_P (the target
    from the platform, platform frame) before it: ``(o_P, o_T's horizontal part negated, o_T's
    up component, d²)`` (``_offsets`` with the target frame).  Give it back to
    :func:`lines_of_sight` as ``offsets``."""
    return _offsets(platform_xyz, target_xyz, radius_m)


def lines_of_sight(platform_xyz, target_xyz, radius_m=DEFAULT_RADIUS_M, *,
                   ground_d2: bool = False, offsets=None):
    """:func:`line_of_sight` and :func:`target_line_of_sight` from one :func:`offsets`:
    ``(range_m, ℓ in the platform's frame, ℓ_T in the target's frame)``, and with
    ``ground_d2`` the squared map separation Δx² + Δy² (None when flat) as a fourth item.
    ``offsets``: :func:`pair_offsets` of these points when the caller has it (the points are
    then not read).

    ℓ_T = −o_T/|o_T| is taken from o_T's horizontal part before its negation (``_offsets``):
    (−a)² = a² and (−a)·(−c) = a·c exactly, so the values are those of −o_T·(1/|o_T|) without
    two negations of every pair."""
    if offsets is None:
        offsets = _offsets(platform_xyz, target_xyz, radius_m)
    o_p, (hx, hy), t_up, d2 = offsets
    rng, los = _unit(o_p)
    rng_t = np.sqrt(hx * hx + hy * hy + t_up * t_up)
    inv = 1.0 / np.maximum(rng_t, MIN_RANGE_M)
    los_t = (hx * inv, hy * inv, t_up * -inv)
    small = rng_t < MIN_RANGE_M
    if np.any(small):           # straight down, as _unit gives it
        los_t = (np.where(small, 0.0, los_t[0]), np.where(small, 0.0, los_t[1]),
                 np.where(small, -1.0, los_t[2]))
    return (rng, los, los_t, d2) if ground_d2 else (rng, los, los_t)


def true_velocity(v_map, z_m, radius_m=DEFAULT_RADIUS_M):
    """A velocity in map rates (d/dt of map x, y, z) as a true velocity in the local frame
    (m/s): the horizontal map rate is the ground-projected one, so at height z it is scaled by
    (R + z)/R (0.09 % at 6 km); the vertical is unchanged.  ``radius_m=None``: unchanged."""
    if radius_m is None:
        return tuple(np.asarray(c, float) for c in v_map)
    z = np.asarray(z_m, float)
    if z.ndim == 1 and z.size > 64 and not np.any(z):
        # on the sphere itself (z = ±0): k = 1 exactly and v·1 = v, bit for bit
        return tuple(np.broadcast_to(np.asarray(c, float), z.shape) for c in v_map)
    k = 1.0 + z / radius_m
    return (np.asarray(v_map[0], float) * k, np.asarray(v_map[1], float) * k,
            np.asarray(v_map[2], float))


def range_rate(target_v, platform_v, los, target_los=None):
    """ṙ = v_t·ℓ_T − v_p·ℓ (m/s, + receding): each velocity in its own local frame, projected
    on the LOS expressed there (``target_los`` None: the same frame, as when flat)."""
    return dot(target_v, los if target_los is None else target_los) - dot(platform_v, los)


def clutter_range_rate(platform_v, los):
    """ṙ_MLC = −v_p·ℓ: range rate of the stationary ground at the target (m/s)."""
    return -dot(platform_v, los)
