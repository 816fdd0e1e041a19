"""Time the run report: on the default scene and a bigger random fleet, or on a given run file.

    python benchmarks/report_time.py [--big N]            # simulate, then time the report
    python benchmarks/report_time.py --run RUN_DIR/run.h5  # e.g. issue 18's 1,000-vehicle scene

Without ``--run`` it simulates each scene once (not timed) into a temporary dir, then builds
report.pdf three times and prints the best total and the per-page seconds of the best build;
with ``--run`` it prints, per build, the wall and CPU time and every page's CPU seconds, with
the machine load (CPU time is what counts on a shared machine).
"""
from __future__ import annotations

import argparse
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

from gmtiflow import pipeline
from gmtiflow.compose import compose
from gmtiflow.report import ReportConfig
from gmtiflow.report.run_report import build_run_report
from gmtiflow.report.data import key_numbers, load_run


def make_run(out_dir: Path, overrides) -> Path:
    return pipeline.run(compose(["progress=false", *overrides]), out_dir)


def bench(name: str, overrides, repeats: int = 3) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        run = make_run(Path(tmp), overrides)
        sim = time.perf_counter() - t0
        k = key_numbers(load_run(run))
        best, pages = float("inf"), {}
        for _ in range(repeats):
            t0 = time.perf_counter()
            out = build_run_report(ReportConfig(), run, Path(tmp) / "report.pdf")
            dt = time.perf_counter() - t0
            if dt < best:
                best, pages = dt, dict(build_run_report.last_seconds)
        size = out.stat().st_size / 1e3
    print(f"{name}: {' '.join(overrides) or '(defaults)'}")
    print(f"  run: {k['vehicles']:.0f} vehicles, {k['dwells']:.0f} dwells, {k['looks']:.0f} looks, "
          f"{k['detections']:.0f} detections, {k['tracks']:.0f} tracks; simulation {sim:.1f} s")
    print(f"  report: best of {repeats} = {best:.2f} s, PDF {size:.0f} kB")
    print("  pages: " + ", ".join(f"{p} {s:.2f}" for p, s in pages.items()))


def bench_file(run: Path, repeats: int) -> None:
    """The report of an existing run file: wall and CPU (process) time, per page."""
    k = key_numbers(load_run(run))
    print(f"{run}: {k['vehicles']:.0f} vehicles, {k['detections']:.0f} detections, "
          f"{k['tracks']:.0f} tracks")
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(repeats):
            t0, c0 = time.perf_counter(), time.process_time()
            build_run_report(ReportConfig(), run, Path(tmp) / "report.pdf")
            print(f"  report: wall {time.perf_counter() - t0:.2f} s, CPU "
                  f"{time.process_time() - c0:.2f} s; pages (CPU s): " + ", ".join(
                      f"{p} {s:.2f}" for p, s in build_run_report.last_cpu_seconds.items()))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--big", type=int, default=500, help="random vehicles in the big scene (0: skip)")
    ap.add_argument("--run", type=Path, help="time the report of this existing run.h5 only "
                    "(e.g. the issue-18 1,000-vehicle scene: see docs/reports.md)")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    print(f"python {sys.version.split()[0]}, {platform.machine()}, {os.cpu_count()} cpus, "
          f"load {os.getloadavg()[0]:.1f}")
    if args.run:
        bench_file(args.run, args.repeat)
        return
    bench("default scene (300 s)", [])
    if args.big:
        bench("big scene", ["vehicles=random", f"vehicles.random.count={args.big}",
                            "clutter=urban"], repeats=1)


if __name__ == "__main__":
    main()
