"""External trajectory (paper §4): a CSV log interpolated consistently, never extrapolated.

``tests/data/platform_log.csv`` is a 200 s log of a known flight: a clockwise circle of radius
R = 25 km around the default town's ENU origin, v = 120 m/s, climbing 2 m/s from z = 4,000 m,
sampled every 2 s with lat/lon to 1e-9° (0.1 mm) and its attitude (heading, pitch, roll).
"""
import math
from pathlib import Path

import numpy as np
import pytest

from gmtiflow.errors import ConfigError, InputFileError
from gmtiflow.frames import Origin, geodetic_to_enu
from gmtiflow.scene.flight import G_MPS2
from gmtiflow.scene.platform import Platform, PlatformConfig, PlatformKind
from gmtiflow.scene.trajectory import read_trajectory_csv

LOG = Path(__file__).resolve().parents[1] / "data" / "platform_log.csv"
ORIGIN = Origin(50.63, 7.13, 150.0)
R_M, V_MPS, CLIMB_MPS = 25000.0, 120.0, 2.0
RNG = np.random.default_rng(4)


def circle(t):
    """The flown circle in ENU: position, velocity (start due south heading west, clockwise)."""
    w = V_MPS / R_M
    ang = -np.pi / 2 - w * t
    pos = np.stack([R_M * np.cos(ang), R_M * np.sin(ang), 4000.0 + CLIMB_MPS * t])
    vel = np.stack([R_M * w * np.sin(ang), -R_M * w * np.cos(ang), np.full_like(t, CLIMB_MPS)])
    return pos, vel


def trajectory(path=LOG, **kw):
    return Platform(PlatformConfig(kind=PlatformKind.trajectory, path=str(path), **kw), ORIGIN)


def test_shipped_log_reads_back_its_rows():
    log = read_trajectory_csv(LOG)
    assert len(log["time_s"]) == 101 and log["time_s"][-1] == 200.0
    st = trajectory().state_at(log["time_s"])
    # at the samples the spline passes through the logged positions
    x, y, z = geodetic_to_enu(ORIGIN, log["lat_deg"], log["lon_deg"], log["height_m"])
    assert np.allclose(st["x_m"], x, atol=1e-6) and np.allclose(st["z_m"], z, atol=1e-6)
    assert np.allclose(st["lat_deg"], log["lat_deg"], atol=1e-11)
    assert np.allclose(np.degrees(st["bank_rad"]), log["roll_deg"], atol=1e-9)


def mapped_circle(t, h=1e-3):
    """The circle the log was written from (in the origin's tangent plane, through pymap3d)
    in the scene's map coordinates (frames): position and its central-difference rate."""
    import pymap3d
    from gmtiflow import frames

    def at(tt):
        p, _ = circle(tt)
        return np.stack(frames.geodetic_to_enu(ORIGIN, *pymap3d.enu2geodetic(*p, *(
            ORIGIN.lat_deg, ORIGIN.lon_deg, ORIGIN.height_m))))
    return at(t), (at(t + h) - at(t - h)) / (2 * h)


def test_position_and_velocity_between_samples_match_the_flown_circle():
    t = RNG.uniform(0.0, 200.0, 2000)
    st = trajectory().state_at(t)
    pos, vel = mapped_circle(t)
    # a cubic spline through 2 s samples of a 25 km circle: error ~ v ω³ Δt⁴ / 384 ≈ 1e-9 m;
    # the log's rounding (1e-9° lat/lon, 0.1 mm heights) leaves ~0.1 mm and ~0.1 mm/s
    for k, key in enumerate(("x_m", "y_m", "z_m")):
        assert np.max(np.abs(st[key] - pos[k])) < 1e-3, key
    for k, key in enumerate(("vx_mps", "vy_mps", "vz_mps")):
        assert np.max(np.abs(st[key] - vel[k])) < 1e-3, key


def test_velocity_is_the_derivative_of_the_interpolated_position():
    p = trajectory()
    t = RNG.uniform(1e-3, 200.0 - 1e-3, 2000)
    h = 1e-4
    a, b, mid = p.state_at(t - h), p.state_at(t + h), p.state_at(t)
    for pos, vel in (("x_m", "vx_mps"), ("y_m", "vy_mps"), ("z_m", "vz_mps")):
        diff = (b[pos] - a[pos]) / (2 * h)
        assert np.max(np.abs(diff - mid[vel])) < 1e-5, pos   # C² spline: O(h²)


def test_logged_attitude_is_interpolated_and_heading_wraps_the_short_way(tmp_path):
    f = tmp_path / "wrap.csv"
    f.write_text("time_s,lat_deg,lon_deg,height_m,heading_deg,pitch_deg,roll_deg\n"
                 "0,50.4,7.1,3000,358,1,-2\n10,50.401,7.1,3000,4,3,2\n20,50.402,7.1,3000,10,3,2\n")
    st = trajectory(f).state_at([5.0, 2.5])
    assert np.degrees(st["heading_rad"]) == pytest.approx([1.0, 359.5])
    assert np.degrees(st["pitch_rad"]) == pytest.approx([2.0, 1.5])
    assert np.degrees(st["bank_rad"]) == pytest.approx([0.0, -1.0])


def test_without_attitude_columns_attitude_follows_the_velocity(tmp_path):
    rows = [r for r in LOG.read_text().splitlines() if not r.startswith("#")]
    f = tmp_path / "no_attitude.csv"
    f.write_text("\n".join(",".join(r.split(",")[:4]) for r in rows) + "\n")
    t = RNG.uniform(10.0, 190.0, 500)
    st = trajectory(f).state_at(t)
    _, vel = mapped_circle(t)
    heading = np.mod(np.arctan2(vel[0], vel[1]), 2 * np.pi)
    assert np.max(np.abs(np.angle(np.exp(1j * (st["heading_rad"] - heading))))) < 1e-6
    # pitch of the map rates (the horizontal map rate at 4 km is the ground-projected one:
    # 0.06 % below the true speed, 1e-5 rad on the pitch)
    assert np.allclose(st["pitch_rad"], np.arctan2(vel[2], np.hypot(vel[0], vel[1])), atol=1e-6)
    assert np.allclose(st["pitch_rad"], math.atan2(CLIMB_MPS, V_MPS), atol=2e-5)
    # coordinated turn, paper eq. 3: φ = atan(v² / (R g)), + right (the circle is clockwise)
    # (from the map rates: speed and radius 0.06 % below the true ones at 4 km, 4e-5 rad)
    assert np.allclose(st["bank_rad"], math.atan(V_MPS ** 2 / (R_M * G_MPS2)), atol=1e-4)


def test_time_offset_shifts_the_log_and_outside_times_are_an_error():
    p = trajectory(time_offset_s=50.0)
    assert np.allclose(p.state_at([10.0])["x_m"], trajectory().state_at([60.0])["x_m"])
    p.state_at([-50.0, 150.0])                         # the log's ends are inside
    for bad in ([150.001], [-50.5], [0.0, 400.0], [float("nan")]):
        with pytest.raises(InputFileError, match=r"platform.path: .*platform_log.csv covers "
                                                 r"scene times -50 \.\. 150 s"):
            p.state_at(bad)


@pytest.mark.parametrize("offset_s, duration_s, ok", [
    (0.0, 200.0, True), (0.0, 200.5, False), (50.0, 150.0, True), (50.0, 151.0, False),
    (-1.0, 10.0, False)])
def test_a_log_shorter_than_the_scene_is_a_config_error_naming_file_and_times(
        offset_s, duration_s, ok):
    """Checked from the config before any work (it used to surface at the platform stage):
    the message names the file, the scene times the log covers and the ones the scene needs."""
    from gmtiflow.scene.trajectory import coverage_problem
    cfg = PlatformConfig(kind=PlatformKind.trajectory, path=str(LOG), time_offset_s=offset_s)
    problem = coverage_problem(cfg, duration_s, "sensors.east.platform")
    if ok:
        assert problem is None
        return
    first, last = 0.0 - offset_s, 200.0 - offset_s
    assert f"sensors.east.platform.path: {LOG} covers scene times {first:g} .. {last:g} s" \
        in problem and f"needs 0 .. {duration_s:g} s (scene.duration_s)" in problem \
        and f"sensors.east.platform.time_offset_s = {offset_s:g}" in problem


def test_the_run_refuses_a_short_log_before_touching_the_run_directory(tmp_path):
    from gmtiflow import pipeline
    from gmtiflow.compose import compose
    cfg = compose(["platform=trajectory", f"platform.path={LOG}", "scene.duration_s=250",
                   "report=none", "export=none", "cache.enabled=false", "progress=false"])
    with pytest.raises(ConfigError, match=r"platform.path: .* covers scene times 0 \.\. 200 s "
                                          r".* scene needs 0 \.\. 250 s"):
        pipeline.run(cfg, tmp_path / "run")
    assert not (tmp_path / "run").exists()


def test_a_device_or_directory_as_trajectory_is_refused_not_read(tmp_path):
    """``platform.path=/dev/zero`` used to read without end; a directory is refused too."""
    for path in ("/dev/zero", str(tmp_path)):
        with pytest.raises(InputFileError, match="not a regular file"):
            read_trajectory_csv(path)


@pytest.mark.parametrize("body", [
    "root:$6$s3cr3t$abcdefghijklmnopqrstuvwxyz0123456789:19000:0:99999:7:::\n",
    "time_s,lat_deg,lon_deg,height_m\n0,50,7," + "9" * 5000 + "\n1,50,7,100\n",
    "time_s,lat_deg,lon_deg,height_m\n0,50,7,100\n1,50,7,s3cr3t$6$abcdefghijklmnopqrstuvwxyz\n"])
def test_trajectory_errors_never_echo_the_file(tmp_path, body):
    """A secret-like line or a 5,000-digit number is not copied into the message (and the log)
    beyond a short token that is plausibly the user's own data."""
    f = tmp_path / "log.csv"
    f.write_text(body)
    with pytest.raises(InputFileError) as info:
        read_trajectory_csv(f)
    msg = str(info.value)
    assert "s3cr3t" not in msg and "99999" not in msg and len(msg) < 300, msg


BAD_FILES = {
    "unsorted": ("time_s,lat_deg,lon_deg,height_m\n0,50,7,100\n2,50,7,100\n1,50,7,100\n",
                 r"line 4, column time_s: times must be strictly increasing, got 1 after 2"),
    "repeated": ("# note\ntime_s,lat_deg,lon_deg,height_m\n0,50,7,100\n0,50,7,101\n",
                 r"line 4, column time_s: times must be strictly increasing"),
    "nan": ("time_s,lat_deg,lon_deg,height_m\n0,50,7,100\n1,nan,7,100\n",
            r"line 3, column lat_deg: must be finite"),
    "text": ("time_s,lat_deg,lon_deg,height_m\n0,50,7,100\n1,50,seven,100\n",
             r"line 3, column lon_deg: not a number: 'seven'"),
    "missing_column": ("time_s,lat_deg,height_m\n0,50,100\n1,50,100\n",
                       r"line 1: header lacks column\(s\) lon_deg"),
    "partial_attitude": ("time_s,lat_deg,lon_deg,height_m,heading_deg\n0,50,7,1,0\n1,50,7,1,0\n",
                         r"all of heading_deg, pitch_deg, roll_deg or none"),
    "one_row": ("time_s,lat_deg,lon_deg,height_m\n0,50,7,100\n", r"at least 2 samples, got 1"),
    "short_row": ("time_s,lat_deg,lon_deg,height_m\n0,50,7,100\n1,50,7\n", r"line 3: 3 fields"),
    "latitude": ("time_s,lat_deg,lon_deg,height_m\n0,50,7,100\n1,95,7,100\n",
                 r"line 3, column lat_deg: 95 is outside \[-90, 90\]"),
    "empty": ("", r"empty trajectory file"),
}


@pytest.mark.parametrize("name", sorted(BAD_FILES))
def test_bad_trajectory_file_names_file_line_and_column(tmp_path, name):
    text, needle = BAD_FILES[name]
    f = tmp_path / f"{name}.csv"
    f.write_text(text)
    with pytest.raises(InputFileError, match=rf"platform.path: .*{name}.csv.*{needle}"):
        trajectory(f)


def test_missing_file_and_missing_path_are_named(tmp_path):
    with pytest.raises(InputFileError, match="platform.path: .*nope.csv: no such trajectory"):
        trajectory(tmp_path / "nope.csv")
    with pytest.raises(ConfigError, match="platform.path: kind=trajectory needs the CSV"):
        Platform(PlatformConfig(kind=PlatformKind.trajectory), ORIGIN)
