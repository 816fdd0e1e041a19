"""Scan schedule: beams tile the sector in sine space; dwells are back to back."""
import numpy as np
import pytest

from gmtiflow.sensor import scan
from gmtiflow.sensor.config import SensorConfig


@pytest.mark.parametrize("az_min, az_max", [(-10, 10), (-45, 45), (0, 5), (20, 20)])
def test_beams_cover_the_sector_within_half_a_spacing(az_min, az_max):
    cfg = SensorConfig(az_min_deg=az_min, az_max_deg=az_max)
    beams = scan.beam_centres_rad(cfg)
    assert len(beams) == scan.n_dwells(cfg)
    assert np.all(np.diff(beams) > 0)
    u = np.sin(np.radians(np.linspace(az_min, az_max, 2001)))
    gap = np.min(np.abs(u[:, None] - np.sin(beams)[None, :]), axis=1)
    assert gap.max() <= 0.5 * cfg.beamwidth_sine * cfg.dwell_spacing_beamwidths + 1e-12


def test_beams_spread_in_angle_towards_the_edges():
    beams = scan.beam_centres_rad(SensorConfig(az_min_deg=-60, az_max_deg=60))
    steps = np.diff(beams)
    assert steps[0] > steps[len(steps) // 2] * 1.5


def test_schedule_times_and_revisits():
    cfg = SensorConfig(revisit_s=5.0)
    s = scan.build_schedule(cfg, 12.0)
    assert s.n_revisits == 3
    t = s.dwell_time_s(np.arange(s.n_total))
    assert t[0] == pytest.approx(0.5 * cfg.cpi_s)
    assert np.allclose(np.diff(t[:s.n_dwells]), cfg.cpi_s)
    assert t[s.n_dwells] == pytest.approx(5.0 + 0.5 * cfg.cpi_s)
    assert scan.build_schedule(cfg, 0.1).n_revisits == 0


def test_instant_scan_puts_every_dwell_of_a_revisit_at_one_time():
    cfg = SensorConfig()
    s = scan.build_schedule(cfg, 20.0, "instant_scan")
    assert s.instant
    t = s.dwell_time_s(np.arange(s.n_dwells))
    assert np.all(t == t[0])
    assert t[0] == pytest.approx(0.5 * s.n_dwells * cfg.cpi_s)
