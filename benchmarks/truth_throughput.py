"""Truth throughput: vehicle-seconds simulated per second of wall time.

For 10, 100 and 1,000 random vehicles over 30 simulated minutes (dt = 1 s), time
``build_fleet`` (routing + speed profiles) and ``Fleet.truth_table`` at 1 s, and print
vehicle-seconds per second (N x 1800 s / wall time) and truth rows per second, with the
machine load before and after.

    PYTHONPATH=. python benchmarks/truth_throughput.py [--map default|PATH.osm] [--repeat 3]

Target: 1,000 vehicles x 30 min in under 5 s on a 2-core machine.
"""
from __future__ import annotations

import argparse
import os
import time

import numpy as np

from gmtiflow.scene.roadmap import RoadmapConfig, RoadmapKind, load_roadmap
from gmtiflow.scene.vehicles import RandomFleetSpec, VehiclesConfig, build_fleet


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--map", default="default", help="'default' or an OSM file")
    ap.add_argument("--duration", type=float, default=1800.0, help="simulated seconds")
    ap.add_argument("--dt", type=float, default=1.0, help="profile time step (s)")
    ap.add_argument("--repeat", type=int, default=3, help="best of N runs")
    ap.add_argument("--counts", type=int, nargs="+", default=[10, 100, 1000])
    args = ap.parse_args()
    if args.map == "default":
        roadmap = load_roadmap(RoadmapConfig())
    else:
        roadmap = load_roadmap(RoadmapConfig(kind=RoadmapKind.osm, path=args.map))
    print(f"load before: {os.getloadavg()[0]:.2f} (1-min average, {os.cpu_count()} cores)")
    print(f"map {args.map}: {roadmap.n_nodes} nodes, {len(roadmap.edges['edge_id'])} edges; "
          f"{args.duration:.0f} s simulated, dt {args.dt} s, truth at 1 s, best of {args.repeat}")
    print(f"{'vehicles':>8} {'build s':>8} {'truth s':>8} {'total s':>8} {'veh-s/s':>10} "
          f"{'rows':>9} {'rows/s':>10}")
    times = np.arange(0.0, args.duration, 1.0)
    for n in args.counts:
        # Vehicles start over the first 10 minutes, with stops, so the fleet stays busy.
        cfg = VehiclesConfig(random=RandomFleetSpec(
            count=n, start_time_max_s=600.0, random_stop_rate_per_s=0.005, mean_wait_s=15.0,
            min_route_m=1000.0))
        best = None
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            fleet = build_fleet(cfg, roadmap, 1, args.duration, args.dt)
            t1 = time.perf_counter()
            truth = fleet.truth_table(times)
            t2 = time.perf_counter()
            if best is None or t2 - t0 < best[2]:
                best = (t1 - t0, t2 - t1, t2 - t0, len(truth["time_s"]))
        build, tt, total, rows = best
        print(f"{n:>8} {build:>8.3f} {tt:>8.3f} {total:>8.3f} {n * args.duration / total:>10.0f} "
              f"{rows:>9} {rows / total:>10.0f}")
    print(f"load after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
