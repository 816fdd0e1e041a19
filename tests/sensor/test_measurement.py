"""Measurement errors (eq. 12-17 with DESIGN §5.5's floors), checked against chi-square bounds."""
import math

import numpy as np
import pytest
from scipy import stats

from gmtiflow.sensor import measurement
from gmtiflow.sensor.config import SensorConfig

N = 20_000


def chi2_ok(x, sigma, alpha=1e-5):
    """Sum of squared normalised errors within the two-sided chi-square interval."""
    q = float(np.sum((np.asarray(x) / sigma) ** 2))
    n = np.size(x)
    return stats.chi2.ppf(alpha / 2, n) <= q <= stats.chi2.ppf(1 - alpha / 2, n)


def test_sigma_formulas_weak_target():
    cfg = SensorConfig()
    bw = 0.03
    snr = 8.0   # between the cell cap's crossover ((γ√12)², ≤ 6.1) and every floor's (≥ 19)
    s_r, s_az, s_rr = measurement.sigmas(cfg, snr, bw)
    assert s_az == pytest.approx(cfg.gamma_az * bw / math.sqrt(snr))
    assert s_r == pytest.approx(cfg.gamma_r * cfg.range_resolution_m / math.sqrt(snr))
    assert s_rr == pytest.approx(cfg.gamma_rr * (cfg.k_d / cfg.cpi_s) / math.sqrt(snr)
                                 * cfg.wavelength_m / 2)


def test_sigma_capped_at_the_cell_for_any_snr():
    """Below SNR (γ√12)² a σ is its cell over √12 (uniform in the cell): bounded and finite
    down to the SNR floor 1e-12 (a false alarm at P_FA 0.9 reports that)."""
    cfg = SensorConfig()
    bw = 0.03
    s_r, s_az, s_rr = measurement.sigmas(cfg, np.array([1e-12, 0.1, 1.0]), bw)
    assert np.allclose(s_r, cfg.range_resolution_m / math.sqrt(12))
    assert np.allclose(s_az, bw / math.sqrt(12))
    assert np.allclose(s_rr, cfg.doppler_cell_hz * cfg.wavelength_m / 2 / math.sqrt(12))
    # the crossover: just above (γ√12)² the 1/√SNR law holds again
    snr_x = (cfg.gamma_r * math.sqrt(12)) ** 2
    s_r2, _, _ = measurement.sigmas(cfg, np.array([snr_x * 1.01]), bw)
    assert s_r2[0] == pytest.approx(cfg.gamma_r * cfg.range_resolution_m / math.sqrt(snr_x * 1.01))


def test_floor_holds_for_strong_targets():
    cfg = SensorConfig()
    bw = 0.03
    s_r, s_az, s_rr = measurement.sigmas(cfg, np.array([1e6, 1e12]), bw)
    assert np.allclose(s_az, cfg.kappa_az * bw / 10)
    assert np.allclose(s_r, cfg.kappa_r * cfg.range_resolution_m / 10)
    assert np.allclose(s_rr, cfg.kappa_rr * cfg.doppler_cell_hz / 10 * cfg.wavelength_m / 2)


@pytest.mark.parametrize("snr", [5.0, 1e6])
def test_drawn_errors_have_the_stated_spread_and_zero_mean(snr):
    cfg = SensorConfig()
    s_r, s_az, s_rr = measurement.sigmas(cfg, np.full(N, snr), np.full(N, 0.025))
    d, v = np.arange(N) // 50, np.arange(N) % 50
    e_r, e_az, e_rr = measurement.draw_errors(11, d, v, s_r, s_az, s_rr)
    for e, s in ((e_r, s_r), (e_az, s_az), (e_rr, s_rr)):
        assert chi2_ok(e, s)
        assert abs(np.mean(e / s)) < 4.5 / math.sqrt(N)
    # distinct keys: the three errors are uncorrelated
    assert abs(np.corrcoef(e_r, e_az)[0, 1]) < 4.5 / math.sqrt(N)
    assert abs(np.corrcoef(e_r, e_rr)[0, 1]) < 4.5 / math.sqrt(N)
