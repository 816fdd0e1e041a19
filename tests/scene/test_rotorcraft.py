"""Rotorcraft (paper §4 "UAV-copter"): hovers at waypoints, trapezoid legs, zero bank."""
import math

import numpy as np
import pytest

from gmtiflow.errors import ConfigError
from gmtiflow.frames import Origin
from gmtiflow.scene.platform import Platform, PlatformConfig, PlatformKind

ORIGIN = Origin(50.63, 7.13, 150.0)
RNG = np.random.default_rng(14)


def copter(**kw):
    args = dict(kind=PlatformKind.rotorcraft,
                waypoints_m=[[0.0, 0.0, 500.0], [3000.0, 0.0, 500.0], [3000.0, 4000.0, 900.0]],
                speed_mps=25.0, accel_mps2=2.5, hover_s=[20.0, 0.0, 45.0])
    args.update(kw)
    return Platform(PlatformConfig(**args), ORIGIN)


def leg_time(length_m, v, a):
    """Trapezoid (or triangle) leg duration, from rest to rest."""
    if length_m >= v * v / a:
        return length_m / v + v / a
    return 2.0 * math.sqrt(length_m / a)


def test_timeline_hovers_and_legs_follow_the_trapezoid():
    p = copter()
    legs = [3000.0, 4000.0, 5000.0]
    hovers = [20.0, 0.0, 45.0]
    expected = sum(hovers) + sum(leg_time(L, 25.0, 2.5) for L in legs)
    assert p.model.period_s == pytest.approx(expected, rel=1e-12)
    # At rest on waypoint 0 for its whole hover, then leaving it.
    st = p.state_at(np.linspace(0.0, 20.0, 201))
    assert np.all(st["x_m"] == 0.0) and np.all(st["y_m"] == 0.0) and np.all(st["z_m"] == 500.0)
    assert np.all(np.hypot(st["vx_mps"], st["vy_mps"]) == 0.0)
    # First leg: a = 2.5 m/s² for v/a = 10 s, then 25 m/s, braking into waypoint 1.
    t1 = 20.0 + np.array([4.0, 10.0, 60.0])
    st = p.state_at(t1)
    assert np.allclose(st["vx_mps"], [10.0, 25.0, 25.0], rtol=1e-12)
    assert np.allclose(st["x_m"][:2], [0.5 * 2.5 * 16.0, 0.5 * 2.5 * 100.0], rtol=1e-12)
    arrive = 20.0 + leg_time(3000.0, 25.0, 2.5)
    st = p.state_at([arrive - 2.0, arrive, arrive + 1e-9])
    assert st["vx_mps"][0] == pytest.approx(5.0)
    assert st["x_m"][1] == pytest.approx(3000.0) and st["vx_mps"][1] == pytest.approx(0.0)


def test_short_leg_is_a_triangle_with_peak_sqrt_aL():
    p = copter(waypoints_m=[[0, 0, 300], [100, 0, 300]], speed_mps=40.0, accel_mps2=2.0,
               hover_s=5.0)
    t = np.linspace(5.0, 5.0 + 2.0 * math.sqrt(100.0 / 2.0), 20001)
    st = p.state_at(t)
    assert np.max(st["vx_mps"]) == pytest.approx(math.sqrt(2.0 * 100.0), rel=1e-6)
    assert p.model.leg_s[0] == pytest.approx(2.0 * math.sqrt(100.0 / 2.0))


def test_velocity_is_the_derivative_of_position_at_random_instants():
    p = copter()
    t = RNG.uniform(0.0, 3.0 * p.model.period_s, 2000)
    h = 1e-4
    a, b, mid = p.state_at(t - h), p.state_at(t + h), p.state_at(t)
    for pos, vel in (("x_m", "vx_mps"), ("y_m", "vy_mps"), ("z_m", "vz_mps")):
        diff = (b[pos] - a[pos]) / (2 * h)
        # position is C¹; at a ramp's end the acceleration jumps by a, so the central
        # difference is off by at most a·h/2
        assert np.max(np.abs(diff - mid[vel])) < 2.5 * h + 1e-6, pos


def test_velocity_is_continuous_and_never_exceeds_the_cruise_speed():
    p = copter()
    t = np.linspace(0.0, p.model.period_s, 400001)
    st = p.state_at(t)
    dt = t[1] - t[0]
    for vel in ("vx_mps", "vy_mps", "vz_mps"):
        assert np.max(np.abs(np.diff(st[vel]))) <= 2.5 * dt * (1 + 1e-9) + 1e-12, vel
    speed = np.hypot(st["vx_mps"], st["vy_mps"])
    assert speed.max() == pytest.approx(25.0) and speed.max() <= 25.0 + 1e-9


def test_bank_is_zero_hovering_and_flying_and_pitch_is_the_flight_path_angle():
    p = copter()
    t = RNG.uniform(0.0, p.model.period_s, 5000)
    st = p.state_at(t)
    assert np.all(st["bank_rad"] == 0.0)
    moving = np.hypot(st["vx_mps"], st["vy_mps"]) > 1e-6
    assert np.allclose(st["pitch_rad"][moving],
                       np.arctan2(st["vz_mps"], np.hypot(st["vx_mps"], st["vy_mps"]))[moving])
    assert np.all(st["pitch_rad"][~moving & (st["z_m"] == 500.0)] == 0.0)


def test_altitude_is_linear_along_the_leg_and_vertical_speed_continuous():
    p = copter()
    start = 20.0 + leg_time(3000.0, 25.0, 2.5)        # hover 1 is 0 s: leg 1 starts here
    t = np.linspace(start, start + leg_time(4000.0, 25.0, 2.5), 5001)
    st = p.state_at(t)
    frac = (st["y_m"] - 0.0) / 4000.0
    assert np.allclose(st["z_m"], 500.0 + 400.0 * frac, atol=1e-9)
    assert st["vz_mps"][0] == 0.0 and abs(st["vz_mps"][-1]) < 1e-9
    assert np.max(st["vz_mps"]) == pytest.approx(25.0 * 0.1)


def test_heading_yaws_during_the_hover_from_arriving_to_leaving_leg():
    p = copter()
    # hover at waypoint 2 (45 s): arrives heading north (0), leaves south-west to waypoint 0
    start = p.model.start_s[4]
    st = p.state_at(np.linspace(start, start + 45.0, 46))
    leave = math.atan2(-3000.0, -4000.0) % (2 * math.pi)
    assert st["heading_rad"][0] == pytest.approx(0.0)
    assert st["heading_rad"][-1] == pytest.approx(leave)
    steps = np.diff(np.unwrap(st["heading_rad"]))
    assert np.allclose(steps, steps[0])                      # constant yaw rate
    assert abs(np.sum(steps)) <= math.pi + 1e-9              # the shorter way round
    assert np.all(st["x_m"] == 3000.0) and np.all(st["vx_mps"] == 0.0)


@pytest.mark.parametrize("hover, key", [(-1.0, "platform.hover_s"),
                                        ([10.0, -0.5, 3.0], r"platform.hover_s\[1\]"),
                                        ([10.0, 2.0], "platform.hover_s"),
                                        (float("nan"), "platform.hover_s")])
def test_bad_hover_time_names_the_key(hover, key):
    with pytest.raises(ConfigError, match=key):
        copter(hover_s=hover)
