"""The GMTI tracker benchmark suite: run it, print the verdict, refresh docs/benchmark.md.

    python benchmarks/benchmark_suite.py [--quick] [--out DIR] [--trackers a,b] [--jobs 2]
                                         [--update-docs] [--figures DIR]

Runs ``gmtiflow-bench`` (every scenario of conf/experiment/challenge/ × the trackers × 10 seeds,
or 2 with ``--quick``) with its own stage cache under DIR, and prints the command, the wall and
CPU time, the machine's load before and after, and the summary table of bench_results.md.
Trackers: ``nn_kalman`` and ``nn_kalman_coast``, plus ``stonesoup_gnn``, ``stonesoup_jpda`` and
``stonesoup_gmphd`` when their configs are shipped and Stone Soup is installed.

``--no-run --extra-sweep DIR`` joins other sweeps (a scenario or trackers run on their own) to
the one in ``--out``: the verdict is built from all of them, paired by seed.
``--update-docs`` replaces the results section of docs/benchmark.md (between its
``<!-- bench-results -->`` markers) with this run's tables, command and load.  ``--figures DIR``
writes one scene picture per scenario (seed 1, from the sweep's first tracker's runs) as
``DIR/<scenario>.png``.
"""
from __future__ import annotations

import argparse
import importlib.util
import os
import re
import resource
import subprocess
import sys
import time
from datetime import datetime, timezone
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "benchmark.md"
BEGIN, END = "<!-- bench-results -->", "<!-- /bench-results -->"


def default_trackers() -> list:
    from importlib import resources
    shipped = {p.name[:-5] for p in resources.files("gmtiflow.conf").joinpath("tracker").iterdir()
               if p.name.endswith(".yaml")}
    out = ["nn_kalman", "nn_kalman_coast"]
    if importlib.util.find_spec("stonesoup") is not None:
        out += [t for t in ("stonesoup_gnn", "stonesoup_jpda", "stonesoup_gmphd") if t in shipped]
    return out


def load() -> str:
    return "load average " + " / ".join(f"{x:.1f}" for x in os.getloadavg())


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--quick", action="store_true", help="two seeds (the CI size)")
    p.add_argument("--out", type=Path, default=ROOT / "outputs" / "benchmarks" / "suite")
    p.add_argument("--trackers", default=None, help="comma-separated tracker configs")
    p.add_argument("--seeds", default=None, help="Hydra seed sweep, e.g. 'range(1,11)'")
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--update-docs", action="store_true")
    p.add_argument("--figures", type=Path, default=None)
    p.add_argument("--no-run", action="store_true",
                   help="reuse the sweep and run_info.txt an earlier run left in --out")
    p.add_argument("--extra-sweep", type=Path, action="append", default=[],
                   help="with --no-run: another sweep dir to join (e.g. a scenario or tracker "
                        "run separately); the verdict pairs all of them by seed")
    args = p.parse_args(argv)
    trackers = args.trackers or ",".join(default_trackers())
    sweep = args.out / "sweep"
    cmd = ["gmtiflow-bench", *(["--quick"] if args.quick else []), "-j", str(args.jobs),
           "-o", str(sweep), f"tracker={trackers}", f"cache.dir={args.out / 'cache'}"]
    if args.seeds:
        cmd.append(f"seed={args.seeds}")
    if args.no_run:
        return report(args, sweep, (args.out / "run_info.txt").read_text().strip(), trackers)
    before = load()
    start_utc = datetime.now(timezone.utc)
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c",
                           "from gmtiflow.bench.cli import console; console()", *cmd[1:]],
                          cwd=ROOT)
    wall = time.perf_counter() - t0
    cpu = resource.getrusage(resource.RUSAGE_CHILDREN)
    after = load()
    if proc.returncode != 0:
        print(f"gmtiflow-bench failed (exit {proc.returncode})", file=sys.stderr)
        return proc.returncode
    shown = " ".join(c if " " not in c and "(" not in c else f"'{c}'" for c in cmd)
    shown = shown.replace(str(args.out), "OUT")
    info = (f"Command: `{shown}` (via `python benchmarks/benchmark_suite.py"
            f"{' --quick' if args.quick else ''}`), {start_utc:%Y-%m-%d %H:%M} UTC, "
            f"{os.cpu_count()} cores; wall {wall:.0f} s, CPU {cpu.ru_utime + cpu.ru_stime:.0f} s; "
            f"{before} before, {after} after (a shared machine: read the times as rough).")
    (args.out / "run_info.txt").write_text(info + "\n")
    return report(args, sweep, info, trackers)


def report(args, sweep: Path, info: str, trackers: str) -> int:
    sweeps = [sweep, *args.extra_sweep]
    if args.extra_sweep:
        from gmtiflow.bench.outputs import build
        out = args.out / "combined"
        md = build(sweeps, out)["md"].read_text()
        print(f"verdict of {len(sweeps)} sweeps: {out}")
    else:
        md = (sweep / "bench_results.md").read_text()
    print(info)
    print(md)
    if args.figures:
        from gmtiflow.bench import collect
        from gmtiflow.bench.figures import save_scene_png
        first = trackers.split(",")[0]
        for rec in collect.collect(sweeps):
            if rec.ok and rec.seed == 1 and rec.tracker == first:
                print(save_scene_png(rec.dir / "run.h5", rec.scenario,
                                     args.figures / f"{rec.scenario}.png"))
    if args.update_docs:
        body = md.split("\n", 1)[1].replace("\n## ", "\n### ").strip()
        block = f"{BEGIN}\n{info}\n\n{body}\n{END}"
        text = DOC.read_text()
        if BEGIN not in text or END not in text:
            print(f"{DOC}: no {BEGIN} ... {END} section to replace", file=sys.stderr)
            return 1
        DOC.write_text(re.sub(re.escape(BEGIN) + ".*?" + re.escape(END), lambda m: block, text,
                              flags=re.S))
        print(f"updated {DOC}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
