"""Time the run report: on the default scene and a bigger random fleet, or on a given run file.

    python benchmarks/report_time.py [--big N]            # simulate, then time the report
    python benchmarks/report_time.py --run RUN_DIR/run.h5  # e.g. issue 18's 1,000-vehicle scene
    python benchmarks/report_time.py --run RUN_DIR/run.h5 --scaling   # each page linear?
    python benchmarks/report_time.py --run RUN_DIR/run.h5 --fresh     # as the pipeline's stage

Without ``--run`` it simulates each scene once (not timed) into a temporary dir, then builds
report.pdf three times and prints the best total and the per-page seconds of the best build;
with ``--run`` it prints, per build, the wall and CPU time and every page's CPU seconds, with
the machine load (CPU time is what counts on a shared machine).  With ``--fresh`` each build
runs in a new process, as the pipeline's report stage does: the import of the report modules
(matplotlib, its PDF backend) is timed apart from the build.
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


_FRESH = """
import json, sys, time
t0, c0 = time.perf_counter(), time.process_time()
from gmtiflow.report import ReportConfig
from gmtiflow.report.run_report import build_run_report
t1, c1 = time.perf_counter(), time.process_time()
build_run_report(ReportConfig(), sys.argv[1], sys.argv[2])
print(json.dumps({"import_wall": t1 - t0, "import_cpu": c1 - c0,
                  "build_wall": time.perf_counter() - t1, "build_cpu": time.process_time() - c1}))
"""


def bench_fresh(run: Path, repeats: int) -> None:
    """The report stage as the pipeline runs it: a fresh process per build (imports included)."""
    import json
    import subprocess
    import numpy as np
    got = []
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(repeats):
            res = subprocess.run([sys.executable, "-c", _FRESH, str(run), str(Path(tmp) / "r.pdf")],
                                 capture_output=True, text=True, check=True)
            r = json.loads(res.stdout.strip().splitlines()[-1])
            got.append(r)
            print(f"  import wall {r['import_wall']:.2f} s CPU {r['import_cpu']:.2f} s; build wall "
                  f"{r['build_wall']:.2f} s CPU {r['build_cpu']:.2f} s; load {os.getloadavg()[0]:.1f}")
    med = {k: float(np.median([r[k] for r in got])) for k in got[0]}
    print(f"  medians: import + build = {med['import_wall']:.2f} + {med['build_wall']:.2f} s wall, "
          f"{med['import_cpu']:.2f} + {med['build_cpu']:.2f} s CPU")


def scaling(run_path: Path, fractions=(0.25, 0.5, 1.0)) -> None:
    """Is every page linear in its data?  Builds each page on the run's first f of its time
    (every table with a time_s column cut at f × the last time; maps, vehicles and summary
    tables whole) and prints each page's CPU seconds and the log-log slope of CPU time against
    the rows the pages read (1 = linear)."""
    import io
    import math

    import numpy as np
    from matplotlib.backends.backend_pdf import PdfPages

    from gmtiflow.report.data import RunData
    from gmtiflow.report.run_report import run_figures

    full = load_run(run_path)
    t_end = max(float(np.max(t["time_s"])) for t in full.tables.values()
                if "time_s" in t and len(t["time_s"]))
    rows, cpu = [], []
    for f in fractions:
        cut = {}
        for name, t in full.tables.items():
            if "time_s" in t and len(t["time_s"]):
                keep = np.asarray(t["time_s"]) <= f * t_end
                cut[name] = {k: np.asarray(v)[keep] for k, v in t.items()}
            else:
                cut[name] = t
        run = RunData(full.path, full.attrs, full.config, cut)
        rows.append(sum(len(next(iter(t.values()), ())) for t in cut.values()))
        per_page = {}
        with PdfPages(io.BytesIO()) as pdf:
            for page, build in run_figures(run, ReportConfig()):
                c0 = time.process_time()
                pdf.savefig(build())
                per_page[page] = time.process_time() - c0
        cpu.append(per_page)
        print(f"  first {f:4.0%} of the run: {rows[-1]:>9,} rows; pages (CPU s): "
              + ", ".join(f"{p} {s:.2f}" for p, s in per_page.items()))
    span = math.log(rows[-1] / rows[0])
    print("  log-log slope of CPU time vs rows, first to last: " + ", ".join(
        f"{p} {math.log(max(cpu[-1][p], 1e-3) / max(cpu[0][p], 1e-3)) / span:.2f}"
        for p in cpu[-1]) + "  (1 = linear; < 1: fixed costs dominate)")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--big", type=int, default=500, help="random vehicles in the big scene (0: skip)")
    ap.add_argument("--run", type=Path, help="time the report of this existing run.h5 only "
                    "(e.g. the issue-18 1,000-vehicle scene: see docs/reports.md)")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--fresh", action="store_true",
                    help="with --run: a fresh process per build, imports timed apart")
    ap.add_argument("--scaling", action="store_true",
                    help="with --run: each page's CPU time on the first 25/50/100 %% of the run")
    args = ap.parse_args()
    print(f"python {sys.version.split()[0]}, {platform.machine()}, {os.cpu_count()} cpus, "
          f"load {os.getloadavg()[0]:.1f}")
    if args.run and args.scaling:
        scaling(args.run)
        return
    if args.run and args.fresh:
        bench_fresh(args.run, args.repeat)
        return
    if args.run:
        bench_file(args.run, args.repeat)
        return
    bench("default scene (300 s)", [])
    if args.big:
        bench("big scene", ["vehicles=random", f"vehicles.random.count={args.big}",
                            "clutter=urban"], repeats=1)


if __name__ == "__main__":
    main()
