"""Measurement errors of a detection (paper eq. 12-17 with DESIGN §5.5's floors).

.. math::

    \\sigma_\\phi = \\max\\big(\\gamma_\\phi\\,\\mathrm{BW}/\\sqrt{\\mathrm{SNR}},\\;
                              \\kappa_\\phi\\,\\mathrm{BW}/10\\big), \\quad
    \\sigma_r = \\max\\big(\\gamma_r\\,\\Delta r/\\sqrt{\\mathrm{SNR}},\\;
                         \\kappa_r\\,\\Delta r/10\\big),

    \\sigma_{\\dot r} = \\max\\big(\\gamma_{\\dot r}\\,\\Delta f_D/\\sqrt{\\mathrm{SNR}},\\;
                              \\kappa_{\\dot r}\\,\\Delta f_D/10\\big)\\,\\lambda/2,

Δr = k c/(2B), Δf_D = k_D/CPI, BW the beam's (broadened) 3-dB width in angle at its scan angle.
The paper prints ``min`` in eq. 14 and 17; its text (accuracy bounded for strong targets) means a
floor, hence ``max``.  Each σ is also capped at its resolution cell over √12 (Δr/√12, BW/√12,
λΔf_D/(2√12)): a detection places the return in the cell that crossed the threshold, whose
uniform spread has that σ, and the 1/√SNR law (a high-SNR bound) says nothing beyond it.  The cap
binds only below SNR (γ√12)² (7.8 dB in range and range rate, 3.7 dB in azimuth with the default
γ's), i.e. for detections at P_FA ≳ 1e-3 or false alarms; it keeps σ finite and bounded for any
P_FA in (0, 1) (a reported SNR of 1e-12 would otherwise give σ_r = 2e6 m).  SNR is the detection's reported (fluctuated) SNR: accuracy follows the
energy actually received, and a tracker that recomputes σ from the reported SNR gets the
simulator's σ back.

Errors are zero-mean Gaussian, one draw per (dwell, target) pair and quantity from
:func:`gmtiflow.rng.pair_normal` with its own counter key, so they do not depend on which other
targets exist.
"""
from __future__ import annotations

import numpy as np

from gmtiflow import rng
from gmtiflow.sensor.config import SensorConfig
from gmtiflow.sensor.snr import SNR_MIN

_INV_SQRT12 = 1.0 / np.sqrt(12.0)   # σ of a uniform spread over one cell, in cells


def sigmas(cfg: SensorConfig, snr, beamwidth_rad):
    """(σ_range_m, σ_azimuth_rad, σ_range_rate_mps) for linear SNRs and beamwidths (rad)."""
    inv = 1.0 / np.sqrt(np.maximum(np.asarray(snr, float), SNR_MIN))
    bw = np.asarray(beamwidth_rad, float)
    dr = cfg.range_resolution_m
    dfd = cfg.doppler_cell_hz
    s_az = np.minimum(np.maximum(cfg.gamma_az * bw * inv, cfg.kappa_az * bw / 10.0),
                      bw * _INV_SQRT12)
    s_r = np.minimum(np.maximum(cfg.gamma_r * dr * inv, cfg.kappa_r * dr / 10.0),
                     dr * _INV_SQRT12)
    s_rr = np.minimum(np.maximum(cfg.gamma_rr * dfd * inv, cfg.kappa_rr * dfd / 10.0),
                      dfd * _INV_SQRT12) * cfg.wavelength_m / 2
    return s_r, s_az, s_rr


def world_azimuth_sigma(sigma_scan_rad, azimuth_rate):
    """σ of the reported *world* azimuth (rad) from the antenna-frame σ_az of :func:`sigmas`:
    the error is drawn on the antenna's scan angle α, and the report's world azimuth A moves by
    it over dα/dA (:func:`gmtiflow.sensor.antenna.azimuth_rate` at the report's line of sight),
    so σ_A = σ_α / |dα/dA| (σ_α itself for a level antenna)."""
    rate = np.maximum(np.abs(np.asarray(azimuth_rate, float)), 1e-12)
    return np.asarray(sigma_scan_rad, float) / rate


def draw_errors(seed: int, dwell_id, vehicle_id, s_r, s_az, s_rr, *, counters=None):
    """Zero-mean Gaussian (range, azimuth, range-rate) errors for each pair.

    ``counters``: the pairs' :class:`gmtiflow.rng.Counters` when the caller has them mixed
    already (the same draws; ``dwell_id`` and ``vehicle_id`` are then not read)."""
    c = rng.Counters(dwell_id, vehicle_id) if counters is None else counters
    e_r = s_r * c.normal(rng.counter_key(seed, "sensor", "error_range"))
    e_az = s_az * c.normal(rng.counter_key(seed, "sensor", "error_azimuth"))
    e_rr = s_rr * c.normal(rng.counter_key(seed, "sensor", "error_range_rate"))
    return e_r, e_az, e_rr
