"""Every platform kind at the extremes issue 12 names (altitude 10 m … 20 km, speed up to
300 m/s, a platform at rest): finite states that keep their formulas."""
import math

import numpy as np
import pytest

from gmtiflow.frames import Origin
from gmtiflow.scene.platform import Platform, PlatformConfig, PlatformKind

ORIGIN = Origin(50.63, 7.13, 150.0)
T = np.random.default_rng(61).uniform(0.0, 2000.0, 4000)


def finite(state):
    return all(np.all(np.isfinite(v)) for v in state.values())


@pytest.mark.parametrize("alt_m", [10.0, 20000.0])
@pytest.mark.parametrize("speed_mps", [1.0, 300.0])
def test_fixed_wing_at_extreme_altitude_and_speed(alt_m, speed_mps):
    side = 40000.0
    lead = 0.25 * side / speed_mps            # turns start a quarter leg before each corner
    cfg = PlatformConfig(waypoints_m=[[0, 0, alt_m], [side, 0, alt_m], [side, -side, alt_m],
                                      [0, -side, alt_m]], speed_mps=speed_mps, turn_lead_s=lead)
    st = Platform(cfg, ORIGIN).state_at(T)
    assert finite(st)
    assert np.allclose(np.hypot(st["vx_mps"], st["vy_mps"]), speed_mps)
    assert np.all(st["z_m"] == alt_m) and np.all(st["vz_mps"] == 0.0)
    # eq. 3-5: r = s / tan(45°) = v t, φ = atan(v² / (r g))
    bank = math.atan(speed_mps ** 2 / (speed_mps * lead * 9.80665))
    assert np.allclose(np.abs(st["bank_rad"][st["bank_rad"] != 0]), bank)


@pytest.mark.parametrize("alt_m", [10.0, 20000.0])
def test_rotorcraft_at_300_mps_and_extreme_altitude(alt_m):
    cfg = PlatformConfig(kind=PlatformKind.rotorcraft, speed_mps=300.0, accel_mps2=5.0,
                         hover_s=[0.0, 10.0], waypoints_m=[[0, 0, alt_m], [5000, 0, alt_m]])
    p = Platform(cfg, ORIGIN)
    st = p.state_at(T)
    assert finite(st) and np.all(st["z_m"] == alt_m) and np.all(st["bank_rad"] == 0.0)
    # a 5 km leg is shorter than v²/a = 18 km: a triangle with peak √(a L) = 158 m/s
    speed = np.hypot(st["vx_mps"], st["vy_mps"])
    assert speed.max() <= math.sqrt(5.0 * 5000.0) + 1e-9
    assert p.model.leg_s[0] == pytest.approx(2.0 * math.sqrt(5000.0 / 5.0))


def test_trajectory_of_an_aircraft_at_rest(tmp_path):
    """A log that never moves (a parked or hovering aircraft): zero velocity, level, finite."""
    f = tmp_path / "parked.csv"
    f.write_text("time_s,lat_deg,lon_deg,height_m\n" + "".join(
        f"{t},50.6,7.1,160.0\n" for t in range(0, 60, 5)))
    st = Platform(PlatformConfig(kind=PlatformKind.trajectory, path=str(f)),
                  ORIGIN).state_at(np.linspace(0.0, 55.0, 111))
    assert finite(st)
    for k in ("vx_mps", "vy_mps", "vz_mps", "pitch_rad", "bank_rad"):
        assert np.allclose(st[k], 0.0, atol=1e-9), k
