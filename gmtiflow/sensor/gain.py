"""Antenna gains and the STAP clutter notch (paper eq. 7-10, DESIGN §5.3).

Beam convention (eq. 8-9 as corrected by DESIGN §5.3).  The beam is a Gaussian in *sine space*
u = sin(azimuth off boresight):

.. math::

    f_\\mathrm{mismatch} =
        \\exp\\Big[-\\ln 2\\,\\Big(\\frac{u_t - u_b}{\\mathrm{BW}_0/2}\\Big)^2\\Big],
    \\qquad \\mathrm{BW}_0 = k\\lambda/d_a ,

so the one-way gain is exactly ½ (−3 dB) where the target is half a beamwidth (BW₀/2 in sine
space) off the beam centre.  In angle, a sine-space width BW₀ is BW₀/cos(scan): the beam broadens
as 1/cos of the scan angle, and half a *broadened* beamwidth off centre is the half-power point to
first order.  (The paper's eq. 8 divides by the full BW, which puts −3 dB a whole beamwidth out.)

Transmit gain (eq. 7): G_t = π N cos^{3/2}(φ_b) f_mismatch with φ_b the beam's scan angle off
broadside.  Receive gain G_r = G_t, times the STAP notch when STAP is on (eq. 10).
"""
from __future__ import annotations

import math

import numpy as np

LN2 = math.log(2.0)


def mismatch(sin_target, sin_beam, beamwidth_sine):
    """One-way mismatch loss f_mismatch in (0, 1]: ½ at half a beamwidth off the beam centre."""
    x = (np.asarray(sin_target, float) - np.asarray(sin_beam, float)) / (0.5 * beamwidth_sine)
    return np.exp(-LN2 * x * x)


def scan_loss(scan_rad):
    """cos^{3/2} of the beam's scan angle off broadside (0 beyond ±90°, never NaN)."""
    c = np.maximum(np.cos(np.asarray(scan_rad, float)), 0.0)
    return c * np.sqrt(c)


def transmit_gain(n_elements: int, scan_rad, f_mismatch):
    """G_t = π N cos^{3/2}(φ_b) f_mismatch (eq. 7), linear."""
    return math.pi * n_elements * scan_loss(scan_rad) * np.asarray(f_mismatch, float)


def blind_offset(own_range_rate_mps, blind_speed_mps=None):
    """Target's own radial speed folded to the nearest blind speed (m/s).

    Without a PRF (``blind_speed_mps`` None) this is the radial speed itself; with one, the
    clutter notch repeats every λ·PRF/2, so the offset is taken modulo that into [−v_b/2, v_b/2).
    """
    v = np.asarray(own_range_rate_mps, float)
    if blind_speed_mps is None:
        return v
    return np.mod(v + 0.5 * blind_speed_mps, blind_speed_mps) - 0.5 * blind_speed_mps


def stap_notch(own_range_rate_mps, mdv_mps: float, blind_speed_mps=None):
    """STAP receive-gain factor 1 − exp(−ln2 ((ṙ − ṙ_MLC)/v_MDV)²) (eq. 10), in [0, 1).

    ``own_range_rate_mps`` is ṙ − ṙ_MLC.  Zero for a stopped or tangential target; ½ at exactly
    the MDV; repeating at the blind speeds when ``blind_speed_mps`` is given.
    """
    x = blind_offset(own_range_rate_mps, blind_speed_mps) / mdv_mps
    return -np.expm1(-LN2 * x * x)
