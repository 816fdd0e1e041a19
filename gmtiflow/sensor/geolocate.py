"""Ground position of a measured (range, azimuth), as a GMTI processor computes it.

The radar measures slant range R and the azimuth (scan angle) in its antenna frame, not the
elevation.  The reported position is where the cone of that azimuth meets the sphere of radius R
on the terrain surface z = h(x, y).  With the antenna axes ``b, h, u`` (see
:mod:`gmtiflow.sensor.antenna`) a point at elevation ε is
``p = P + R (cos ε (cos az b + sin az h) + sin ε u)``; its height is ``P_z + A cos ε + B sin ε``
with A = R (cos az b_z + sin az h_z), B = R u_z.  Setting it to the ground height C + P_z gives

.. math::  \\varepsilon = \\operatorname{atan2}(B, A) - \\arccos\\big(C / \\sqrt{A^2 + B^2}\\big),

the lower (downward-looking) of the two roots.  Over a DEM the ground height is not known
beforehand, so it is iterated: start at the height under the platform, intersect, read
``terrain.height_at`` there, repeat.  A flat terrain takes a single step.  When the range is too
short to reach the ground (|C| > √(A²+B²)) the closest direction is used and ``reached`` is False
(range-folded reports can do that; the ambiguity stage flags them implausible).
"""
from __future__ import annotations

import numpy as np

from gmtiflow.sensor import antenna


def _intersect(platform_xyz, range_m, az_rad, b, h, u, ground_z):
    a_coef = range_m * (np.cos(az_rad) * b[..., 2] + np.sin(az_rad) * h[..., 2])
    b_coef = range_m * u[..., 2]
    c = ground_z - platform_xyz[..., 2]
    rho = np.hypot(a_coef, b_coef)
    ratio = np.divide(c, rho, out=np.full_like(c, -1.0), where=rho > 0)
    reached = np.abs(ratio) <= 1.0
    el = np.arctan2(b_coef, a_coef) - np.arccos(np.clip(ratio, -1.0, 1.0))
    p = platform_xyz + range_m[..., None] * antenna.direction(az_rad, el, b, h, u)
    return p, el, reached


def geolocate(platform_xyz, range_m, az_rad, b, h, u, terrain, iterations: int = 6,
              tol_m: float = 0.1):
    """Measured ground points (n, 3), their antenna elevations and a ``reached`` flag.

    ``platform_xyz``, ``b``, ``h``, ``u`` are (n, 3); ``range_m`` and ``az_rad`` (antenna frame)
    are (n,).  ``terrain`` provides ``flat`` and ``height_at(x_m, y_m)``.
    """
    platform_xyz = np.asarray(platform_xyz, float)
    range_m = np.asarray(range_m, float)
    az_rad = np.asarray(az_rad, float)
    ground = np.asarray(terrain.height_at(platform_xyz[:, 0], platform_xyz[:, 1]), float)
    ground = np.broadcast_to(ground, range_m.shape).astype(float)
    p, el, reached = _intersect(platform_xyz, range_m, az_rad, b, h, u, ground)
    if getattr(terrain, "flat", False):
        return p, el, reached
    for _ in range(iterations):
        new_ground = np.asarray(terrain.height_at(p[:, 0], p[:, 1]), float)
        p, el, reached = _intersect(platform_xyz, range_m, az_rad, b, h, u, new_ground)
        if np.all(np.abs(new_ground - ground) < tol_m):
            break
        ground = new_ground
    return p, el, reached
