"""Start-up time of the ``gmtiflow`` command (issue 18: ``--help`` and a config error ≤ 1.5 s).

Runs, in fresh processes, ``gmtiflow --help``, a typo in a config group option
(``sensor=nosuch``), an unknown key (``sensor.nosuch=1``) and a value out of range
(``sensor.peak_power_w=-1``), each ``--repeat`` times, alternating, and prints the median and
best wall time of each and its CPU time (user + sys: what the wall time would be on an idle
core) with the machine load.  Only what a user waits for: process start,
imports, Hydra's composition and the error message.

    python benchmarks/startup_time.py [--repeat 5] [--against CHECKOUT]

``--against`` alternates every case with the same command run from another checkout of the
repository (its ``gmtiflow`` package first on ``PYTHONPATH``; the installed entry point and
config are shared), for a before/after ratio measured under the same load.
"""
from __future__ import annotations

import argparse
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

CASES = {
    "--help": ["--help"],
    "unknown option sensor=nosuch": ["sensor=nosuch"],
    "unknown key sensor.nosuch=1": ["sensor.nosuch=1"],
    "range error sensor.peak_power_w=-1": ["sensor.peak_power_w=-1"],
}


def gmtiflow_command() -> list:
    exe = Path(sys.executable).with_name("gmtiflow")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "gmtiflow.cli"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--against", metavar="CHECKOUT",
                    help="also time another checkout of the repository, alternating")
    args = ap.parse_args()
    cmd = gmtiflow_command()
    variants = {"this": dict(os.environ)}
    if args.against:
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(Path(args.against).resolve()),
                                                          env.get("PYTHONPATH")]))
        variants[f"against {args.against}"] = env
    times = {(v, k): [] for v in variants for k in CASES}
    cpu = {key: [] for key in times}
    load0 = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(args.repeat):
            for name, extra in CASES.items():
                for variant, env in variants.items():
                    t0 = time.perf_counter()
                    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
                    p = subprocess.run(cmd + extra + [f"hydra.run.dir={tmp}/run"], cwd=tmp,
                                       capture_output=True, text=True, env=env)
                    times[variant, name].append(time.perf_counter() - t0)
                    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
                    cpu[variant, name].append(r1.ru_utime + r1.ru_stime
                                              - r0.ru_utime - r0.ru_stime)
                    want_ok = name == "--help"
                    if (p.returncode == 0) != want_ok:
                        sys.exit(f"{variant} {name}: unexpected exit status {p.returncode}\n"
                                 f"{p.stderr[-2000:]}")
                    shutil.rmtree(f"{tmp}/run", ignore_errors=True)
    print(f"load average {load0:.2f} at start, {os.getloadavg()[0]:.2f} at end, "
          f"{os.cpu_count()} cores, {args.repeat} runs each")
    for (variant, name), t in times.items():
        label = name if len(variants) == 1 else f"{variant}: {name}"
        print(f"{label:60s} wall median {statistics.median(t):5.2f} s, best {min(t):5.2f} s;"
              f"  CPU median {statistics.median(cpu[variant, name]):5.2f} s")


if __name__ == "__main__":
    main()
