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

from gmtiflow.sensor import antenna, fastnp

LN2 = math.log(2.0)


def mismatch(sin_target, sin_beam, beamwidth_sine):
    """One-way mismatch loss f_mismatch in (0, 1]: ½ at half a beamwidth off the beam centre."""
    x = (np.asarray(sin_target, float) - np.asarray(sin_beam, float)) / (0.5 * beamwidth_sine)
    return np.exp(-LN2 * x * x)


def mismatch_off(offset_sine, beamwidth_sine):
    """:func:`mismatch` from the distance |u_t − u_b| in sine space (as the footprint test
    computes it): the same values, since (−LN2·x)·x does not see the sign of x."""
    x = np.asarray(offset_sine, float) / (0.5 * beamwidth_sine)
    return np.exp(-LN2 * x * x)


def scan_loss(scan_rad):
    """cos^{3/2} of the beam's scan angle off broadside (0 beyond ±90°, never NaN)."""
    c = np.maximum(np.cos(np.asarray(scan_rad, float)), 0.0)
    return c * np.sqrt(c)


def transmit_gain(n_elements: int, scan_rad, f_mismatch, loss=None):
    """G_t = π N cos^{3/2}(φ_b) f_mismatch (eq. 7), linear; ``loss``: :func:`scan_loss` of
    ``scan_rad`` when the caller has it (e.g. looked up per beam), which is then not read."""
    if loss is None:
        loss = scan_loss(scan_rad)
    return math.pi * n_elements * loss * np.asarray(f_mismatch, float)


def blind_offset(own_range_rate_mps, blind_speed_mps=None):
    """Target's own radial speed folded to the nearest blind speed (m/s).

    Without a PRF (``blind_speed_mps`` None) this is the radial speed itself; with one, the
    clutter notch repeats every λ·PRF/2, so the offset is taken modulo that into [−v_b/2, v_b/2).
    """
    v = np.asarray(own_range_rate_mps, float)
    if blind_speed_mps is None:
        return v
    return fastnp.mod(v + 0.5 * blind_speed_mps, blind_speed_mps) - 0.5 * blind_speed_mps


def stap_notch(own_range_rate_mps, mdv_mps: float, blind_speed_mps=None, offset=None):
    """STAP receive-gain factor 1 − exp(−ln2 ((ṙ − ṙ_MLC)/v_MDV)²) (eq. 10), in [0, 1).

    ``own_range_rate_mps`` is ṙ − ṙ_MLC.  Zero for a stopped or tangential target; ½ at exactly
    the MDV; repeating at the blind speeds when ``blind_speed_mps`` is given.  ``offset``: its
    :func:`blind_offset` when the caller has it (the first two arguments are then not read).
    """
    mdv = np.asarray(mdv_mps, float)
    off = blind_offset(own_range_rate_mps, blind_speed_mps) if offset is None else offset
    if np.all(mdv > 0):     # every notch has a width: the same values without the np.where's
        x = off / mdv
        return -np.expm1(-LN2 * x * x)
    x = off / np.where(mdv > 0, mdv, 1.0)
    return np.where(mdv > 0, -np.expm1(-LN2 * x * x), 1.0)   # width 0: no notch


def mainlobe_clutter_halfwidth_mps(platform_vel, scan_rad, el_rad, b, h, u, half_width_sine):
    """Half the spread of the clutter range rate ṙ_MLC = −v_p·ℓ across ±``half_width_sine`` in
    sine space (u = sin az) about the beam's scan angle, at elevation ``el_rad`` (m/s, per dwell;
    vectors are 3-tuples of arrays):  ½ |v_p · (ℓ(u_b + Δu) − ℓ(u_b − Δu))|.

    For a side-looking antenna in level flight ṙ_MLC = v_p cos(el) u exactly, so this is
    v_p cos(el) Δu at any scan angle: with Δu = BW₀/2 (the 3-dB beam) half the main-beam clutter
    width, ½ v_p cos(el) kλ/d_a — wider for a faster platform, a longer wavelength or a smaller
    aperture (Skolnik, *Radar Handbook*, 3rd ed., ch. 5: main-beam clutter spectral width
    Δf = 2 v_p θ_B sin θ_v / λ, θ_v the beam's angle to the velocity; in range rate Δṙ = Δf λ/2
    = v_p θ_B sin θ_v).  A squinted antenna's spread varies with the scan angle."""
    ub = np.sin(np.asarray(scan_rad, float))
    hi = np.arcsin(np.clip(ub + half_width_sine, -1.0, 1.0))
    lo = np.arcsin(np.clip(ub - half_width_sine, -1.0, 1.0))
    lp = antenna.direction(hi, el_rad, b, h, u)
    lm = antenna.direction(lo, el_rad, b, h, u)
    return 0.5 * np.abs(sum(platform_vel[k] * (lp[k] - lm[k]) for k in range(3)))


def clutter_band_gain(offset_mps, band_mps, blind_speed_mps=None, folded=None):
    """Receive-gain factor of a non-adaptive Doppler filter that rejects the main-lobe clutter
    band |Δ| < band (Δ = ṙ − ṙ_MLC of the beam centre, folded to the nearest blind speed):
    0 inside, then 1 − exp(−ln2 ((|Δ| − band)/(band/2))²) (half power half a band outside);
    1 everywhere for a band of 0 (no clutter).  ``folded``: :func:`blind_offset` of
    ``offset_mps`` when the caller has it."""
    band = np.asarray(band_mps, float)
    if folded is None:
        folded = blind_offset(offset_mps, blind_speed_mps)
    excess = np.abs(folded) - band
    x = np.maximum(excess, 0.0) / np.where(band > 0, 0.5 * band, 1.0)
    return np.where(band > 0, -np.expm1(-LN2 * x * x), 1.0)
