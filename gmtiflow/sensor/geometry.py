"""Platform-target geometry: slant range, line of sight and range rates (DESIGN §5, step 1).

Sign convention: range rate ṙ = (v_t − v_p)·ℓ with ℓ the unit line of sight from the platform
to the target, positive when the range grows (receding).  The main-lobe clutter at the target's
position (the ground, at rest) has ṙ_MLC = −v_p·ℓ, so ṙ − ṙ_MLC = v_t·ℓ is the target's own
radial speed: zero for a stopped or tangentially moving target.
"""
from __future__ import annotations

import numpy as np

#: Ranges below this are treated as this (m): keeps R⁻⁴ and ℓ finite at R → 0.
MIN_RANGE_M = 1e-3


def line_of_sight(platform_xyz, target_xyz):
    """Slant range (m) and unit LOS (..., 3) from platform to target.

    At zero range the LOS is taken straight down (0, 0, −1) so that nothing is NaN.
    """
    d = np.asarray(target_xyz, float) - np.asarray(platform_xyz, float)
    rng = np.sqrt(np.einsum("...k,...k->...", d, d))
    safe = np.maximum(rng, MIN_RANGE_M)
    los = d / safe[..., None]
    small = rng < MIN_RANGE_M
    if np.any(small):
        los[small] = (0.0, 0.0, -1.0)
    return rng, los


def range_rate(target_v, platform_v, los):
    """ṙ = (v_t − v_p)·ℓ (m/s, + receding)."""
    dv = np.asarray(target_v, float) - np.asarray(platform_v, float)
    return np.einsum("...k,...k->...", dv, los)


def clutter_range_rate(platform_v, los):
    """ṙ_MLC = −v_p·ℓ: range rate of the stationary ground at the target (m/s)."""
    return -np.einsum("...k,...k->...", np.asarray(platform_v, float), los)
