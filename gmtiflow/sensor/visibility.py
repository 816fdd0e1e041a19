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


def terrain_clear(terrain, platform_xyz, target_xyz, step_m: float):
    """Line of sight from platform to target not blocked by terrain (all True when flat).

    ``platform_xyz`` and ``target_xyz`` are 3-tuples of arrays; the terrain is called with
    (n, 3) arrays, ``terrain.line_of_sight(from_xyz, to_xyz, step_m) -> bool[n]``.
    """
    n = len(target_xyz[0])
    if getattr(terrain, "flat", False) or n == 0:
        return np.ones(n, bool)
    return np.asarray(terrain.line_of_sight(np.column_stack(platform_xyz),
                                            np.column_stack(target_xyz), step_m), bool)
