"""Visibility of a target in a look (DESIGN §5 step 2): field of view and terrain.

Field-of-view limits are inclusive: a target exactly on a limit is inside.  Azimuth and elevation
are antenna-frame angles (:mod:`gmtiflow.sensor.antenna`), range is slant range.  The terrain
line of sight is asked only for the pairs that survived every cheaper test, and never when the
terrain is flat.
"""
from __future__ import annotations

import math

import numpy as np

from gmtiflow.sensor.config import SensorConfig

#: Mean earth radius (m) of the radar-horizon model when no sphere is given.
EARTH_RADIUS_M = 6_371_008.8


def fov_limits_rad(cfg: SensorConfig):
    """(az_min, az_max, el_min, el_max) in radians."""
    return (math.radians(cfg.az_min_deg), math.radians(cfg.az_max_deg),
            math.radians(cfg.el_min_deg), math.radians(cfg.el_max_deg))


def in_field_of_view(cfg: SensorConfig, az_rad, el_rad, range_m):
    """True where azimuth, elevation and slant range are all within their (inclusive) limits."""
    az_min, az_max, el_min, el_max = fov_limits_rad(cfg)
    az = np.asarray(az_rad, float)
    el = np.asarray(el_rad, float)
    r = np.asarray(range_m, float)
    return ((az >= az_min) & (az <= az_max) & (el >= el_min) & (el <= el_max)
            & (r >= cfg.range_min_m) & (r <= cfg.range_max_m))


def terrain_clear(terrain, platform_xyz, target_xyz, step_m: float, earth_radius_m=None):
    """Line of sight from platform to target not blocked by terrain (all True when flat).

    ``platform_xyz`` and ``target_xyz`` are 3-tuples of arrays; the terrain is called with
    (n, 3) arrays, ``terrain.line_of_sight(from_xyz, to_xyz, step_m) -> bool[n]``.
    """
    n = len(target_xyz[0])
    if getattr(terrain, "flat", False) or n == 0:
        return np.ones(n, bool)
    if earth_radius_m is None:
        return np.asarray(terrain.line_of_sight(np.column_stack(platform_xyz),
                                                np.column_stack(target_xyz), step_m), bool)
    return np.asarray(terrain.line_of_sight(np.column_stack(platform_xyz),
                                            np.column_stack(target_xyz), step_m,
                                            earth_radius_m=earth_radius_m), bool)


def horizon_distance_m(height_m, k_factor: float, radius_m: float = EARTH_RADIUS_M):
    """Ground (arc) distance to the radar horizon of a point ``height_m`` above a smooth earth
    of effective radius a = k·R (4/3 for standard refraction): a·acos(a/(a + h)) (≈ √(2ah) for
    h ≪ a); 0 at or below the surface."""
    a = k_factor * radius_m
    h = np.maximum(np.asarray(height_m, float), 0.0)
    # acos(a/(a+h)) = atan(√(2ah + h²)/a), stable for small h
    if h.ndim == 1 and h.size > 64:      # points on the surface (flat ground) are exactly 0
        up = np.flatnonzero(h)
        out = np.zeros(h.shape)
        if up.size:
            hu = h[up]
            out[up] = a * np.arctan(np.sqrt(hu * (2.0 * a + hu)) / a)
        return out
    return a * np.arctan(np.sqrt(h * (2.0 * a + h)) / a)


def within_horizon(platform_xyz, target_xyz, k_factor: float, radius_m: float = EARTH_RADIUS_M,
                   platform_reach_m=None):
    """True where a point is above the radar horizon of the platform (smooth k-earth).

    Heights are map ``z`` (above the sphere through the scene origin, :mod:`gmtiflow.frames`);
    the point is seen when its ground (great-circle) distance d from the platform is at most the
    sum of the two horizon distances, d ≤ a·acos(a/(a + h_p)) + a·acos(a/(a + h_t)), a = k·R
    (Skolnik, *Introduction to Radar Systems*, 3rd ed., §8.4; the 4/3-earth radar horizon):
    exactly where the straight ray in the k-earth grazes the sphere, i.e. where the grazing angle
    on the k-earth (:func:`gmtiflow.sensor.geometry.grazing_angle_rad` with radius k·R) of a
    ground point reaches 0.  At 10 m altitude a ground point is seen out to 13 km, at 6 km
    altitude out to 319 km, at 20 km out to 583 km.

    ``platform_reach_m``: the platform's :func:`horizon_distance_m`, when the caller has it (one
    per dwell rather than per pair); ``platform_xyz[2]`` is then not read.
    """
    dx = np.asarray(target_xyz[0], float) - np.asarray(platform_xyz[0], float)
    dy = np.asarray(target_xyz[1], float) - np.asarray(platform_xyz[1], float)
    if platform_reach_m is None:
        platform_reach_m = horizon_distance_m(platform_xyz[2], k_factor, radius_m)
    return within_reach(dx * dx + dy * dy, target_xyz[2], k_factor, radius_m, platform_reach_m)


def within_reach(ground_d2, target_z, k_factor: float, radius_m: float, platform_reach_m):
    """:func:`within_horizon` from the squared map separation d² = Δx² + Δy² of platform and
    point (as :func:`gmtiflow.sensor.geometry.offsets` computes it for the pair's geometry), the
    point's height and the platform's horizon distance."""
    reach = platform_reach_m + horizon_distance_m(target_z, k_factor, radius_m)
    return ground_d2 <= reach * reach
