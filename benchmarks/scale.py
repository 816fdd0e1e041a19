"""Wall time and peak memory of the simulation as scenes grow (docs/scale.md).

    python benchmarks/scale.py [--out DIR] [--quick]

What it measures: ``gmtiflow.pipeline.run`` (truth, sensor with the urban clutter, the HDF5
run file) in a fresh process per case, so the peak resident set size (``ru_maxrss``) is that
run's alone.  Off, because they are measured elsewhere: the tracker and the metrics
(``tracker=none metrics.enabled=false``), the report (``report=none``) and the text exports
(``export=none``) -- except in the last row, which keeps the default exports (all formats) as
the issue's memory goal states.  Stage cache off.  Default road map, random fleet.

Scaling rows: fixed traffic density, ``--density`` vehicles per 30 min (1,000), departures
spread uniformly over the scene but its last 5 min, for 10 min, 30 min, 1 h and 2 h.  The
log-log slopes of wall time and peak memory from 10 min to 2 h are printed (goal <= 1.1: cost
follows the traffic, not vehicles x duration).  ``--quick`` runs 10 min and 30 min only and
skips the 10,000-vehicle row.  Prints the machine load (1-min average) before and after, and
the CPU time of each run beside its wall time (on a shared machine the CPU time is the steadier
figure; the slopes are printed for both).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

COMMON = ["vehicles=random", "clutter=urban", "cache.enabled=false", "progress=false",
          "tracker=none", "metrics.enabled=false", "report=none"]


def child(out: str, overrides) -> None:
    from gmtiflow import pipeline
    from gmtiflow.compose import compose
    import logging
    stages = {}

    class StageTimes(logging.Handler):      # the runner logs "stage <name> <seconds> s"
        def emit(self, record):
            if record.msg.startswith("stage "):
                stages[record.args[0]] = round(float(record.args[1]), 3)
    log = logging.getLogger("gmtiflow.pipeline")
    log.setLevel(logging.INFO)
    log.addHandler(StageTimes())
    cfg = compose(overrides)
    start = time.perf_counter()
    cpu0 = time.process_time()
    path = pipeline.run(cfg, out)
    wall = time.perf_counter() - start
    cpu = time.process_time() - cpu0
    import h5py
    with h5py.File(path, "r") as f:
        rows = {t: int(f[t]["time_s"].shape[0]) for t in ("truth", "detections", "looks")}
    print(json.dumps({"wall_s": wall, "cpu_s": cpu, "stages": stages, "rss_mb": resource.getrusage(
        resource.RUSAGE_SELF).ru_maxrss / 1024.0, "file_mb": Path(path).stat().st_size / 2**20,
        **rows}))


def run_case(out_root: str, n: int, dur: float, exports: str) -> dict:
    ov = COMMON + [f"vehicles.random.count={n}", f"scene.duration_s={dur:g}",
                   f"vehicles.random.start_time_max_s={max(dur - 300, 0):g}",
                   f"export={exports}"]
    out = Path(out_root) / f"{n}_{dur:g}_{exports}"
    proc = subprocess.run([sys.executable, __file__, "--child", str(out), *ov],
                          capture_output=True, text=True)
    if proc.returncode:
        print(proc.stderr[-2000:], file=sys.stderr)
        raise SystemExit(f"case {n} x {dur} s failed")
    r = json.loads(proc.stdout.strip().splitlines()[-1])
    for f in out.glob("*"):     # keep the disk tidy; the figures are printed
        if f.is_file() and f.suffix in (".h5", ".4607", ".xml", ".csv", ".geojson", ".json",
                                        ".gz"):
            f.unlink(missing_ok=True)
    return r


def row(n: int, dur: float, exports: str, r: dict) -> str:
    st = " ".join(f"{k} {v:.1f}" for k, v in r["stages"].items() if v >= 0.05)
    return (f"{n:8d} {dur / 60:6.0f} m {exports:>7} {r['wall_s']:8.1f} {r['cpu_s']:8.1f} "
            f"{r['rss_mb']:8.0f} {r['truth']:11d} {r['detections']:10d} {r['looks']:9d} "
            f"{r['file_mb']:8.1f}  {st}")


def slope(x0, y0, x1, y1) -> float:
    return math.log(y1 / y0) / math.log(x1 / x0)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="outputs/benchmarks/scale")
    ap.add_argument("--quick", action="store_true",
                    help="10 and 30 min only, no 10,000-vehicle row")
    ap.add_argument("--density", type=int, default=1000, help="vehicles per 30 min")
    ap.add_argument("--no-big", action="store_true", help="skip the 10,000-vehicle row")
    ap.add_argument("--child", nargs="*", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child is not None:
        child(args.child[0], args.child[1:])
        return
    print(f"load before: {os.getloadavg()[0]:.2f} (1-min average, {os.cpu_count()} cores)")
    print(f"{'vehicles':>8} {'duration':>8} {'exports':>7} {'wall s':>8} {'CPU s':>8} "
          f"{'peak MB':>8} {'truth rows':>11} {'detections':>10} {'looks':>9} {'file MB':>8}  "
          f"CPU-bound stages (wall s)", flush=True)
    durations = [600, 1800] if args.quick else [600, 1800, 3600, 7200]
    rows = []
    for dur in durations:
        n = int(round(args.density * dur / 1800))
        r = run_case(args.out, n, dur, "none")
        rows.append((dur, r))
        print(row(n, dur, "none", r), flush=True)
    (d0, r0), (d1, r1) = rows[0], rows[-1]
    print(f"fixed density {args.density} vehicles / 30 min, {d0 / 60:.0f} min -> {d1 / 60:.0f} "
          f"min: log-log slope wall {slope(d0, r0['wall_s'], d1, r1['wall_s']):.2f}, "
          f"CPU {slope(d0, r0['cpu_s'], d1, r1['cpu_s']):.2f}, peak memory {slope(d0, r0['rss_mb'], d1, r1['rss_mb']):.2f} (goal <= 1.1)")
    if not (args.quick or args.no_big):
        n, dur = 10_000, 7200
        r = run_case(args.out, n, dur, "all")
        print(row(n, dur, "all", r), flush=True)
        print(f"10,000 vehicles x 2 h with the default exports: peak {r['rss_mb'] / 1024:.2f} GB "
              f"(goal <= 3 GB)")
    print(f"load after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
