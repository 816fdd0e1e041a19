"""SNR: energy form of the radar equation and the reference form (DESIGN §5.3)."""
import math

import numpy as np
import pytest

from gmtiflow.sensor import snr
from gmtiflow.sensor.config import K_BOLTZMANN, SensorConfig


def test_energy_form_matches_a_hand_computation():
    cfg = SensorConfig()
    r, sigma_dbsm = 30_000.0, 10.0
    g = math.pi * cfg.n_elements
    lam = 299_792_458.0 / cfg.freq_hz
    expected = (cfg.peak_power_w * cfg.pulse_width_s * g * g * (cfg.cpi_s / cfg.pri_s) * lam ** 2
                * 10.0 / ((4 * math.pi) ** 3 * r ** 4 * K_BOLTZMANN * cfg.system_temp_k
                          * 10 ** (cfg.noise_figure_db / 10) * 10 ** (cfg.losses_db / 10)))
    got = snr.db_to_linear(snr.snr_db(cfg, r, g, g, sigma_dbsm))
    assert got == pytest.approx(expected, rel=1e-9)


def test_range_to_the_fourth_and_rcs_scaling():
    cfg = SensorConfig()
    g = math.pi * cfg.n_elements
    s = snr.snr_db(cfg, np.array([10e3, 20e3]), g, g, np.array([10.0, 13.0]))
    assert s[0] - s[1] == pytest.approx(40 * math.log10(2) - 3.0)


def test_reference_form_gives_snr0_at_r0_on_the_beam_centre():
    cfg = SensorConfig(snr_form="reference", snr0_db=17.0, r0_m=25e3, rcs0_dbsm=5.0)
    g = math.pi * cfg.n_elements
    assert snr.snr_db(cfg, 25e3, g, g, 5.0) == pytest.approx(17.0)
    assert snr.snr_db(cfg, 50e3, g / 2, g, 8.0) == pytest.approx(17.0 - 40 * math.log10(2) - 3.0
                                                                 + 3.0, abs=0.02)


def test_extremes_are_clipped_and_finite():
    cfg = SensorConfig()
    g = math.pi * cfg.n_elements
    with np.errstate(all="raise"):
        s = snr.snr_db(cfg, np.array([0.0, 1e-9, 1e12, 30e3]), np.array([g, g, g, 0.0]),
                       np.array([g, g, g, g]), 10.0)
    assert np.all(np.isfinite(s))
    assert s[0] == s[1] == pytest.approx(120.0)
    assert s[2] == pytest.approx(-120.0) and s[3] == pytest.approx(-120.0)
