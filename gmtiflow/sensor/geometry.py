"""Platform-target geometry: slant range, line of sight and range rates (DESIGN §5, step 1).

Vectors are 3-tuples of arrays ``(east, north, up)`` in the world ENU frame (metres, m/s).

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


def line_of_sight(platform_xyz, target_xyz):
    """Slant range (m) and unit LOS from platform to target.

    At zero range the LOS is taken straight down (0, 0, −1) so that nothing is NaN.
    """
    dx = np.asarray(target_xyz[0], float) - platform_xyz[0]
    dy = np.asarray(target_xyz[1], float) - platform_xyz[1]
    dz = np.asarray(target_xyz[2], float) - platform_xyz[2]
    rng = np.sqrt(dx * dx + dy * dy + dz * dz)
    inv = 1.0 / np.maximum(rng, MIN_RANGE_M)
    los = (dx * inv, dy * inv, dz * inv)
    small = rng < MIN_RANGE_M
    if np.any(small):
        los = (np.where(small, 0.0, los[0]), np.where(small, 0.0, los[1]),
               np.where(small, -1.0, los[2]))
    return rng, los


def range_rate(target_v, platform_v, los):
    """ṙ = (v_t − v_p)·ℓ (m/s, + receding)."""
    return dot(target_v, los) - dot(platform_v, los)


def clutter_range_rate(platform_v, los):
    """ṙ_MLC = −v_p·ℓ: range rate of the stationary ground at the target (m/s)."""
    return -dot(platform_v, los)
