"""What a user waits for: the ``gmtiflow`` command on issue 18's 1,000-vehicle scene (docs/scale.md).

    python benchmarks/user_wait.py [--repeat 2] [--big] [--keep DIR] [--quick]

Scene: the default road map, sensor and platform, ``vehicles=random
vehicles.random.count=1000 scene.duration_s=1800 vehicles.random.start_time_max_s=1500
clutter=urban cache.enabled=false``.  Each case is the ``gmtiflow`` console command in a fresh
process (imports, config, the allocator setting and Hydra's run directory included), timed from
launch to exit:

* ``pipeline``: the default pipeline (tracker, metrics, every export, the PDF report);
  goal <= 20 s wall.
* ``binary``: the simulation and the binary outputs only (``tracker=none
  metrics.enabled=false report=none export=stanag4607``: run.h5 and the 4607 file); goal <= 6 s.
* ``--big`` adds ``10k x 2 h``: 10,000 vehicles over 2 h (departures until 6,900 s) with
  ``export=all`` and the tracker, metrics and report off; goal: peak memory <= 3 GB.

For every run: wall seconds, CPU seconds (user + system of the process and its threads, from
``wait4``), peak resident memory of the process, and the stage times the run logs in its
``gmtiflow.log`` (wall seconds).  Cases alternate within each repeat; the medians and the goals
are printed, with the UTC time and the 1-minute load average before and after.  ``--keep DIR``
keeps the last run directory of each case under DIR (``DIR/pipeline/run.h5`` is the 1,000-vehicle
run that ``export_throughput.py --run``, ``report_time.py --run`` and ``metrics_throughput.py
--run`` read); otherwise outputs go to a temporary directory that is removed.  ``--quick``
runs 100 vehicles over 300 s (departures until 120 s), one repeat, no goals.
"""
from __future__ import annotations

import argparse
import datetime as dt
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SCENE = ["vehicles=random", "vehicles.random.count=1000", "scene.duration_s=1800",
         "vehicles.random.start_time_max_s=1500", "clutter=urban", "cache.enabled=false",
         "progress=false"]
QUICK_SCENE = ["vehicles=random", "vehicles.random.count=100", "scene.duration_s=300",
               "vehicles.random.start_time_max_s=120", "clutter=urban", "cache.enabled=false",
               "progress=false"]
BINARY = ["tracker=none", "metrics.enabled=false", "report=none", "export=stanag4607"]
BIG = ["vehicles=random", "vehicles.random.count=10000", "scene.duration_s=7200",
       "vehicles.random.start_time_max_s=6900", "clutter=urban", "cache.enabled=false",
       "progress=false", "tracker=none", "metrics.enabled=false", "report=none", "export=all"]
#: case: (goal on what, goal value, unit)
GOALS = {"pipeline": ("wall_s", 20.0, "s wall"), "binary": ("wall_s", 6.0, "s wall"),
         "10k x 2 h": ("peak_gb", 3.0, "GB peak")}
STAGE_LINE = re.compile(r"stage (\S+)\s+([0-9.]+) s")


def stamp() -> str:
    now = dt.datetime.now(dt.timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC")
    return f"{now}, load {os.getloadavg()[0]:.2f} (1-min average, {os.cpu_count()} cores)"


def gmtiflow_command() -> list[str]:
    """The installed console script beside this interpreter, else ``python -m gmtiflow.cli``."""
    script = Path(sys.executable).with_name("gmtiflow")
    return [str(script)] if script.exists() else [sys.executable, "-m", "gmtiflow.cli"]


def run_once(overrides: list[str], run_dir: Path) -> dict:
    """One ``gmtiflow`` process: wall, CPU (user + system) and peak RSS from ``wait4``, and the
    stage times of its log."""
    if run_dir.exists():
        shutil.rmtree(run_dir)
    cmd = gmtiflow_command() + overrides + [f"hydra.run.dir={run_dir}"]
    with tempfile.TemporaryFile() as err:       # a file, not a pipe: it never fills up
        start = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=err)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - start
        proc.returncode = os.waitstatus_to_exitcode(status)     # reaped here, not by Popen
        if proc.returncode:
            err.seek(0)
            stderr = err.read().decode(errors="replace")
            raise SystemExit(f"{' '.join(cmd)} exited {proc.returncode}:\n{stderr[-3000:]}")
    stages = {}
    log = run_dir / "gmtiflow.log"
    for m in STAGE_LINE.finditer(log.read_text() if log.exists() else ""):
        stages[m.group(1)] = stages.get(m.group(1), 0.0) + float(m.group(2))
    return {"wall_s": wall, "cpu_s": usage.ru_utime + usage.ru_stime,
            "peak_gb": usage.ru_maxrss / 2**20, "stages": stages}


def show(case: str, r: dict) -> None:
    st = ", ".join(f"{k} {v:.2f}" for k, v in r["stages"].items() if v >= 0.05)
    print(f"{case:>10} {r['wall_s']:8.2f} {r['cpu_s']:8.2f} {r['peak_gb']:8.2f}   {st}",
          flush=True)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--big", action="store_true", help="also 10,000 vehicles x 2 h, export=all")
    ap.add_argument("--keep", type=Path, help="keep each case's last run directory here")
    ap.add_argument("--quick", action="store_true", help="100 vehicles x 300 s, no goals")
    args = ap.parse_args(argv)
    scene = QUICK_SCENE if args.quick else SCENE
    cases = {"pipeline": scene, "binary": scene + BINARY}
    if args.big and not args.quick:
        cases["10k x 2 h"] = BIG
    repeat = 1 if args.quick else args.repeat
    root = args.keep or Path(tempfile.mkdtemp(prefix="gmtiflow_user_wait_"))
    print(f"start {stamp()}; command: {' '.join(gmtiflow_command())} {' '.join(scene)}")
    print(f"{'case':>10} {'wall s':>8} {'CPU s':>8} {'peak GB':>8}   stages (wall s, from "
          f"gmtiflow.log)", flush=True)
    results = {case: [] for case in cases}
    try:
        for _ in range(repeat):
            for case, overrides in cases.items():
                r = run_once(overrides, root / case.replace(" ", "_"))
                results[case].append(r)
                show(case, r)
    finally:
        if args.keep is None:
            shutil.rmtree(root, ignore_errors=True)
    missed = []
    for case, runs in results.items():
        med = {k: statistics.median(r[k] for r in runs) for k in ("wall_s", "cpu_s", "peak_gb")}
        line = (f"{case}: median of {len(runs)}: {med['wall_s']:.2f} s wall, "
                f"{med['cpu_s']:.2f} s CPU, peak {med['peak_gb']:.2f} GB")
        if not args.quick:
            what, goal, unit = GOALS[case]
            met = med[what] <= goal
            missed += [] if met else [case]
            line += f" (goal <= {goal:g} {unit}: {'met' if met else 'NOT met'})"
        print(line)
    print(f"end {stamp()}")
    raise SystemExit(1 if missed else 0)


if __name__ == "__main__":
    main()
