"""Run every benchmark whose figures docs/ quotes, and print each one's output with the date
and the machine load (docs/scale.md, "Regenerating the figures").

    python benchmarks/all.py [--quick] [--only NAME ...] [--list] [--out DIR]

Each script runs in its own process, one after the other (never two at once: they would time
each other), with its own arguments; ``--quick`` gives every script smaller arguments (fewer
sizes, seeds and repeats: the same measurements, coarser) so that the whole set takes a few
minutes, for checking that every figure still reproduces in order of magnitude.  The figures
to quote are those of a full run on a quiet machine.  Before and after each script the UTC time
and the 1-minute load average are printed; ratios from one script's run (A/B alternated inside
it) are what count on a shared machine.  Output of each script also goes to ``--out``/NAME.txt.

The table below (``BENCHMARKS``) names, for every command, the script and the doc page that
quotes it (a script quoted with several argument sets has an entry per set); ``user_wait`` keeps
its 1,000-vehicle run under ``--out``, and the entries that time a stage of a real run
(``export_stage``, ``report_run``, ``metrics_run``) read it: ``--only`` adds it first.  The
A/B comparisons against old revisions that some pages quote (``--against``, ``--baseline``,
``--text-against``) are left out, except the clutter one: they measure a past change, not
today's figure.  A script that backs no figure in docs/ is not listed (``fuzz.py`` and ``config_extremes.py`` back the
reliability tables through ``reliability_table.py``).
"""
from __future__ import annotations

import argparse
import datetime as dt
import os
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent

# name: (script, doc page quoting it, full arguments, --quick arguments).  "{out}" stands for
# --out; the entries after "user_wait" read the 1,000-vehicle run it keeps in {out}/user_wait.
BENCHMARKS = {
    "scale": ("scale", "docs/scale.md", [], ["--quick"]),
    "user_wait": ("user_wait", "docs/scale.md",
                  ["--big", "--keep", "{out}/user_wait"], ["--quick", "--keep", "{out}/user_wait"]),
    "export_stage": ("export_throughput", "docs/formats.md",
                     ["--run", "{out}/user_wait/pipeline/run.h5", "--stage", "--ab-runs", "3"],
                     ["--run", "{out}/user_wait/pipeline/run.h5", "--stage", "--ab-runs", "1"]),
    "report_run": ("report_time", "docs/reports.md",
                   ["--run", "{out}/user_wait/pipeline/run.h5", "--fresh"],
                   ["--run", "{out}/user_wait/pipeline/run.h5", "--repeat", "1"]),
    "metrics_run": ("metrics_throughput", "docs/evaluation.md",
                    ["--run", "{out}/user_wait/pipeline/run.h5"],
                    ["--run", "{out}/user_wait/pipeline/run.h5", "--repeats", "1"]),
    "fidelity_tradeoff": ("fidelity_tradeoff", "docs/scale.md",
                          ["--seeds", "1", "2", "--repeat", "3"],
                          ["--seeds", "1", "--", "scene.duration_s=300",
                           "vehicles.random.count=100"]),
    "fidelity_1k": ("fidelity_tradeoff", "docs/scale.md",     # issue 18's 1,000-vehicle scene
                    ["--seeds", "1", "--repeat", "5", "--out", "{out}/fidelity_1k", "--",
                     "vehicles.random.count=1000", "scene.duration_s=1800",
                     "vehicles.random.start_time_max_s=1500"],
                    ["--seeds", "1", "--out", "{out}/fidelity_1k", "--",
                     "vehicles.random.count=500", "scene.duration_s=900",
                     "vehicles.random.start_time_max_s=600"]),
    "fidelity_variants_1k": ("fidelity_tradeoff", "docs/scale.md",   # fast with 2 s steps
                             ["--seeds", "1", "--repeat", "5",
                              "--out", "{out}/fidelity_variants_1k",
                              "--variant", "fast-2s=fast:fidelity.time_step_s=2.0",
                              "--variant", "fast-2s5s=fast:fidelity.time_step_s=2.0,"
                              "fidelity.truth_output_dt_s=5.0", "--",
                              "vehicles.random.count=1000", "scene.duration_s=1800",
                              "vehicles.random.start_time_max_s=1500"],
                             ["--seeds", "1", "--out", "{out}/fidelity_variants_1k",
                              "--variant", "fast-2s=fast:fidelity.time_step_s=2.0", "--",
                              "vehicles.random.count=500", "scene.duration_s=900",
                              "vehicles.random.start_time_max_s=600"]),
    "stonesoup_peer": ("stonesoup_peer", "docs/scale.md", [], ["--quick"]),
    "run_file_write": ("run_file_write", "docs/scale.md", [], ["--rounds", "1", "--repeat", "2"]),
    "truth_windows": ("truth_windows", "docs/scale.md", [],
                      ["--repeat", "1", "--only", "peer 10 x", "default"]),
    "sweep_parallel": ("sweep_parallel", "docs/scale.md", [], ["--jobs", "2"]),
    "sensor_throughput": ("sensor_throughput", "docs/scale.md, docs/sensor.md",
                          ["--vehicles", "10000", "--workers", "1", "--plain"],
                          ["--vehicles", "10000", "--workers", "1", "--repeat", "3"]),
    "truth_throughput": ("truth_throughput", "docs/scene.md", [],
                         ["--counts", "100", "1000", "--repeat", "1"]),
    "effects_scaling": ("effects_scaling", "docs/effects.md", [], ["--quick"]),
    "clutter_throughput": ("clutter_throughput", "docs/scale.md, docs/effects.md",
                           ["--baseline", "20b4222"], ["--quick"]),
    "terrain_los": ("terrain_los", "docs/terrain.md", [], ["--rays", "10000", "--repeat", "1"]),
    "export_throughput": ("export_throughput", "docs/formats.md, docs/exports.md",
                          ["--detections", "100000", "--dwells", "1000", "--repeat", "1"],
                          ["--detections", "50000", "--dwells", "500", "--repeat", "1"]),
    "read_4607_throughput": ("read_4607_throughput", "docs/formats.md", [],
                             ["--packets", "100000", "--repeat", "1"]),
    "metrics_throughput": ("metrics_throughput", "docs/evaluation.md", [], []),
    "metrics_scaling": ("metrics_throughput", "docs/evaluation.md", ["--scaling"], ["--scaling"]),
    "tracker_protocol_overhead": ("tracker_protocol_overhead", "docs/evaluation.md",
                                  ["--vehicles", "1000", "--duration-s", "300", "--repeats", "2"],
                                  ["--vehicles", "200", "--duration-s", "120", "--repeats", "1"]),
    "two_orbits": ("two_orbits", "docs/evaluation.md", ["--seeds", "1", "2", "3"],
                   ["--seeds", "1"]),
    "report_time": ("report_time", "docs/reports.md", [], ["--big", "30", "--repeat", "1"]),
    "startup_time": ("startup_time", "README.md", [], ["--repeat", "2"]),
    "config_scale": ("config_scale", "docs/scale.md", ["--omegaconf", "--hydra"],
                     ["--repeat", "1"]),
    "vehicles_file": ("vehicles_file", "docs/scale.md", [], ["--vehicles", "200", "--repeat", "1"]),
    "reliability_table": ("reliability_table", "docs/reliability.md", [],
                          ["--fuzz-cases", "100", "--config-runs", "5"]),
    "benchmark_suite": ("benchmark_suite", "docs/benchmark.md", [], ["--quick"]),
}
#: Left out of --quick: they run whole tracker suites or sweeps of processes (minutes each).
SLOW = {"benchmark_suite", "sweep_parallel", "reliability_table"}
#: Entries that read what another entry keeps: --only adds that one first.
NEEDS = {"export_stage": "user_wait", "report_run": "user_wait", "metrics_run": "user_wait"}


def stamp() -> str:
    now = dt.datetime.now(dt.timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC")
    return f"{now}, load {os.getloadavg()[0]:.2f} (1-min average, {os.cpu_count()} cores)"


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="smaller arguments; slow ones skipped")
    ap.add_argument("--only", nargs="+", choices=sorted(BENCHMARKS), help="run just these")
    ap.add_argument("--list", action="store_true", help="list the scripts and their docs")
    ap.add_argument("--out", type=Path, default=Path("outputs/benchmarks/all"))
    args = ap.parse_args(argv)
    if args.list:
        for name, (script, doc, full, quick) in BENCHMARKS.items():
            print(f"{name:26s} {doc:32s} {script}.py full: {' '.join(full) or '-'}   quick: "
                  f"{'skipped' if name in SLOW else ' '.join(quick) or '-'}")
        return
    names = args.only or [n for n in BENCHMARKS if not (args.quick and n in SLOW)]
    names = [n for n in BENCHMARKS if n in names or n in {NEEDS.get(m) for m in names}]
    args.out.mkdir(parents=True, exist_ok=True)
    print(f"benchmarks/all.py{' --quick' if args.quick else ''}: {len(names)} scripts; "
          f"started {stamp()}", flush=True)
    failed, t_all = [], time.perf_counter()
    for name in names:
        script, doc, full, quick = BENCHMARKS[name]
        cmd = [sys.executable, str(HERE / f"{script}.py"),
               *(a.replace("{out}", str(args.out)) for a in (quick if args.quick else full))]
        print(f"\n=== {name} (quoted in {doc}): {' '.join(cmd[1:])}\n    start {stamp()}",
              flush=True)
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, capture_output=True, text=True,
                              env={**os.environ, "PYTHONPATH": str(HERE.parent)})
        text = proc.stdout + (proc.stderr[-2000:] if proc.returncode else "")
        (args.out / f"{name}.txt").write_text(text)
        print(text.rstrip())
        print(f"    end   {stamp()}; {time.perf_counter() - t0:.1f} s"
              + ("" if proc.returncode == 0 else
                 f"; exit status {proc.returncode}: it failed or reports a missed goal (above)"),
              flush=True)
        if proc.returncode:
            failed.append(name)
    print(f"\nall: {len(names) - len(failed)} of {len(names)} ran in "
          f"{time.perf_counter() - t_all:.0f} s; finished {stamp()}"
          + (f"; non-zero exit: {', '.join(failed)}" if failed else ""))
    raise SystemExit(1 if failed else 0)


if __name__ == "__main__":
    main()
