"""The rotorcraft and external-trajectory platforms end to end through the CLI, and their bad
input: one clear line naming the key or file and row, non-zero exit, no run file."""
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from gmtiflow import store
from gmtiflow.frames import Origin, geodetic_to_enu
from gmtiflow.scene.trajectory import read_trajectory_csv

LOG = Path(__file__).resolve().parent / "data" / "platform_log.csv"
FAST = ["cache.enabled=false", "progress=false", "report.enabled=false", "export=none"]


def gmtiflow(tmp_path, *overrides):
    env = dict(os.environ, HYDRA_FULL_ERROR="0")
    tmp_path.mkdir(parents=True, exist_ok=True)
    cmd = [sys.executable, "-m", "gmtiflow.cli", f"hydra.run.dir={tmp_path / 'run'}", *FAST,
           *overrides]
    return subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True, env=env,
                          timeout=300)


def test_rotorcraft_preset_hovers_then_flies_and_the_radar_sees_the_town(tmp_path):
    proc = gmtiflow(tmp_path, "platform=rotorcraft", "scene.duration_s=90")
    assert proc.returncode == 0, proc.stderr
    run = tmp_path / "run" / "run.h5"
    plat = store.read_table(run, "platform")
    speed = np.hypot(plat["vx_mps"], plat["vy_mps"])
    hover = plat["time_s"] <= 30.0
    # the preset: 30 s hold at [6000, -25000, 2000], then west at 2 m/s² up to 30 m/s
    assert np.all(speed[hover] == 0.0) and np.all(plat["x_m"][hover] == 6000.0)
    assert np.allclose(speed[plat["time_s"] == 40.0], 20.0)
    assert np.allclose(speed[plat["time_s"] >= 45.0], 30.0)
    assert np.all(plat["bank_rad"] == 0.0) and np.all(plat["z_m"] == 2000.0)
    dwells = store.read_table(run, "dwells")
    assert np.array_equal(np.unique(dwells["platform_bank_rad"]), [0.0])
    # hovering, it yaws from east to west through south: the right-looking radar sees the town
    # (north) only once it heads west (18 vehicle detections in 90 s with the default seed)
    det = store.read_table(run, "detections")
    seen = det["truth_id"] >= 0
    assert np.count_nonzero(seen) >= 10 and np.min(det["time_s"][seen]) > 15.0


def test_trajectory_from_the_shipped_log_runs_end_to_end(tmp_path):
    proc = gmtiflow(tmp_path, "platform=trajectory", f"platform.path={LOG}",
                    "scene.duration_s=100")
    assert proc.returncode == 0, proc.stderr
    run = tmp_path / "run" / "run.h5"
    plat = store.read_table(run, "platform")
    log = read_trajectory_csv(LOG)
    on_log = np.isin(log["time_s"], plat["time_s"])
    rows = np.isin(plat["time_s"], log["time_s"])
    assert np.count_nonzero(rows) == 51
    assert np.allclose(plat["lat_deg"][rows], log["lat_deg"][on_log], atol=1e-11)
    assert np.allclose(plat["lon_deg"][rows], log["lon_deg"][on_log], atol=1e-11)
    assert np.allclose(plat["height_m"][rows], log["height_m"][on_log], atol=1e-6)
    origin = Origin(50.63, 7.13, 150.0)
    # the logged circle: 25 km in the origin's tangent plane (pymap3d's ENU, as written);
    # in the scene's map coordinates it is the same circle at the map distance
    import pymap3d
    e, n, _ = pymap3d.geodetic2enu(plat["lat_deg"], plat["lon_deg"], plat["height_m"],
                                   origin.lat_deg, origin.lon_deg, origin.height_m)
    assert np.allclose(np.hypot(e, n), 25000.0, atol=0.01)
    x, y, _ = geodetic_to_enu(origin, plat["lat_deg"], plat["lon_deg"], plat["height_m"])
    assert np.ptp(np.hypot(x, y)) < 2.0
    det = store.read_table(run, "detections")
    assert np.count_nonzero(det["truth_id"] >= 0) > 50


def _write(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    return path


@pytest.mark.parametrize("case", ["unsorted", "nan", "hover", "bank", "outside"])
def test_bad_platform_input_is_one_line_non_zero_exit_no_run_file(tmp_path, case):
    header = "time_s,lat_deg,lon_deg,height_m\n"
    if case == "unsorted":
        f = _write(tmp_path, "log.csv", header + "0,50.4,7.1,3000\n5,50.41,7.1,3000\n"
                   "4,50.42,7.1,3000\n")
        args, needle = ["platform=trajectory", f"platform.path={f}"], \
            f"platform.path: {f} line 4, column time_s: times must be strictly increasing"
    elif case == "nan":
        f = _write(tmp_path, "log.csv", header + "0,50.4,7.1,3000\n5,50.41,NaN,3000\n")
        args, needle = ["platform=trajectory", f"platform.path={f}"], \
            f"platform.path: {f} line 3, column lon_deg: must be finite"
    elif case == "hover":
        args, needle = ["platform=rotorcraft", "platform.hover_s=-5"], \
            "platform.hover_s: must be a finite number of seconds >= 0, got -5"
    elif case == "bank":
        args, needle = ["platform=racetrack", "platform.turn_lead_s=5"], \
            "platform.waypoints_m[0]: the coordinated turn at this waypoint (heading change " \
            "90.0°) banks 71.9°"
    else:
        args, needle = ["platform=trajectory", f"platform.path={LOG}", "scene.duration_s=210"], \
            "covers scene times 0 .. 200 s"
    proc = gmtiflow(tmp_path, *args)
    assert proc.returncode != 0
    errors = [line for line in proc.stderr.splitlines() if "ERROR" in line]
    assert len(errors) == 1 and needle in errors[0], proc.stderr
    assert "Traceback" not in proc.stderr
    assert not (tmp_path / "run" / "run.h5").exists()
    assert not list((tmp_path / "run").glob("*.h5*"))
