"""Ground position of a measured (range, azimuth), as a GMTI processor computes it.

The radar measures slant range R and the azimuth (scan angle) in its antenna frame, not the
elevation.  The reported position is where the cone of that azimuth meets the sphere of radius R
on the terrain surface z = h(x, y).  With the antenna axes ``b, h, u`` (see
:mod:`gmtiflow.sensor.antenna`) a point at elevation ε is
``p = P + R (cos ε (cos az b + sin az h) + sin ε u)``; its height is ``P_z + A cos ε + B sin ε``
with A = R (cos az b_z + sin az h_z), B = R u_z.  Setting it to the ground height (C = h − P_z)
gives

.. math::  \\varepsilon = \\operatorname{atan2}(B, A) - \\arccos\\big(C / \\sqrt{A^2 + B^2}\\big),

the lower (downward-looking) of the two roots.  Over a DEM the ground height is not known
beforehand, so it is iterated: start at the height under the platform, intersect, read
``terrain.height_at`` there, repeat until it moves less than ``tol_m``.  A flat terrain takes a
single step.  When the range is too short to reach the ground (|C| > √(A²+B²)) the closest
direction is used and ``reached`` is False (range-folded reports can do that; the ambiguity stage
flags them implausible).

Vectors are 3-tuples of arrays (ENU).
"""
from __future__ import annotations

import numpy as np



def _intersect(platform_xyz, range_m, ca, sa, b, h, u, ground_z):
    """One intersection with the plane z = ground_z, trig-free in ε:
    with ρ = √(A²+B²), r = C/ρ, s = √(1 − r²): cos ε = (A r + B s)/ρ, sin ε = (B r − A s)/ρ."""
    a_coef = range_m * (ca * b[2] + sa * h[2])
    b_coef = range_m * u[2]
    c = ground_z - platform_xyz[2]
    rho = np.hypot(a_coef, b_coef)
    ok = rho > 0
    inv_rho = np.divide(1.0, rho, out=np.zeros_like(rho), where=ok)
    ratio = np.where(ok, c * inv_rho, -1.0)
    reached = np.abs(ratio) <= 1.0
    r = np.clip(ratio, -1.0, 1.0)
    s = np.sqrt(1.0 - r * r)
    ce = np.where(ok, (a_coef * r + b_coef * s) * inv_rho, 0.0)
    se = np.where(ok, (b_coef * r - a_coef * s) * inv_rho, -1.0)
    rc, rs, re = range_m * ce * ca, range_m * ce * sa, range_m * se
    p = tuple(platform_xyz[k] + rc * b[k] + rs * h[k] + re * u[k] for k in range(3))
    return p, ce, se, reached


def geolocate(platform_xyz, range_m, az_rad, b, h, u, terrain, iterations: int = 8,
              tol_m: float = 0.1):
    """Measured ground points ``(x, y, z)``, their antenna elevations and a ``reached`` flag.

    ``platform_xyz``, ``b``, ``h``, ``u`` are 3-tuples of arrays; ``range_m`` and ``az_rad``
    (antenna frame) arrays of the same shape.  ``terrain`` provides ``flat`` and
    ``height_at(x_m, y_m)``.
    """
    range_m = np.asarray(range_m, float)
    az_rad = np.asarray(az_rad, float)
    ca, sa = np.cos(az_rad), np.sin(az_rad)
    # a terrain without data under the platform (NaN) starts from 0 m
    ground = np.broadcast_to(np.nan_to_num(np.asarray(
        terrain.height_at(platform_xyz[0], platform_xyz[1]), float)), range_m.shape)
    p, ce, se, reached = _intersect(platform_xyz, range_m, ca, sa, b, h, u, ground)
    if not getattr(terrain, "flat", False):
        for _ in range(iterations):
            new_ground = np.asarray(terrain.height_at(p[0], p[1]), float)
            new_ground = np.where(np.isfinite(new_ground), new_ground, ground)  # off the DEM
            p, ce, se, reached = _intersect(platform_xyz, range_m, ca, sa, b, h, u, new_ground)
            if np.all(np.abs(new_ground - ground) < tol_m):
                break
            ground = new_ground
    return p, np.arctan2(se, ce), reached


def geolocate_world_azimuth(platform_xyz, range_m, azimuth_rad, terrain, iterations: int = 8,
                            tol_m: float = 0.1):
    """Ground points at slant range R and *world* azimuth A (clockwise from north) from the
    platform: ``p = P + (g sin A, g cos A, h − P_z)``, g = √(R² − (P_z − h)²), iterated on
    ``terrain.height_at`` like :func:`geolocate`.  The inverse of a detection's reported
    ``range_m``/``azimuth_rad`` (for re-geolocating merged or range-folded reports).

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
        g = np.sqrt(np.maximum(g2, 0.0))
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
