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
floor, hence ``max``.  SNR is the detection's reported (fluctuated) SNR: accuracy follows the
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


def sigmas(cfg: SensorConfig, snr, beamwidth_rad):
    """(σ_range_m, σ_azimuth_rad, σ_range_rate_mps) for linear SNRs and beamwidths (rad)."""
    inv = 1.0 / np.sqrt(np.maximum(np.asarray(snr, float), SNR_MIN))
    bw = np.asarray(beamwidth_rad, float)
    dr = cfg.range_resolution_m
    dfd = cfg.doppler_cell_hz
    s_az = np.maximum(cfg.gamma_az * bw * inv, cfg.kappa_az * bw / 10.0)
    s_r = np.maximum(cfg.gamma_r * dr * inv, cfg.kappa_r * dr / 10.0)
    s_rr = np.maximum(cfg.gamma_rr * dfd * inv, cfg.kappa_rr * dfd / 10.0) * cfg.wavelength_m / 2
    return s_r, s_az, s_rr


def draw_errors(seed: int, dwell_id, vehicle_id, s_r, s_az, s_rr):
    """Zero-mean Gaussian (range, azimuth, range-rate) errors for each pair."""
    e_r = s_r * rng.pair_normal(rng.counter_key(seed, "sensor", "error_range"), dwell_id,
                                vehicle_id)
    e_az = s_az * rng.pair_normal(rng.counter_key(seed, "sensor", "error_azimuth"), dwell_id,
                                  vehicle_id)
    e_rr = s_rr * rng.pair_normal(rng.counter_key(seed, "sensor", "error_range_rate"), dwell_id,
                                  vehicle_id)
    return e_r, e_az, e_rr
