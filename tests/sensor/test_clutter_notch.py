"""mdv_mps: auto (the main-lobe clutter spread) and no_stap's main-lobe clutter (issue 12 §5)."""
import math

import numpy as np
import pytest

from gmtiflow.sensor import gain, scan
from gmtiflow.sensor.config import SensorConfig
from gmtiflow.sensor.outcome import Outcome
from sensor_fakes import RADIUS_M, LevelPlatform, LineFleet, ground_angles, run, still

# The platform flies at 6 km: its states hold map rates, its true speed is (R + z)/R faster
# (gmtiflow.sensor.geometry.true_velocity), and the clutter spread follows the true speed.
TRUE_PER_MAP = 1.0 + 6000.0 / RADIUS_M


@pytest.mark.parametrize("speed, aperture", [(200.0, 1.2), (100.0, 1.2), (200.0, 0.6),
                                             (0.0, 1.2), (300.0, 1.2)])
def test_auto_mdv_is_half_the_main_beam_clutter_spread(speed, aperture):
    """Side-looking, level: ½ v_p cos(el) k λ / d_a at every scan angle (el of the range
    window's middle, v_p the true speed): 2.44 m/s for the default at 200 m/s, ∝ speed,
    ∝ 1/aperture.  (Before 2026-11-28 the map rate: 0.094 % less at 6 km.)"""
    cfg = SensorConfig(mdv_mps="auto", aperture_m=aperture)
    assert cfg.problems() == []
    plat = LevelPlatform(speed_mps=speed)
    out = run(cfg, still([[0.0, 0.0]]), platform=plat)
    d = out["dwells"]
    r_mid = 0.5 * (cfg.range_min_m + cfg.range_max_m)
    cos_el = math.cos(ground_angles(6000.0, slant_m=r_mid)[1])     # round earth
    expected = 0.5 * speed * TRUE_PER_MAP * cos_el * cfg.beamwidth_sine
    assert np.allclose(d["mdv_mps"], expected, rtol=1e-7, atol=1e-12)
    if speed == 200.0 and aperture == 1.2:
        assert 2.4 < d["mdv_mps"][0] < 2.5


def test_auto_mdv_with_a_squinted_antenna_depends_on_the_scan_angle():
    """Mounted 45° forward: the spread is v_p sin(θ_v) … with θ_v the beam's angle to the
    velocity, so it varies across the scan (the formula is evaluated per dwell)."""
    cfg = SensorConfig(mdv_mps="auto", mount_deg=45.0, az_min_deg=-30, az_max_deg=30,
                       el_min_deg=-60, range_min_m=9000, range_max_m=15000)
    out = run(cfg, still([[0.0, 0.0]]), platform=LevelPlatform(speed_mps=200.0))
    m = out["dwells"]["mdv_mps"]
    assert np.ptp(m) > 0.1 * m.max()
    # the beam nearest the velocity (most negative scan angle, 15° off the nose) spreads least
    assert np.argmin(m) == 0


def test_auto_mdv_sweeps_with_platform_speed_end_to_end():
    """A slow radial mover (own radial speed 2 m/s) is in the notch of a 300 m/s platform's
    auto MDV (3.7 m/s) and out of that of a 50 m/s platform (0.6 m/s)."""
    fleet = LineFleet([[0.0, 0.0, 0.0]] * 40, [0.0, 2.0, 0.0])
    blind = {}
    for speed in (50.0, 300.0):
        cfg = SensorConfig(mdv_mps="auto")
        lk = run(cfg, fleet, platform=LevelPlatform(speed_mps=speed), duration_s=30.0)["looks"]
        drawn = np.isin(lk["outcome"], [Outcome.DETECTED, Outcome.DOPPLER_BLIND, Outcome.PD_MISS])
        blind[speed] = np.mean(lk["outcome"][drawn] == Outcome.DOPPLER_BLIND)
    assert blind[50.0] == 0.0 and blind[300.0] > 0.5


def test_no_stap_keeps_main_lobe_clutter():
    """Without STAP, targets inside the main-lobe clutter band (centred on the beam centre's
    clutter, half-width the spread to the first nulls v_p cos(el) k λ/d_a = 4.9 m/s) are lost;
    radial movers outside it are seen; mdv_mps 0 is the paper's clutter-free case."""
    cfg = SensorConfig(stap=False, mdv_mps="auto")
    out = run(cfg, still([[0.0, 0.0]] * 20), duration_s=20.0)
    d = out["dwells"]
    expected = (200.0 * TRUE_PER_MAP * math.cos(ground_angles(6000.0, slant_m=28000.0)[1])
                * cfg.beamwidth_sine)
    assert np.allclose(d["mdv_mps"], expected, rtol=1e-7)
    lk = out["looks"]
    seen = lk["outcome"] != Outcome.OUTSIDE_FOV
    assert seen.sum() > 20 and np.all(lk["outcome"][seen] == Outcome.DOPPLER_BLIND)
    movers = LineFleet([[0.0, 0.0, 0.0]] * 20, [0.0, 10.0, 0.0])
    lk = run(cfg, movers, duration_s=20.0)["looks"]
    seen = lk["outcome"] != Outcome.OUTSIDE_FOV
    assert not np.any(lk["outcome"] == Outcome.DOPPLER_BLIND)
    assert np.mean(lk["outcome"][seen] == Outcome.DETECTED) > 0.3
    clean = run(SensorConfig(stap=False, mdv_mps=0.0), still([[0.0, 0.0]] * 20),
                duration_s=20.0)["looks"]
    assert np.any(clean["outcome"] == Outcome.DETECTED)
    assert not np.any(clean["outcome"] == Outcome.DOPPLER_BLIND)


def test_mdv_config_values():
    assert [p.key for p in SensorConfig(mdv_mps="fast").problems()] == ["mdv_mps"]
    assert SensorConfig(mdv_mps="auto").problems() == []
    assert gain.stap_notch(np.array([0.0, 1.0]), np.array([0.0, 1.0]))[0] == 1.0


def test_no_stap_band_is_centred_on_the_ground_at_the_beam_centre():
    """A stationary target on the ground exactly where a beam centre points has the range rate
    of the clutter there, so its offset from the beam centre's clutter is 0 and it is inside
    even a 1 cm/s band.  The band's centre was computed with the platform's map velocity while
    the target's range rate uses the true one ((R + z)/R = 1.00094 at 6 km): 0.03 m/s apart at
    a 9° scan angle and 200 m/s, outside such a band (it was detected)."""
    from gmtiflow.sensor import antenna, geolocate
    from sensor_fakes import RADIUS_M, FlatTerrain

    cfg = SensorConfig(stap=False, mdv_mps=0.01)
    plat = LevelPlatform(speed_mps=200.0)
    d = run(cfg, still([[0.0, 0.0]]), platform=plat)["dwells"]
    hits = []
    for k in (0, len(d["dwell_id"]) - 1):          # the sector's edges: |scan| ≈ 9.3°
        b, h, u = antenna.antenna_axes(d["platform_heading_rad"][k], d["platform_pitch_rad"][k],
                                       d["platform_bank_rad"][k], math.radians(cfg.mount_deg))
        pos = tuple(np.atleast_1d(d[f"platform_{c}_m"][k]) for c in "xyz")
        ground, _, _ = geolocate.geolocate(pos, np.array([28_000.0]),
                                           np.array([d["beam_scan_rad"][k]]), b, h, u,
                                           FlatTerrain(), radius_m=RADIUS_M)
        target = still([[ground[0][0], ground[1][0]]])
        lk = run(cfg, target, platform=plat)["looks"]
        hits.append(lk["outcome"][lk["dwell_id"] == d["dwell_id"][k]][0])
    assert abs(d["beam_scan_rad"][0]) > math.radians(9.0)
    assert hits == [Outcome.DOPPLER_BLIND, Outcome.DOPPLER_BLIND], hits
