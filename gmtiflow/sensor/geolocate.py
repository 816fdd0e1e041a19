r"""Ground position of a measured (range, azimuth), as a GMTI processor computes it, on the
round earth of :mod:`gmtiflow.sensor.geometry` (a sphere of radius R; ``radius_m=None``: flat).

The radar measures slant range R_m and the azimuth (scan angle) in its antenna frame, not the
elevation.  The reported position is where the cone of that azimuth meets the sphere of radius
R_m around the platform on the terrain surface, the sphere of radius R + h (h the terrain
height).  With the antenna axes ``b, h, u`` (see :mod:`gmtiflow.sensor.antenna`, in the
platform's local ENU frame) a point at elevation ε is
``o = R_m (cos ε (cos az b + sin az h) + sin ε u)`` from the platform; its up component is
``A cos ε + B sin ε`` with A = R_m (cos az b_z + sin az h_z), B = R_m u_z.  It lies on the
surface of height h when that up component is

.. math::  C = \frac{(h - z_P)(2R + h + z_P) - R_m^2}{2 (R + z_P)}

(from |o + (0, 0, R + z_P)|² = (R + h)²; flat: C = h − z_P), so

.. math::  \varepsilon = \operatorname{atan2}(B, A) - \arccos\big(C / \sqrt{A^2 + B^2}\big),

the lower (downward-looking) of the two roots.  Where the cone grazes the surface (C/√(A²+B²)
→ ±1) the two roots merge, 2 arcsin √(1 − (C/√(A²+B²))²) apart: range and azimuth cannot tell
them apart there, and the point returned may be the other one (a target 0.44 m away in
``tests/sensor/test_geolocate.py``'s grazing case).  The point goes back to map coordinates
through its central angle from the platform, θ = atan2(|o_horizontal|, R + z_P + o_up): map
distance Rθ along the azimuth of o's horizontal part.  Over a DEM the ground height is not known
beforehand, so it is iterated: start at the height under the platform, intersect, read
``terrain.height_at`` there, repeat until it moves less than ``tol_m``.  A flat terrain takes a
single step.  When the range is too short to reach the ground (|C| > √(A²+B²)) the closest
direction is used and ``reached`` is False (range-folded reports can do that; the ambiguity
stage flags them implausible).

Vectors are 3-tuples of arrays (map coordinates, :mod:`gmtiflow.frames`).
"""
from __future__ import annotations

import numpy as np

from gmtiflow.sensor.geometry import DEFAULT_RADIUS_M


def _intersect(platform_xyz, range_m, ca, sa, b, h, u, ground_z, radius_m):
    """One intersection with the surface of height ``ground_z``, trig-free in ε:
    with ρ = √(A²+B²), r = C/ρ, s = √(1 − r²): cos ε = (A r + B s)/ρ, sin ε = (B r − A s)/ρ.
    Returns the map point, cos ε, sin ε and ``reached``."""
    a_coef = range_m * (ca * b[2] + sa * h[2])
    b_coef = range_m * u[2]
    zp = np.asarray(platform_xyz[2], float)
    if radius_m is None:
        c = ground_z - zp
    else:
        c = ((ground_z - zp) * (2.0 * radius_m + ground_z + zp) - range_m * range_m) \
            / (2.0 * (radius_m + zp))
    rho = np.hypot(a_coef, b_coef)
    ok = rho > 0
    if np.all(ok):      # the usual case: the same values without the masked fallbacks
        inv_rho = 1.0 / rho
        ratio = c * inv_rho
    else:
        inv_rho = np.divide(1.0, rho, out=np.zeros_like(rho), where=ok)
        ratio = np.where(ok, c * inv_rho, -1.0)
    reached = np.abs(ratio) <= 1.0
    r = np.clip(ratio, -1.0, 1.0)
    s = np.sqrt(1.0 - r * r)
    ce = (a_coef * r + b_coef * s) * inv_rho
    se = (b_coef * r - a_coef * s) * inv_rho
    if not np.all(ok):
        ce = np.where(ok, ce, 0.0)
        se = np.where(ok, se, -1.0)
    rc, rs, re = range_m * ce * ca, range_m * ce * sa, range_m * se
    o = tuple(rc * b[k] + rs * h[k] + re * u[k] for k in range(3))
    height = ground_z if reached.all() else np.where(reached, ground_z, np.nan)
    return to_map(platform_xyz, o, radius_m, height), ce, se, reached


def to_map(platform_xyz, o, radius_m, height_m=None):
    """Map point of an offset ``o`` (platform's local ENU frame, m) from the platform: central
    angle θ = atan2(|o_h|, R + z_P + o_up), map distance Rθ along o_h; its height ``height_m``
    where given (finite), else |o + centre offset| − R."""
    px, py, pz = (np.asarray(c, float) for c in platform_xyz)
    if radius_m is None:
        z = pz + o[2]
        if height_m is not None:
            z = np.where(np.isfinite(height_m), height_m, z)
        return px + o[0], py + o[1], z
    horiz = np.hypot(o[0], o[1])
    up = radius_m + pz + o[2]
    theta = np.arctan2(horiz, up)
    if np.all(horiz > 0):
        scale = radius_m * theta / horiz
    else:
        scale = np.divide(radius_m * theta, horiz, out=np.ones_like(horiz), where=horiz > 0)
    if height_m is None:
        z = np.hypot(horiz, up) - radius_m
    else:       # the height where given; |o + centre offset| − R only where not
        height_m = np.asarray(height_m, float)
        z = np.array(np.broadcast_to(height_m, np.broadcast(horiz, height_m).shape))
        off = ~np.isfinite(z)
        if np.any(off):
            z[off] = (np.hypot(np.broadcast_to(horiz, z.shape)[off],
                               np.broadcast_to(up, z.shape)[off]) - radius_m)
    return px + o[0] * scale, py + o[1] * scale, z


def geolocate(platform_xyz, range_m, az_rad, b, h, u, terrain, iterations: int = 8,
              tol_m: float = 0.1, radius_m=DEFAULT_RADIUS_M, *, elevation: bool = True,
              cos_sin=None):
    """Measured ground points ``(x, y, z)``, their antenna elevations and a ``reached`` flag.

    ``platform_xyz``, ``b``, ``h``, ``u`` are 3-tuples of arrays; ``range_m`` and ``az_rad``
    (antenna frame) arrays of the same shape.  ``terrain`` provides ``flat`` and
    ``height_at(x_m, y_m)``.  ``elevation=False``: the elevations are not computed (None).
    ``cos_sin``: ``(np.cos(az_rad), np.sin(az_rad))`` when the caller has them (``az_rad`` is
    then not read).
    """
    range_m = np.asarray(range_m, float)
    if cos_sin is None:
        az_rad = np.asarray(az_rad, float)
        ca, sa = np.cos(az_rad), np.sin(az_rad)
    else:
        ca, sa = cos_sin
    # a terrain without data under the platform (NaN) starts from 0 m
    ground = np.asarray(terrain.height_at(platform_xyz[0], platform_xyz[1]), float)
    ground = np.broadcast_to(ground if np.isfinite(ground).all() else np.nan_to_num(ground),
                             range_m.shape)
    p, ce, se, reached = _intersect(platform_xyz, range_m, ca, sa, b, h, u, ground, radius_m)
    if not getattr(terrain, "flat", False):
        for _ in range(iterations):
            new_ground = np.asarray(terrain.height_at(p[0], p[1]), float)
            new_ground = np.where(np.isfinite(new_ground), new_ground, ground)  # off the DEM
            p, ce, se, reached = _intersect(platform_xyz, range_m, ca, sa, b, h, u, new_ground,
                                            radius_m)
            if np.all(np.abs(new_ground - ground) < tol_m):
                break
            ground = new_ground
    return p, (np.arctan2(se, ce) if elevation else None), reached


def geolocate_world_azimuth(platform_xyz, range_m, azimuth_rad, terrain, iterations: int = 8,
                            tol_m: float = 0.1, radius_m=DEFAULT_RADIUS_M):
    """Ground points at slant range R_m and *world* azimuth A (clockwise from north) from the
    platform: ``p = P + (g sin A, g cos A, h − P_z)`` with the ground distance g = Rθ,
    sin²(θ/2) = (R_m² − (a − b)²)/(4ab), a = R + P_z, b = R + h (law of cosines; flat:
    g = √(R_m² − (P_z − h)²)), iterated on ``terrain.height_at`` like :func:`geolocate`.  The
    inverse of a detection's reported ``range_m``/``azimuth_rad`` (for re-geolocating merged or
    range-folded reports).

    Returns ``((x, y, z), reached)``; where R is shorter than the height above the ground the
    point is put at nadir and ``reached`` is False.
    """
    px, py, pz = (np.asarray(c, float) for c in platform_xyz)
    range_m = np.asarray(range_m, float)
    sa, ca = np.sin(azimuth_rad), np.cos(azimuth_rad)
    ground = np.broadcast_to(np.nan_to_num(np.asarray(terrain.height_at(px, py), float)),
                             range_m.shape)

    def step(h):
        dz = pz - h
        g2 = range_m * range_m - dz * dz
        if radius_m is None:
            g = np.sqrt(np.maximum(g2, 0.0))
        else:
            half = g2 / (4.0 * (radius_m + pz) * (radius_m + h))
            g = 2.0 * radius_m * np.arcsin(np.sqrt(np.clip(half, 0.0, 1.0)))
        return (px + g * sa, py + g * ca, np.broadcast_to(h, range_m.shape).astype(float)), \
            g2 >= 0

    p, reached = step(ground)
    if not getattr(terrain, "flat", False):
        for _ in range(iterations):
            new_ground = np.asarray(terrain.height_at(p[0], p[1]), float)
            new_ground = np.where(np.isfinite(new_ground), new_ground, ground)
            p, reached = step(new_ground)
            if np.all(np.abs(new_ground - ground) < tol_m):
                break
            ground = new_ground
    return p, reached
