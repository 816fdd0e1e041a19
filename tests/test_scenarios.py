"""The shipped example of docs/scenarios.md: an own scene in a --config-dir folder, with
inline roads, vehicles with stops, and points in ENU metres and in latitude/longitude."""
import subprocess
import sys
from pathlib import Path

import numpy as np
import pymap3d
import pytest

from gmtiflow import frames, schema, store

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "riverside"


@pytest.fixture(scope="module")
def riverside(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("riverside") / "run"
    proc = subprocess.run([sys.executable, "-m", "gmtiflow.cli", "--config-dir", str(EXAMPLE),
                           "experiment=riverside", f"hydra.run.dir={out}", "export=none",
                           "report.enabled=false"], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "run finished" in proc.stdout
    return out / "run.h5"


def test_latlon_nodes_are_converted_and_metres_stay_metres(riverside):
    nodes = store.read_table(riverside, "roads/nodes")
    pos = {str(n): (x, y, z) for n, x, y, z in zip(nodes["name"], nodes["x_m"], nodes["y_m"],
                                                    nodes["z_m"])}
    # map coordinates (frames): the tangent plane's x, y to millimetres 3 km out, and the
    # height above the surface through the origin (0 m: the node is at the origin's height)
    x, y, _ = pymap3d.geodetic2enu(50.6300, 7.1722, 150.0, 50.63, 7.13, 150.0)
    assert pos["east"] == pytest.approx((x, y, 0.0), abs=5e-3)
    assert 2900 < pos["east"][0] < 3100 and abs(pos["east"][1]) < 5     # ~3 km east
    assert pos["station"][1] == pytest.approx(-1000.8, abs=2.0)          # 0.009° south ≈ 1 km
    assert pos["west"][:2] == (-2000.0, 0.0) and pos["hill"] == (0.0, 2000.0, 60.0)


def test_vehicles_stop_drive_the_tunnel_and_follow_latlon_waypoints(riverside):
    truth = store.read_table(riverside, "truth")
    veh = store.read_table(riverside, "vehicles")
    vid = dict(zip([str(n) for n in veh["name"]], veh["vehicle_id"]))
    bus = truth["vehicle_id"] == vid["bus"]
    stopped = bus & (truth["mode"] == 2)
    assert stopped.any()                                        # the bus waits at its stops
    at_square = np.hypot(truth["x_m"][stopped], truth["y_m"][stopped]) < 20
    assert at_square.any()
    commuter = truth["vehicle_id"] == vid["commuter"]
    assert truth["invisible"][commuter].any()                   # through the tunnel
    tractor = truth["vehicle_id"] == vid["tractor"]
    origin = frames.Origin(50.63, 7.13, 150.0)
    wx, wy, _ = frames.point_to_enu({"lat_deg": 50.6150, "lon_deg": 7.1000}, origin)
    first = np.argmin(truth["time_s"][tractor])
    assert truth["x_m"][tractor][first] == pytest.approx(wx, abs=5.0)
    assert truth["y_m"][tractor][first] == pytest.approx(wy, abs=5.0)


def test_geodetic_points_are_validated():
    ok = {"lat_deg": 50.0, "lon_deg": 7.0}
    assert schema.point_problems("p", ok, geodetic=True) == []
    assert schema.point_problems("p", ok) != []                     # metres-only keys refuse it
    bad = schema.point_problems("nodes.x", {"lat_deg": 95.0, "lon_deg": 7.0}, geodetic=True)
    assert bad and bad[0].key == "nodes.x" and "lat_deg" in bad[0].message
    typo = schema.point_problems("nodes.x", {"lat": 50.0, "lon_deg": 7.0}, geodetic=True)
    assert typo and "lat_deg" in typo[0].message
    assert frames.point_to_enu([1.5, 2.5], frames.Origin(50, 7, 0)) == [1.5, 2.5]
