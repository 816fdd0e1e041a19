"""Wall time and peak memory of end-to-end runs for growing scenes (docs/scale.md).

    python benchmarks/scale.py [--out DIR] [--quick]

Each case runs ``gmtiflow.pipeline.run`` in a fresh process (so the peak resident set size,
``ru_maxrss``, is that run's alone) on the default road map with a random fleet
(``vehicles=random vehicles.random.count=N``, departures spread uniformly over the scene but
its last 5 min), the urban clutter, the stage cache off, and
writes the HDF5 run file.  Sizes: 100 / 1,000 / 10,000 vehicles over 30 min and 2 h.  The
scale rows run ``tracker=none metrics.enabled=false`` (the tracker and the metrics need whole
tables in memory; their cost is shown separately for 1,000 x 30 min).  10,000 vehicles x 2 h
runs ``fidelity=large`` (2 s motion steps): at the standard 0.5 s the Fleet's per-step profiles
alone would take ~11 GB.
"""
from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time
from pathlib import Path

COMMON = ["vehicles=random", "clutter=urban", "cache.enabled=false", "progress=false"]
NO_EVAL = ["tracker=none", "metrics.enabled=false"]
CASES = [  # (vehicles, duration_s, fidelity, evaluation)
    (100, 1800, "standard", False), (100, 7200, "standard", False),
    (1000, 1800, "standard", False), (1000, 7200, "standard", False),
    (10000, 1800, "standard", False), (10000, 7200, "large", False),
    (1000, 1800, "standard", True),
]


def child(out: str, overrides) -> None:
    from gmtiflow import pipeline
    from gmtiflow.compose import compose
    cfg = compose(overrides)
    start = time.perf_counter()
    path = pipeline.run(cfg, out)
    wall = time.perf_counter() - start
    import h5py
    with h5py.File(path, "r") as f:
        rows = {t: int(f[t]["time_s"].shape[0]) for t in ("truth", "detections", "looks")}
    print(json.dumps({"wall_s": wall, "rss_mb": resource.getrusage(
        resource.RUSAGE_SELF).ru_maxrss / 1024.0, "file_mb": Path(path).stat().st_size / 2**20,
        **rows}))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="outputs/benchmarks/scale")
    ap.add_argument("--quick", action="store_true", help="only the 100 and 1,000 vehicle rows")
    ap.add_argument("--child", nargs="*", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child is not None:
        child(args.child[0], args.child[1:])
        return
    print(f"{'vehicles':>8} {'duration':>8} {'fidelity':>8} {'tracker+metrics':>15} "
          f"{'wall s':>8} {'peak MB':>8} {'truth rows':>11} {'detections':>10} "
          f"{'looks':>9} {'file MB':>8}", flush=True)
    for n, dur, fid, ev in CASES:
        if args.quick and n > 1000:
            continue
        # Departures spread over the whole scene so that it stays busy for its full length.
        ov = COMMON + [f"vehicles.random.count={n}", f"scene.duration_s={dur}",
                       f"vehicles.random.start_time_max_s={dur - 300}",
                       f"fidelity={fid}"] + ([] if ev else NO_EVAL)
        out = Path(args.out) / f"{n}_{dur}_{fid}{'_eval' if ev else ''}"
        proc = subprocess.run([sys.executable, __file__, "--child", str(out), *ov],
                              capture_output=True, text=True)
        if proc.returncode:
            print(proc.stderr[-2000:], file=sys.stderr)
            raise SystemExit(f"case {n} x {dur} s failed")
        r = json.loads(proc.stdout.strip().splitlines()[-1])
        print(f"{n:8d} {dur / 60:6.0f} m {fid:>8} {'yes' if ev else 'no':>15} "
              f"{r['wall_s']:8.1f} {r['rss_mb']:8.0f} {r['truth']:11d} {r['detections']:10d} "
              f"{r['looks']:9d} {r['file_mb']:8.1f}", flush=True)
        (out / "run.h5").unlink(missing_ok=True)   # keep the disk tidy; the figures are printed
    target = "1,000 vehicles x 30 min end to end (truth, sensor with clutter, HDF5)"
    print(f"target: {target} < 15 s; 10,000 vehicles x 2 h < 4 GB peak")


if __name__ == "__main__":
    main()
