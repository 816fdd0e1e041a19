"""Line-of-sight throughput: rays per second for 30 km rays (issue 4).

Targets on the ground in the scene's centre (6 km x 6 km), the aircraft 30 km away in a random
direction at 6 km altitude (grazing ~11 deg), on the built-in hills preset and on the real SRTM
tile N43E007 (Monaco), at the suggested fidelity ray steps.

    PYTHONPATH=. python benchmarks/terrain_los.py            # 1e4 and 1e5 rays
    PYTHONPATH=. python benchmarks/terrain_los.py --rays 10000 --steps 30

The SRTM tile is looked for in $GMTIFLOW_DATA_DIR, else in shared/data beside the checkout.
"""
from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

import numpy as np
from omegaconf import OmegaConf

from gmtiflow import frames
from gmtiflow.scene import terrain as T

REPO = Path(__file__).resolve().parents[1]
ORIGIN = frames.Origin(43.7307, 7.421392, 0.0)


def terrains():
    hills = OmegaConf.to_object(OmegaConf.merge(OmegaConf.structured(T.TerrainConfig),
                                                OmegaConf.load(REPO / "conf/terrain/hills.yaml")))
    out = {"hills": T.build_terrain(hills, ORIGIN)}
    tile = Path(os.environ.get("GMTIFLOW_DATA_DIR") or REPO.parent / "shared/data") / "N43E007.hgt"
    if tile.is_file():
        t0 = time.perf_counter()
        cfg = T.TerrainConfig(kind=T.TerrainKind.srtm, paths=[str(tile)], geoid_offset_m=50.0)
        out["srtm N43E007"] = T.build_terrain(cfg, ORIGIN)
        print(f"read + void fill of {tile.name}: {time.perf_counter() - t0:.2f} s")
    else:
        print(f"{tile} absent: SRTM case skipped")
    return out


def geometry(ter, n, rng):
    tgt = np.c_[rng.uniform(-3e3, 3e3, n), rng.uniform(-3e3, 3e3, n), np.zeros(n)]
    tgt[:, 2] = ter.height_at(tgt[:, 0], tgt[:, 1])
    ang = rng.uniform(0, 2 * np.pi, n)
    air = np.c_[tgt[:, 0] + 30e3 * np.sin(ang), tgt[:, 1] + 30e3 * np.cos(ang), np.full(n, 6000.0)]
    return air, tgt


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rays", type=int, nargs="+", default=[10_000, 100_000])
    ap.add_argument("--steps", type=float, nargs="+", default=sorted(T.SUGGESTED_STEP_M.values()))
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    print(f"python {platform.python_version()}, numpy {np.__version__}, "
          f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, "
          f"load before {os.getloadavg()[0]:.2f} (1-min average)")
    print(f"{'terrain':14s} {'rays':>8s} {'step_m':>7s} {'seconds':>8s} {'rays/s':>10s} {'visible':>8s}")
    for name, ter in terrains().items():
        for n in args.rays:
            air, tgt = geometry(ter, n, np.random.default_rng(0))
            for step in args.steps:
                best = np.inf
                for _ in range(args.repeat):
                    t0 = time.perf_counter()
                    seen = ter.line_of_sight(air, tgt, step)
                    best = min(best, time.perf_counter() - t0)
                print(f"{name:14s} {n:8d} {step:7.0f} {best:8.3f} {n / best:10.0f} "
                      f"{seen.mean():8.3f}")
    print(f"load after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
