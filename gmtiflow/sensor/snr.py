"""Mean signal-to-noise ratio of a look (DESIGN §5.3, replacing the paper's eq. 6).

Energy form (dimensionless):

.. math::

    \\mathrm{SNR} = \\frac{P_S\\,\\tau\\,G_t\\,G_r\\,G_I\\,\\lambda^2\\,\\sigma}
                         {(4\\pi)^3 R^4\\,k_B T_0\\,F\\,L}

with G_I the integration gain (CPI/PRI pulses by default).  Reference form (Table 1's SNR₀, R₀):

.. math::

    \\mathrm{SNR} = \\mathrm{SNR}_0 \\,(R_0/R)^4\\,(\\sigma/\\sigma_0)\\;
                   \\frac{G_t G_r}{(\\pi N)^2},

i.e. SNR₀ is the SNR of a σ₀ target at R₀ on the beam centre at broadside, and the pattern losses
(scan loss, mismatch, STAP notch) scale it.  Both are computed in dB and clipped to
[:data:`SNR_MIN`, :data:`SNR_MAX`] so that R → 0, zero gain or a notch never give inf/NaN.
"""
from __future__ import annotations

import math

import numpy as np

from gmtiflow.sensor.config import K_BOLTZMANN, SensorConfig
from gmtiflow.sensor.geometry import MIN_RANGE_M

SNR_MIN = 1e-12
SNR_MAX = 1e12
_DB_MIN = 10.0 * math.log10(SNR_MIN)
_DB_MAX = 10.0 * math.log10(SNR_MAX)
_TINY = 1e-300


def _db(x):
    return 10.0 * np.log10(np.maximum(np.asarray(x, float), _TINY))


def radar_equation_constant_db(cfg: SensorConfig) -> float:
    """10 log10 of P τ G_I λ² / ((4π)³ k_B T₀ F L): everything but G_t G_r σ / R⁴."""
    lam = cfg.wavelength_m
    return (10.0 * math.log10(cfg.peak_power_w * cfg.pulse_width_s * cfg.integration_gain
                              * lam * lam / ((4.0 * math.pi) ** 3 * K_BOLTZMANN
                                             * cfg.system_temp_k))
            - cfg.noise_figure_db - cfg.losses_db)


def snr_db(cfg: SensorConfig, range_m, gain_t, gain_r, rcs_dbsm):
    """Mean SNR (dB), clipped to [−120, 120] dB, by ``cfg.snr_form``.

    ``gain_t``, ``gain_r`` are linear one-way gains (G_t, G_r including the notch).
    """
    r_db = 40.0 * np.log10(np.maximum(np.asarray(range_m, float), MIN_RANGE_M))
    g_db = _db(np.asarray(gain_t, float) * np.asarray(gain_r, float))
    if cfg.snr_form == "reference":
        peak_db = 20.0 * math.log10(math.pi * cfg.n_elements)
        out = (cfg.snr0_db + 40.0 * math.log10(cfg.r0_m) - r_db
               + np.asarray(rcs_dbsm, float) - cfg.rcs0_dbsm + g_db - peak_db)
    else:
        out = radar_equation_constant_db(cfg) + g_db + np.asarray(rcs_dbsm, float) - r_db
    return np.clip(out, _DB_MIN, _DB_MAX)


def db_to_linear(x_db):
    """10^(x/10), for SNRs already clipped to a finite range."""
    return np.power(10.0, np.asarray(x_db, float) / 10.0)
