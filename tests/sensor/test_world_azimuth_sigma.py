"""sigma_azimuth_rad is the σ of the reported *world* azimuth (/detections.azimuth_rad).

The azimuth error is drawn on the antenna's scan angle; with the antenna banked or pitched its
azimuth plane is tilted, one antenna-frame radian is not one world radian, and the σ reported
beside the world azimuth must be converted (measurement.world_azimuth_sigma).  Checked here
against a numerical derivative of the antenna azimuth for targets, noise false alarms and
merged reports; the normalised errors of the targets are in test_model.py.
"""
import math
import numpy as np
import pytest

from gmtiflow.sensor import antenna, geometry, measurement, scan
from gmtiflow.sensor.config import MergeCells, MergeConfig, MergeMode, SensorConfig
from gmtiflow.sensor.effects import Merging, NoiseFalseAlarms
from gmtiflow.sensor.model import simulate
from sensor_fakes import ORIGIN, RADIUS_M, FlatTerrain, LevelPlatform, LineFleet, grid_fleet


def _turned(los, d_rad):
    """The unit LOS turned clockwise (seen from above) by d_rad about the local vertical."""
    c, s = math.cos(d_rad), math.sin(d_rad)
    return (c * los[0] + s * los[1], -s * los[0] + c * los[1], los[2])


def _numeric_rate(los, b, h, u, step=1e-6):
    """dα/dA by central differences of antenna.target_angles."""
    hi = antenna.target_angles(_turned(los, step), b, h, u)[0]
    lo = antenna.target_angles(_turned(los, -step), b, h, u)[0]
    return (hi - lo) / (2 * step)


def test_azimuth_rate_is_the_derivative_of_the_antenna_azimuth_and_one_when_level():
    g = np.random.default_rng(4)
    n = 2_000
    b, h, u = antenna.antenna_axes(g.uniform(0, 2 * np.pi, n), g.uniform(-0.2, 0.2, n),
                                   g.uniform(-0.6, 0.6, n), math.radians(90.0))
    az, el = g.uniform(-0.7, 0.7, n), g.uniform(-0.8, -0.05, n)
    los = antenna.direction(az, el, b, h, u)
    rate = antenna.azimuth_rate(los, b, h)
    assert np.allclose(rate, _numeric_rate(los, b, h, u), rtol=1e-6, atol=1e-8)
    assert rate.max() - rate.min() > 0.1                    # banks and pitches matter
    bl, hl, ul = antenna.antenna_axes(g.uniform(0, 2 * np.pi, n), 0.0, 0.0, math.radians(60.0))
    level = antenna.direction(az, el, bl, hl, ul)
    assert np.allclose(antenna.azimuth_rate(level, bl, hl), 1.0, rtol=1e-12)


def _expected_sigma(cfg, det, dw, mount_rad):
    """σ_az of measurement.sigmas over |dα/dA| at each report's ground point, numerically."""
    k = det["dwell_id"] - dw["dwell_id"][0]
    bw = scan.broadened_beamwidth_rad(cfg, dw["beam_scan_rad"][k])
    s_az = measurement.sigmas(cfg, 10 ** (det["snr_db"] / 10), bw)[1]
    b, h, u = antenna.antenna_axes(dw["platform_heading_rad"][k], dw["platform_pitch_rad"][k],
                                   dw["platform_bank_rad"][k], mount_rad)
    plat = tuple(dw[f"platform_{c}_m"][k] for c in "xyz")
    _, los = geometry.line_of_sight(plat, (det["x_m"], det["y_m"], det["z_m"]), RADIUS_M)
    return s_az / np.abs(_numeric_rate(los, b, h, u))


@pytest.mark.parametrize("bank_deg", [0.0, 12.0])
def test_targets_and_noise_false_alarms_report_the_world_azimuth_sigma(bank_deg):
    cfg = SensorConfig(stap=False, mdv_mps=0.0, el_max_deg=20.0, pfa=1e-4)
    platform = LevelPlatform(bank_deg=bank_deg)
    out = simulate(cfg, grid_fleet(400, seed=2), platform, FlatTerrain(), 5, 10.0, ORIGIN,
                   effects=[NoiseFalseAlarms(cfg, 5)])
    det, dw = out["detections"], out["dwells"]
    fa = det["truth_id"] < 0
    assert fa.sum() > 500 and (~fa).sum() > 200
    want = _expected_sigma(cfg, det, dw, math.radians(cfg.mount_deg))
    assert np.allclose(det["sigma_azimuth_rad"], want, rtol=1e-5)
    if bank_deg:    # the conversion is not a no-op here: σ_world differs from σ_antenna
        k = det["dwell_id"] - dw["dwell_id"][0]
        bw = scan.broadened_beamwidth_rad(cfg, dw["beam_scan_rad"][k])
        s_ant = measurement.sigmas(cfg, 10 ** (det["snr_db"] / 10), bw)[1]
        assert np.min(det["sigma_azimuth_rad"] / s_ant) > 1.01


def test_merged_reports_report_the_world_azimuth_sigma():
    """Pairs of targets a few metres apart (one range-azimuth cell) seen from a hovering, banked
    platform: the merged report's σ follows its summed SNR and its own ground point."""
    cfg = SensorConfig(merge=MergeConfig(mode=MergeMode.threshold,
                                         cells=MergeCells("range_azimuth")), el_max_deg=20.0)
    y = np.repeat(np.arange(-1500.0, 1500.0, 100.0), 2)
    p0 = np.column_stack([np.zeros_like(y), y, np.zeros_like(y)])
    v = np.zeros_like(p0)
    v[:, 1] = np.tile([8.0, 9.5], len(y) // 2)
    platform = LevelPlatform(speed_mps=0.0, bank_deg=12.0)
    out = simulate(cfg, LineFleet(p0, v), platform, FlatTerrain(), 2,
                   scan.n_dwells(cfg) * cfg.cpi_s, ORIGIN, effects=[Merging(cfg, 2, iterate=False)])
    det, dw = out["detections"], out["dwells"]
    m = det["merged"]
    assert m.sum() >= 10
    want = _expected_sigma(cfg, det, dw, math.radians(cfg.mount_deg))
    assert np.allclose(det["sigma_azimuth_rad"][m], want[m], rtol=1e-5)
