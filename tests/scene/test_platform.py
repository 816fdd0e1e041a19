"""Platform orbit: coordinated turns against paper eq. 3-5 (DESIGN §4)."""
import math

import numpy as np
import pytest

from gmtiflow.errors import ConfigError
from gmtiflow.frames import Origin
from gmtiflow.scene.platform import G_MPS2, Platform, PlatformConfig, bank_angle_rad

ORIGIN = Origin(50.63, 7.13, 150.0)
RNG = np.random.default_rng(12)


def square(speed=150.0, lead=20.0, side=20000.0, alt=6000.0):
    return PlatformConfig(waypoints_m=[[0, 0, alt], [side, 0, alt], [side, -side, alt],
                                       [0, -side, alt]], speed_mps=speed, turn_lead_s=lead)


def sample(platform, n=40001):
    period = platform.orbit.total_m / platform.cfg.speed_mps
    return platform.state_at(np.linspace(0.0, period, n)), period


def test_bank_matches_corrected_eq5_and_eq3():
    cfg = square(speed=150.0, lead=20.0)
    p = Platform(cfg, ORIGIN)
    # All corners of this square are 90° right turns.
    expected = math.atan(150.0 * math.tan(math.pi / 4) / (20.0 * G_MPS2))
    turns = p.orbit.turn_sign != 0
    assert np.allclose(p.orbit.bank_rad[turns], expected, rtol=1e-12)
    # eq. 3 with the radius of eq. 4: r = s / tan(α/2), s = v t.
    r = 150.0 * 20.0 / math.tan(math.pi / 4)
    assert np.allclose(p.orbit.radius_m[turns], r)
    assert math.isclose(expected, math.atan(150.0 ** 2 / (r * G_MPS2)), rel_tol=1e-12)
    assert math.isclose(float(bank_angle_rad(150.0, math.pi / 2, 20.0)), expected, rel_tol=1e-12)


def test_right_turns_bank_right_and_left_turns_left():
    right = Platform(square(), ORIGIN)   # clockwise square: right turns
    assert np.all(right.orbit.bank_rad[right.orbit.turn_sign != 0] > 0)
    left = Platform(PlatformConfig(waypoints_m=list(reversed(square().waypoints_m)),
                                   turn_lead_s=20.0), ORIGIN)
    assert np.all(left.orbit.bank_rad[left.orbit.turn_sign != 0] < 0)


def test_zero_bank_on_straight_legs_and_bank_in_turns():
    p = Platform(square(), ORIGIN)
    state, _ = sample(p)
    # Heading is constant exactly where the bank is zero.
    straight = state["bank_rad"] == 0.0
    dh = np.abs(np.diff(np.unwrap(state["heading_rad"])))
    assert np.all(dh[straight[:-1] & straight[1:]] < 1e-9)
    assert np.any(~straight)
    # Turn rate in the arcs is g tan(φ) / v (coordinated turn).
    t = np.linspace(0, 1, 2)
    k = np.flatnonzero(p.orbit.turn_sign != 0)[0]
    t_mid = (p.orbit.start_s_m[k] + p.orbit.length_m[k] / 2) / p.cfg.speed_mps
    s = p.state_at(t_mid + t)
    rate = float(np.diff(np.unwrap(s["heading_rad"]))[0])
    assert math.isclose(rate, G_MPS2 * math.tan(s["bank_rad"][0]) / p.cfg.speed_mps, rel_tol=1e-9)


def test_constant_speed_and_the_loop_closes():
    p = Platform(square(), ORIGIN)
    state, period = sample(p)
    dt = period / (len(state["time_s"]) - 1)
    ground = np.hypot(np.diff(state["x_m"]), np.diff(state["y_m"])) / dt
    assert np.allclose(ground, 150.0, rtol=1e-6)
    for key in ("x_m", "y_m", "z_m", "heading_rad"):
        assert abs(state[key][0] - state[key][-1]) < 1e-6
    assert np.allclose(np.hypot(state["vx_mps"], state["vy_mps"]), 150.0)


def test_altitude_follows_waypoints_and_vertical_speed_is_its_slope():
    cfg = square()
    cfg.waypoints_m[2][2] = 8000.0
    p = Platform(cfg, ORIGIN)
    state, period = sample(p)
    assert state["z_m"].min() == pytest.approx(6000.0)
    assert state["z_m"].max() == pytest.approx(8000.0, abs=0.5)
    dz = np.gradient(state["z_m"], state["time_s"])
    # Central differences disagree with the slope only at the few samples beside a knot.
    agree = np.isclose(dz, state["vz_mps"], atol=1e-6)
    assert np.count_nonzero(~agree) <= 8
    assert np.ptp(state["vz_mps"]) > 0.1
    assert np.allclose(state["pitch_rad"], np.arctan2(state["vz_mps"], 150.0))


def test_geodetic_columns_round_trip_through_enu():
    from gmtiflow.frames import geodetic_to_enu
    p = Platform(square(), ORIGIN)
    s = p.state_at(np.array([0.0, 100.0, 500.0]))
    x, y, z = geodetic_to_enu(ORIGIN, s["lat_deg"], s["lon_deg"], s["height_m"])
    assert np.allclose([x, y, z], [s["x_m"], s["y_m"], s["z_m"]], atol=1e-6)


def test_sharp_corner_banks_towards_90_degrees_without_nan():
    # A near-reversal corner: α -> 180°, r -> 0, φ -> 90°.
    cfg = PlatformConfig(waypoints_m=[[0, 0, 5000], [20000, 0, 5000], [0, 100, 5000]],
                         speed_mps=200.0, turn_lead_s=0.2, max_bank_deg=90.0)
    p = Platform(cfg, ORIGIN)
    assert np.all(np.isfinite(p.orbit.bank_rad))
    assert np.max(np.abs(p.orbit.bank_rad)) > math.radians(89.9)
    state, _ = sample(p, 2001)
    assert all(np.all(np.isfinite(v)) for v in state.values())


@pytest.mark.parametrize("change, key", [
    (dict(speed_mps=-1.0), "speed_mps"),
    (dict(waypoints_m=[[0, 0, 1000]]), "waypoints_m"),
    (dict(waypoints_m=[[0, 0, 1000], [0, 0, 2000]]), "waypoints_m"),
    (dict(turn_lead_s=1000.0), "turn_lead_s"),
])
def test_bad_platform_config_names_the_key(change, key):
    cfg = square()
    for k, v in change.items():
        setattr(cfg, k, v)
    with pytest.raises(ConfigError, match=f"platform.{key}"):
        Platform(cfg, ORIGIN)


def test_default_orbit_is_a_30_km_circle_around_the_scene():
    """Turns that start half a leg early join into one circle (eq. 4 with s = half a leg)."""
    p = Platform(PlatformConfig(), ORIGIN)
    state, _ = sample(p, 4001)
    radius = np.hypot(state["x_m"], state["y_m"])
    assert np.allclose(radius, 30000.0, rtol=1e-4)
    expected = math.atan(150.0 ** 2 / (30000.0 * G_MPS2))
    # clockwise: right wing down, except on the 0.4 m straight bits the rounded lead leaves
    assert np.mean(np.isclose(state["bank_rad"], expected, rtol=1e-3)) > 0.99
    assert state["x_m"][0] == pytest.approx(0.0, abs=1.0) and state["y_m"][0] < 0
    assert state["heading_rad"][0] == pytest.approx(1.5 * math.pi, abs=1e-3)   # west


def test_bank_beyond_the_maximum_is_a_config_error_naming_the_waypoint():
    # 150 m/s, t = 20 s: the 90° corner at waypoint 1 banks atan(150 tan 45° / (20 g)) = 37.4°,
    # the 135° corners at waypoints 0 and 2 atan(150 tan 67.5° / (20 g)) = 61.5° > 60°,
    # waypoint 3 is no corner at all.
    cfg = PlatformConfig(waypoints_m=[[0, 0, 6000], [20000, 0, 6000], [20000, -20000, 6000],
                                      [5000, -5000, 6000]], speed_mps=150.0, turn_lead_s=20.0)
    bank = math.degrees(math.atan(150.0 * math.tan(math.radians(135.0) / 2) / (20.0 * G_MPS2)))
    assert 60.0 < bank < 62.0
    with pytest.raises(ConfigError) as err:
        Platform(cfg, ORIGIN)
    msg = str(err.value)
    assert "platform.waypoints_m[0]" in msg and "platform.waypoints_m[2]" in msg
    assert f"banks {bank:.1f}°" in msg
    assert "waypoints_m[1]" not in msg and "waypoints_m[3]" not in msg
    cfg.max_bank_deg = 62.0
    p = Platform(cfg, ORIGIN)
    assert np.degrees(np.max(np.abs(p.orbit.bank_rad))) == pytest.approx(bank, rel=1e-9)
    cfg.max_bank_deg = 0.0
    with pytest.raises(ConfigError, match="platform.max_bank_deg"):
        Platform(cfg, ORIGIN)


def climbing_square():
    """A square whose corners sit at 6, 6, 8 and 7 km: climbs, a descent and a level leg."""
    cfg = square()
    cfg.waypoints_m[2][2] = 8000.0
    cfg.waypoints_m[3][2] = 7000.0
    return Platform(cfg, ORIGIN)


def test_vertical_profile_is_the_cosine_blend_between_knots():
    """Between knots (each waypoint's altitude at the middle of its turn) the altitude is
    z0 + (z1 − z0)(1 − cos πu)/2 in path-length fraction u, so v_z = v (z1 − z0) π sin(πu) / 2L."""
    p = climbing_square()
    o = p.orbit
    v = p.cfg.speed_mps
    knots_s = o.alt_knots_s_m
    t = RNG.uniform(0.0, 3.0 * o.total_m / v, 3000)
    s = np.mod(v * t, o.total_m)
    ks = np.concatenate([knots_s - o.total_m, knots_s, knots_s + o.total_m])
    ka = np.tile(o.alt_knots_m, 3)
    i = np.searchsorted(ks, s, side="right") - 1
    length = ks[i + 1] - ks[i]
    u = (s - ks[i]) / length
    dz = ka[i + 1] - ka[i]
    st = p.state_at(t)
    assert np.allclose(st["z_m"], ka[i] + dz * (1 - np.cos(np.pi * u)) / 2, atol=1e-6)
    assert np.allclose(st["vz_mps"], v * dz * np.pi * np.sin(np.pi * u) / (2 * length),
                       atol=1e-9)
    # each waypoint's altitude is held at the middle of its turn, with v_z = 0 there
    at_knots = p.state_at(knots_s / v)
    assert np.allclose(at_knots["z_m"], o.alt_knots_m) and np.allclose(at_knots["vz_mps"], 0)


def test_vertical_speed_is_continuous_at_altitude_changes():
    p = climbing_square()
    o = p.orbit
    v = p.cfg.speed_mps
    # v_z changes by at most max|a_z| dt in dt, a_z = v² Δz π² / (2 L²) (no jump anywhere)
    lengths = np.diff(np.concatenate([o.alt_knots_s_m, [o.alt_knots_s_m[0] + o.total_m]]))
    dzs = np.abs(np.diff(np.concatenate([o.alt_knots_m, o.alt_knots_m[:1]])))
    az_max = np.max(v * v * dzs * np.pi ** 2 / (2 * lengths ** 2))
    # straddling every knot and every piece boundary by ±1 µs
    edges = np.concatenate([o.alt_knots_s_m, o.start_s_m]) / v
    before, after = p.state_at(edges - 1e-6), p.state_at(edges + 1e-6)
    assert np.max(np.abs(after["vz_mps"] - before["vz_mps"])) <= az_max * 2e-6 * 1.001 + 1e-12
    # and densely over one loop
    t = np.linspace(0.0, o.total_m / v, 200001)
    st = p.state_at(t)
    assert np.max(np.abs(np.diff(st["vz_mps"]))) <= az_max * (t[1] - t[0]) * (1 + 1e-6)
    assert np.max(np.abs(st["vz_mps"])) > 1.0


def test_velocity_is_the_derivative_of_position_at_random_instants():
    p = climbing_square()
    period = p.orbit.total_m / p.cfg.speed_mps
    t = RNG.uniform(0.0, 2.0 * period, 3000)
    h = 1e-4
    a, b, mid = p.state_at(t - h), p.state_at(t + h), p.state_at(t)
    # central differences are exact to O(h · jump in acceleration): v²/r = 150²/3000 m/s²
    for pos, vel in (("x_m", "vx_mps"), ("y_m", "vy_mps"), ("z_m", "vz_mps")):
        diff = (b[pos] - a[pos]) / (2 * h)
        assert np.max(np.abs(diff - mid[vel])) < 150.0 ** 2 / 3000.0 * h, pos


def test_fixed_wing_interface_is_a_plain_function_of_the_config():
    from gmtiflow.scene.platform import platform_states
    t = RNG.uniform(0.0, 1000.0, 50)
    a = platform_states(square(), ORIGIN, t)
    b = Platform(square(), ORIGIN).state_at(t)
    assert a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)
