"""Numerical stability at the extremes: no NaN/inf, no numpy floating-point warning (every check
runs under ``np.errstate(all="raise")``), and monotone where the physics is.

SNR 1e-12..1e12, P_FA down to 1e-15, ranges 1 m..1,000 km, speeds 0 and 100 m/s, grazing
angles near 0° and 90°, scan angles near ±90° (cos -> 0 in eq. 7 and 9), zero-length road
segments and duplicate nodes, motion steps 1e-3..10 s, bank angles near 90°.
"""
import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from gmtiflow.scene.platform import Platform, PlatformConfig, bank_angle_rad
from gmtiflow.scene.roadmap import RoadmapConfig, RoadSpec, load_roadmap
from gmtiflow.scene.vehicles import VehicleSpec, VehiclesConfig, build_fleet
from gmtiflow.sensor import antenna, detect, gain, geometry, measurement, scan, snr
from gmtiflow.sensor.config import SensorConfig

def raise_all():
    # Underflow to 0 is the right answer (exp(-x^2) far off the beam) and numpy never warns on
    # it by default; everything else raises.
    return np.errstate(divide="raise", over="raise", invalid="raise", under="ignore")
SNRS = np.logspace(-12, 12, 2401)
PFAS = [1e-15, 1e-12, 1e-6, 1e-2, 0.5]


def finite(*arrays):
    return all(np.all(np.isfinite(np.asarray(a, float))) for a in arrays)


@pytest.mark.parametrize("pfa", PFAS)
def test_pd_finite_bounded_monotone_in_snr(pfa):
    with raise_all():
        p = detect.pd(SNRS, pfa)
        lp = detect.log_pd(SNRS, pfa)
    assert finite(p, lp)
    assert np.all((p >= pfa * (1 - 1e-12)) & (p <= 1.0))
    assert np.all(np.diff(p) >= 0) and np.all(np.diff(lp) >= 0)
    assert p[0] == pytest.approx(pfa, rel=1e-9)          # SNR -> 0: P_D -> P_FA
    assert p[-1] == pytest.approx(1.0, abs=1e-10)         # SNR huge: certain
    assert lp[-1] < 0 or lp[-1] == 0


@settings(max_examples=200, derandomize=True, deadline=None)
@given(u=st.floats(2.0 ** -54, 1 - 2.0 ** -53), snr_db=st.floats(-120, 120),
       pfa=st.sampled_from(PFAS))
def test_detection_draw_and_reported_snr_finite(u, snr_db, pfa):
    s = 10.0 ** (snr_db / 10.0)
    with raise_all():
        hit = detect.detected(u, s, pfa)
        rep = detect.reported_snr(u, s)
        sr, saz, srr = measurement.sigmas(SensorConfig(), rep, 0.025)
    assert finite(rep, sr, saz, srr)
    assert rep > 0
    # Higher SNR never turns a detection into a miss for the same uniform (CRN monotonicity).
    with raise_all():
        assert (not hit) or detect.detected(u, s * 10, pfa)


def test_snr_finite_and_monotone_in_range():
    cfg = SensorConfig().normalised()
    ranges = np.logspace(0, 6, 601)          # 1 m .. 1,000 km
    with raise_all():
        for form in ("radar_equation", "reference"):
            c = SensorConfig(snr_form=form).normalised()
            s = snr.snr_db(c, ranges, 3000.0, 3000.0, 10.0)
            assert finite(s)
            assert np.all(np.diff(s) <= 0)
        # zero gain (scan at 90°, deep notch) and zero range: clipped, finite
        s0 = snr.snr_db(cfg, np.array([0.0, 1e-9, 1e9]), np.array([0.0, 1.0, 0.0]),
                        np.array([0.0, 1.0, 1e-300]), np.array([-50.0, 60.0, 10.0]))
    assert finite(s0) and s0.min() >= -120 and s0.max() <= 120


def test_gain_near_scan_limits_and_off_centre():
    scan_rad = np.deg2rad(np.concatenate([np.linspace(-90, 90, 3601),
                                          [-90 - 1e-9, 90 + 1e-9, 89.999999, -89.999999]]))
    cfg = SensorConfig().normalised()
    with raise_all():
        loss = gain.scan_loss(scan_rad)
        g = gain.transmit_gain(cfg.n_elements, scan_rad, 1.0)
        bw = scan.broadened_beamwidth_rad(cfg, scan_rad)
        sr, saz, srr = measurement.sigmas(cfg, np.array(1e-12), bw)
    assert finite(loss, g, bw, sr, saz, srr)
    assert np.all((loss >= 0) & (loss <= 1))
    half = np.deg2rad(np.linspace(0, 90, 901))
    assert np.all(np.diff(gain.scan_loss(half)) <= 0)    # monotone off broadside
    assert np.all(np.diff(scan.broadened_beamwidth_rad(cfg, half)) >= 0)
    # Off-centre: gain falls monotonically with distance from the beam centre; ½ at half a BW.
    off = np.linspace(0, 5 * cfg.beamwidth_sine, 1001)
    with raise_all():
        m = gain.mismatch(off, 0.0, cfg.beamwidth_sine)
    assert finite(m) and np.all(np.diff(m) <= 0) and m[0] == 1.0
    assert gain.mismatch(cfg.beamwidth_sine / 2, 0.0, cfg.beamwidth_sine) == pytest.approx(0.5)


@pytest.mark.parametrize("speed", [0.0, 1e-9, 2.0, 30.0, 59.999, 60.0, 100.0])
def test_stap_notch_speeds(speed):
    cfg = SensorConfig().normalised()
    v = np.array([speed, -speed])
    with raise_all():
        notch = gain.stap_notch(v, cfg.mdv_mps)
        folded = gain.stap_notch(v, cfg.mdv_mps, blind_speed_mps=60.0)
    assert finite(notch, folded)
    assert np.all((notch >= 0) & (notch <= 1) & (folded >= 0) & (folded <= 1))
    if speed == 0.0:
        assert np.all(notch == 0)


def test_notch_monotone_in_radial_speed():
    v = np.linspace(0, 100, 10001)
    with raise_all():
        n = gain.stap_notch(v, 2.0)
    assert np.all(np.diff(n) >= 0)


@settings(max_examples=200, derandomize=True, deadline=None)
@given(graze_deg=st.floats(0.0, 90.0), az_deg=st.floats(-90.0, 90.0),
       rng_m=st.floats(1.0, 1e6), bank_deg=st.floats(-89.9, 89.9),
       heading_deg=st.floats(0, 360))
def test_geometry_angles_finite(graze_deg, az_deg, rng_m, bank_deg, heading_deg):
    """Targets at any grazing angle (0..90°) and scan angle (±90°) from any attitude."""
    b, h, u = antenna.antenna_axes(np.deg2rad(heading_deg), 0.0, np.deg2rad(bank_deg),
                                   np.deg2rad(90.0))
    with raise_all():
        los = antenna.direction(np.deg2rad(az_deg), -np.deg2rad(graze_deg), b, h, u)
        target = tuple(rng_m * c for c in los)
        r, los2 = geometry.line_of_sight((0.0, 0.0, 0.0), target, radius_m=None)
        az, el, sin_az, cb = antenna.target_angles(los2, b, h, u)
        rr = geometry.range_rate((0.0, 0.0, 0.0), (150.0, 0.0, 0.0), los2)
        r_round, los_round = geometry.line_of_sight((0.0, 0.0, 0.0), target)
    assert finite(r, *los2, az, el, sin_az, cb, rr, r_round, *los_round)
    assert r == pytest.approx(rng_m, rel=1e-9)                 # flat: the map offset itself
    # round earth: the chord between the two points on a sphere (platform above the origin,
    # the target at arc ρ = |(x, y)| and height z), computed here independently
    radius = geometry.DEFAULT_RADIUS_M
    rho, theta = math.hypot(target[0], target[1]), math.hypot(target[0], target[1]) / radius
    t_xyz = ((radius + target[2]) * math.sin(theta), 0.0, (radius + target[2]) * math.cos(theta))
    chord = math.dist(t_xyz, (0.0, 0.0, radius))
    assert r_round == pytest.approx(chord, rel=1e-7, abs=1e-6), rho


def test_zero_range_line_of_sight():
    with raise_all():
        r, los = geometry.line_of_sight((1.0, 2.0, 3.0), (np.array([1.0]), np.array([2.0]),
                                                          np.array([3.0])))
    assert finite(r, *los) and los[2][0] == -1.0


@pytest.mark.parametrize("turn_deg", [1e-6, 90.0, 179.0, 179.999999, 180.0])
def test_bank_angles_near_90(turn_deg):
    with raise_all():
        phi = bank_angle_rad(150.0, np.deg2rad(turn_deg), 1e-3)
    assert np.isfinite(phi) and 0 <= phi <= math.pi / 2


def test_sharp_corner_orbit_is_finite():
    """A near-reversal at each corner: bank close to 90°, state finite everywhere."""
    cfg = PlatformConfig(waypoints_m=[[0, 0, 6000], [20000, 0, 6000], [0, 10, 6000]],
                         speed_mps=200.0, turn_lead_s=0.01, max_bank_deg=90.0)
    from gmtiflow.frames import Origin
    p = Platform(cfg, Origin(50.0, 7.0, 0.0))
    with raise_all():
        # the first corner is reached at 20 km / 200 m/s = 100 s; its turn lasts milliseconds
        stt = p.state_at(np.concatenate([np.linspace(0, 400, 4001),
                                         np.linspace(99.9, 100.1, 200001)]))
    for k, v in stt.items():
        if np.asarray(v).dtype.kind == "f":
            assert finite(v), k
    assert np.max(np.abs(stt["bank_rad"])) > np.deg2rad(80)


def _roads_with_degenerate_segments():
    return RoadmapConfig(kind="inline", nodes={"a": [0, 0, 0], "b": [100, 0, 0],
                                               "b2": [100, 0, 0], "c": [100, 200, 0],
                                               "d": [300, 200, 0]},
                         roads=[RoadSpec(from_node="a", to_node="b", via=[[50, 0], [50, 0]]),
                                RoadSpec(from_node="b", to_node="b2"),
                                RoadSpec(from_node="b2", to_node="c"),
                                RoadSpec(from_node="c", to_node="d")])


@pytest.mark.parametrize("dt", [1e-3, 0.1, 1.0, 10.0])
def test_fleet_on_zero_length_segments_and_duplicate_nodes(dt):
    try:
        roadmap = load_roadmap(_roads_with_degenerate_segments())
    except Exception as exc:        # a clear refusal is acceptable too
        from gmtiflow.errors import GmtiflowError
        assert isinstance(exc, GmtiflowError), exc
        pytest.skip(f"degenerate road map refused: {exc}")
    spec = VehicleSpec(name="v", start="a", end="d", cruise_speed_mps=15.0,
                       stop_points=["c"], speed_noise_mps=0.5, position_noise_m=[0.5, 0.5, 0.0])
    duration = 5.0 if dt == 1e-3 else 60.0
    with raise_all():
        fleet = build_fleet(VehiclesConfig(vehicles=[spec]), roadmap, seed=3,
                            duration_s=duration, dt_s=dt)
        t = np.linspace(0, duration, 2001)
        stt = fleet.state_at(t, np.zeros_like(t, dtype=np.int64))
    act = stt["active"]
    for k in ("x_m", "y_m", "z_m", "vx_mps", "vy_mps", "speed_mps", "heading_rad",
              "route_s_m"):
        assert finite(stt[k][act]), k
    s = stt["route_s_m"][act]
    assert np.all(np.diff(s) >= -1e-9)         # never drives backwards
    assert np.all(stt["speed_mps"][act] >= 0)


def test_extreme_dt_range_gives_consistent_distance():
    """dt from 1e-3 to 10 s: the same cruise gives the same distance (no drift, no blow-up)."""
    roadmap = load_roadmap(RoadmapConfig(kind="inline", nodes={"a": [0, 0], "b": [5000, 0]},
                                         roads=[RoadSpec(from_node="a", to_node="b")]))
    spec = VehicleSpec(name="v", start="a", end="b", cruise_speed_mps=20.0)
    out = []
    for dt in (1e-3, 0.01, 1.0, 10.0):
        with raise_all():
            fleet = build_fleet(VehiclesConfig(vehicles=[spec]), roadmap, seed=1,
                                duration_s=10.0, dt_s=dt)
            out.append(float(fleet.state_at(np.array([10.0]), np.array([0]))["route_s_m"][0]))
    assert np.allclose(out, 200.0, atol=1e-6), out


@pytest.mark.parametrize("overrides", [
    # a sector to ±89° (the config limit; (cos -> 0 in eq. 7 and 9), P_FA 1e-15, ranges 1 m .. 1,000 km, grazing
    # angles from 0° to 90°, a stop-and-go fleet with a speed of 0 at stops
    ["sensor.az_min_deg=-89.0", "sensor.az_max_deg=89.0", "sensor.pfa=1e-15",
     "sensor.range_min_m=1", "sensor.range_max_m=1e6", "sensor.pri_s=null",
     "sensor.integration_gain_db=21",
     "sensor.el_min_deg=-90", "sensor.el_max_deg=0"],
    # the platform right over the scene (grazing 90°) in a tight circle (bank ~ 80°)
    ["sensor.el_min_deg=-90", "sensor.el_max_deg=0", "sensor.range_min_m=1",
     "sensor.az_min_deg=-89.0", "sensor.az_max_deg=89.0",
     "platform.waypoints_m=[[0.0,-300.0,1000.0],[300.0,0.0,1000.0],[0.0,300.0,1000.0],[-300.0,0.0,1000.0]]",
     "platform.speed_mps=100", "platform.turn_lead_s=1.5", "platform.max_bank_deg=90",
     "fidelity=full"],
])
def test_whole_run_at_extremes_is_finite(tmp_path, overrides, compose_config):
    from gmtiflow import pipeline, store
    cfg = compose_config(["scene.duration_s=40", "tracker=none", "cache.enabled=false", "report=none",
                       *overrides])
    with raise_all():
        path = pipeline.run(cfg, tmp_path)
    det = store.read_table(path, "detections")
    looks = store.read_table(path, "looks")
    assert len(looks["dwell_id"]) > 0
    for c in ("range_m", "azimuth_rad", "range_rate_mps", "snr_db", "sigma_range_m",
              "sigma_azimuth_rad", "sigma_range_rate_mps"):
        assert finite(det[c]), c
    seen = looks["outcome"] != 1
    assert finite(looks["snr_db"][seen], looks["pd"][seen])
