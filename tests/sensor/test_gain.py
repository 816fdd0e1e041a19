"""Antenna gain, beam mismatch and the STAP notch (eq. 7-10, DESIGN §5.3)."""
import math

import numpy as np
import pytest

from gmtiflow.sensor import gain, scan
from gmtiflow.sensor.config import SensorConfig


@pytest.mark.parametrize("beam_deg", [0.0, 20.0, -45.0, 60.0])
def test_mismatch_is_exactly_half_half_a_beamwidth_off_centre_in_sine_space(beam_deg):
    bw = SensorConfig().beamwidth_sine
    u_b = math.sin(math.radians(beam_deg))
    f = gain.mismatch(np.array([u_b + bw / 2, u_b - bw / 2, u_b]), u_b, bw)
    assert f[0] == pytest.approx(0.5, rel=1e-12)
    assert f[1] == pytest.approx(0.5, rel=1e-12)
    assert f[2] == 1.0


@pytest.mark.parametrize("beam_deg", [0.0, 30.0, 50.0])
def test_beam_broadens_as_one_over_cos_in_angle(beam_deg):
    """Half a broadened beamwidth BW/cos(scan) off centre in angle is the half-power point to
    first order (exact in sine space)."""
    cfg = SensorConfig()
    beam = math.radians(beam_deg)
    half = 0.5 * scan.broadened_beamwidth_rad(cfg, beam)
    assert half == pytest.approx(0.5 * cfg.beamwidth_sine / math.cos(beam))
    f = gain.mismatch(np.sin([beam + half, beam - half]), math.sin(beam), cfg.beamwidth_sine)
    assert np.all(np.abs(f - 0.5) < 0.01)
    # one full beamwidth off: 1/16 one way
    f1 = gain.mismatch(math.sin(beam) + cfg.beamwidth_sine, math.sin(beam), cfg.beamwidth_sine)
    assert f1 == pytest.approx(1 / 16)


def test_transmit_gain_peak_and_scan_loss_without_nan():
    g = gain.transmit_gain(1000, np.radians([0.0, 60.0, 90.0, -90.0, 120.0]), 1.0)
    assert g[0] == pytest.approx(math.pi * 1000)
    assert g[1] == pytest.approx(math.pi * 1000 * 0.5 ** 1.5)
    assert np.all(np.isfinite(g)) and np.all(g[2:] >= 0) and np.all(g[2:] < 1e-20)


def test_stap_notch_zero_at_clutter_half_at_mdv_one_far_away():
    mdv = 2.0
    n = gain.stap_notch(np.array([0.0, mdv, -mdv, 30.0]), mdv)
    assert n[0] == 0.0
    assert n[1] == pytest.approx(0.5) and n[2] == pytest.approx(0.5)
    assert n[3] == pytest.approx(1.0)


def test_notch_repeats_at_blind_speeds_with_a_prf():
    cfg = SensorConfig()
    vb = cfg.blind_speed_mps
    v = np.array([vb, 2 * vb, -vb, vb + cfg.mdv_mps, vb / 2])
    n = gain.stap_notch(v, cfg.mdv_mps, vb)
    assert n[0] == pytest.approx(0.0, abs=1e-12) and n[1] == pytest.approx(0.0, abs=1e-12)
    assert n[2] == pytest.approx(0.0, abs=1e-12)
    assert n[3] == pytest.approx(0.5)
    assert n[4] == pytest.approx(1.0)
    # without a PRF the same speeds are far from the notch
    assert np.all(gain.stap_notch(v[:3], cfg.mdv_mps) > 0.999)


def test_mismatch_from_the_sine_distance_is_the_mismatch_bit_for_bit():
    g = np.random.default_rng(9)
    bw = SensorConfig().beamwidth_sine
    u_t, u_b = g.uniform(-0.3, 0.3, 100_000), g.uniform(-0.3, 0.3, 100_000)
    assert np.array_equal(gain.mismatch_off(np.abs(u_t - u_b), bw), gain.mismatch(u_t, u_b, bw))
