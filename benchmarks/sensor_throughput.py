"""Throughput of the GMTI sensor stage: (dwell, target) pairs and detections per second.

Scene: the default sensor preset (conf/sensor/default.yaml), a platform flying west at 200 m/s,
6 km up, 30 km south of an 8 km x 8 km scene (passing broadside at mid-run), vehicles driving
straight lines at 5-25 m/s in random directions (a self-contained fake fleet: the benchmark
measures the sensor stage, not the truth model), flat terrain.

    PYTHONPATH=. python benchmarks/sensor_throughput.py [--vehicles 100 10000] [--duration 60]
                                                         [--workers 1 2] [--repeat 5]

Wall-clock and CPU times are the best of ``--repeat`` runs (CPU time sums all threads; it is
the steadier figure on a shared machine).  "pairs" are the (dwell, target) pairs whose
geometry is evaluated exactly (the candidates of the footprint search, ~2 per vehicle and
revisit here); "looks" the /looks rows kept; the coarse once-per-revisit pass over every
vehicle is included in the time but not counted.
"""
from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np
from omegaconf import OmegaConf

from gmtiflow import frames
from gmtiflow.sensor.config import SensorConfig
from gmtiflow.sensor.model import simulate

CONF = Path(__file__).resolve().parents[1] / "conf" / "sensor" / "default.yaml"


class LineFleet:
    """Vehicles on straight lines at constant velocity, always active."""

    def __init__(self, n: int, seed: int = 0, extent_m: float = 8_000.0):
        g = np.random.default_rng(seed)
        self.p0 = g.uniform(-extent_m / 2, extent_m / 2, (n, 2))
        hd = g.uniform(0, 2 * np.pi, n)
        sp = g.uniform(5.0, 25.0, n)
        self.v = np.column_stack([np.sin(hd) * sp, np.cos(hd) * sp])
        self.heading = np.mod(hd, 2 * np.pi)
        self.vehicles = {"vehicle_id": np.arange(n, dtype=np.int64),
                         "vehicle_type": np.array(["car", "truck"] * (n // 2) + ["car"] * (n % 2))}

    def state_at(self, time_s, vehicle_id):
        t, vid = np.broadcast_arrays(np.asarray(time_s, float), np.asarray(vehicle_id))
        x = self.p0[vid, 0] + self.v[vid, 0] * t
        y = self.p0[vid, 1] + self.v[vid, 1] * t
        zero = np.zeros(t.shape)
        return {"x_m": x, "y_m": y, "z_m": zero, "vx_mps": self.v[vid, 0],
                "vy_mps": self.v[vid, 1], "vz_mps": zero, "heading_rad": self.heading[vid],
                "invisible": np.zeros(t.shape, bool), "active": np.ones(t.shape, bool),
                "vehicle_id": vid}


class StraightPlatform:
    def __init__(self, duration_s: float, speed_mps: float = 200.0):
        self.x0 = 0.5 * duration_s * speed_mps
        self.speed = speed_mps

    def state_at(self, time_s):
        t = np.atleast_1d(np.asarray(time_s, float))
        n = t.size
        return {"x_m": self.x0 - self.speed * t, "y_m": np.full(n, -30_000.0),
                "z_m": np.full(n, 6_000.0), "vx_mps": np.full(n, -self.speed),
                "vy_mps": np.zeros(n), "vz_mps": np.zeros(n),
                "heading_rad": np.full(n, 1.5 * math.pi), "pitch_rad": np.zeros(n),
                "bank_rad": np.zeros(n)}


class FlatTerrain:
    flat = True

    def height_at(self, x_m, y_m):
        return np.zeros(np.broadcast(np.asarray(x_m), np.asarray(y_m)).shape)

    def line_of_sight(self, from_xyz, to_xyz, step_m=30.0):
        return np.ones(len(to_xyz), bool)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--vehicles", type=int, nargs="+", default=[100, 10_000])
    ap.add_argument("--duration", type=float, default=60.0, help="scene seconds")
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--repeat", type=int, default=5, help="runs per case; the best is shown")
    ap.add_argument("--mode", default="dwell_resolved", choices=["dwell_resolved", "instant_scan"])
    args = ap.parse_args()

    cfg = OmegaConf.to_object(OmegaConf.merge(OmegaConf.structured(SensorConfig),
                                              OmegaConf.load(CONF)))
    origin = frames.Origin(48.0, 11.0, 0.0)
    platform = StraightPlatform(args.duration)
    print(f"sensor preset default ({args.mode}), {args.duration:g} s scene, "
          f"revisit {cfg.revisit_s:g} s, best of {args.repeat}")
    print(f"{'vehicles':>9} {'workers':>7} {'pairs':>9} {'looks':>9} {'dets':>8} {'wall s':>8} "
          f"{'pairs/s':>10} {'looks/s':>10} {'dets/s':>10} {'cpu s':>8} {'pairs/cpu-s':>11}")
    for n in args.vehicles:
        fleet = LineFleet(n)
        for w in args.workers:
            best, cpu, stats, out = math.inf, math.inf, {}, None
            for _ in range(args.repeat):
                stats = {}
                t0, c0 = time.perf_counter(), time.process_time()
                out = simulate(cfg, fleet, platform, FlatTerrain(), 1, args.duration, origin,
                               workers=w, stats=stats, dwell_mode=args.mode)
                best = min(best, time.perf_counter() - t0)
                cpu = min(cpu, time.process_time() - c0)
            pairs = stats["pairs_evaluated"]
            looks = len(out["looks"]["dwell_id"])
            dets = len(out["detections"]["det_id"])
            print(f"{n:>9} {w:>7} {pairs:>9} {looks:>9} {dets:>8} {best:>8.3f} "
                  f"{pairs / best:>10.3g} {looks / best:>10.3g} {dets / best:>10.3g} "
                  f"{cpu:>8.3f} {pairs / cpu:>11.3g}")


if __name__ == "__main__":
    main()
