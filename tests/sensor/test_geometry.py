"""Antenna frame, range and range rates (DESIGN §5 step 1)."""
import math

import numpy as np
import pytest

from gmtiflow.sensor import antenna, geometry


def vec(*xyz):
    return tuple(np.atleast_1d(np.asarray(c, float)) for c in xyz)


def angles(target, platform=(0.0, -30_000.0, 6_000.0), heading_deg=270.0, bank_deg=0.0,
           mount_deg=90.0, pitch_deg=0.0):
    b, h, u = antenna.antenna_axes(np.radians([heading_deg]), np.radians([pitch_deg]),
                                   np.radians([bank_deg]), math.radians(mount_deg))
    # flat frame (radius None): these tests pin the angle conventions; the round earth is
    # tested in test_curved_earth.py
    _, los = geometry.line_of_sight(vec(*platform), vec(*target), None)
    az, el, s, lb = antenna.target_angles(los, b, h, u)
    return az[0], el[0], s[0], lb[0]


def test_axes_are_orthonormal_for_any_attitude():
    g = np.random.default_rng(0)
    n = 50
    b, h, u = antenna.antenna_axes(g.uniform(0, 6.3, n), g.uniform(-0.3, 0.3, n),
                                   g.uniform(-1, 1, n), 1.2)
    for a in (b, h, u):
        assert np.allclose(antenna.dot(a, a), 1.0)
    assert np.allclose(antenna.dot(b, h), 0) and np.allclose(antenna.dot(b, u), 0)
    assert np.allclose(antenna.dot(h, u), 0)


def test_right_side_looking_boresight_and_positive_azimuth_clockwise():
    # flying west, right side looks north; a target north-east is clockwise of boresight
    az, el, _, lb = angles((0.0, 0.0, 0.0))
    assert az == pytest.approx(0.0, abs=1e-12) and lb > 0
    assert el == pytest.approx(-math.atan2(6000, 30000))
    az_e, *_ = angles((3000.0, 0.0, 0.0))
    assert az_e == pytest.approx(math.atan2(3000, 30000))
    # left side-looking (mount -90): the same target is behind the antenna
    *_, lb_left = angles((0.0, 0.0, 0.0), mount_deg=-90.0)
    assert lb_left < 0


def test_bank_towards_the_antenna_raises_target_elevation_by_the_bank():
    _, el0, *_ = angles((0.0, 0.0, 0.0))
    _, el_r, *_ = angles((0.0, 0.0, 0.0), bank_deg=10.0)   # right wing down
    _, el_l, *_ = angles((0.0, 0.0, 0.0), bank_deg=-10.0)
    assert el_r - el0 == pytest.approx(math.radians(10.0), abs=1e-9)
    assert el_l - el0 == pytest.approx(math.radians(-10.0), abs=1e-9)


def test_range_rate_of_a_target_moving_straight_away_and_at_right_angles():
    p, t = vec(0.0, -30_000.0, 6_000.0), vec(0.0, 0.0, 0.0)
    rng_m, los = geometry.line_of_sight(p, t, None)       # sign conventions, flat frame
    assert rng_m[0] == pytest.approx(math.hypot(30_000, 6_000))
    still = vec(0, 0, 0)
    away = vec(0.0, 10.0, 0.0)            # north, away from the platform
    across = vec(10.0, 0.0, 0.0)          # east, at right angles to the LOS
    cos_dep = 30_000 / math.hypot(30_000, 6_000)
    assert geometry.range_rate(away, still, los)[0] == pytest.approx(10.0 * cos_dep)
    assert geometry.range_rate(across, still, los)[0] == pytest.approx(0.0, abs=1e-12)
    toward = vec(0.0, -10.0, 0.0)
    assert geometry.range_rate(toward, still, los)[0] == pytest.approx(-10.0 * cos_dep)


def test_clutter_range_rate_is_minus_platform_velocity_along_los():
    p, t = vec(0.0, -30_000.0, 6_000.0), vec(5_000.0, 0.0, 0.0)
    _, los = geometry.line_of_sight(p, t)
    vp = vec(-200.0, 0.0, 0.0)             # flying west, the target is aft (east)
    mlc = geometry.clutter_range_rate(vp, los)[0]
    assert mlc > 0                         # ground aft recedes
    # a stopped target moves exactly with the clutter
    assert geometry.range_rate(vec(0, 0, 0), vp, los)[0] == pytest.approx(mlc)


def test_zero_range_is_finite():
    with np.errstate(all="raise"):
        rng_m, los = geometry.line_of_sight(vec(1.0, 2.0, 3.0), vec(1.0, 2.0, 3.0))
    assert rng_m[0] == 0.0 and los[2][0] == -1.0
