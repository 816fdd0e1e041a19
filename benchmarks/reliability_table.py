"""docs/reliability.md's table: hostile inputs tried per entry point and their outcomes.

Outcomes: *clean error* (the documented error type: one line, exit 1), *clean run* (accepted and
finished), *other* (any other exception, a traceback, a hang: a bug).

* config: every numeric leaf at 0, tiny, huge, the largest accepted magnitude and -1
  (``benchmarks/config_extremes.py``); a seeded sample of the accepted ones is run.
* loaders and format readers: ``benchmarks/fuzz.py``'s mutation cases per target.
* run files: the tampered (``tests/reliability/test_tampered_runs.py``) and damaged
  (``tests/reliability/test_hdf5_inputs.py``) variants of one run file, each given to
  ``gmtiflow-convert`` (4607 and GeoJSON), ``gmtiflow-evaluate`` and ``gmtiflow-report --runs``.

    python benchmarks/reliability_table.py                      # the recorded run
    python benchmarks/reliability_table.py --fuzz-cases 200 --config-runs 10   # quicker
"""
from __future__ import annotations

import argparse
import contextlib
import importlib.util
import io
import shutil
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def _load(name: str, path: Path):
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    spec.loader.exec_module(mod)
    return mod


def config_rows(runs: int, seed: int):
    ext = _load("config_extremes", ROOT / "benchmarks" / "config_extremes.py")
    base = ext.compose(ext.BASE)
    counts = Counter()
    accepted = []
    for leaf, value in ext.cases(base):
        try:
            cfg, err = ext.validate_case(base, leaf, value)
        except Exception:           # noqa: BLE001
            counts["other"] += 1
            continue
        if cfg is None:
            counts["clean error"] += 1
        else:
            accepted.append(cfg)
    pick = np.random.default_rng(seed).choice(len(accepted), min(runs, len(accepted)),
                                              replace=False)
    for i in pick:
        outcome, _ = ext.run_case(accepted[i], 120.0)
        counts[outcome] += 1
    counts["accepted, not run"] = len(accepted) - len(pick)
    return [("config (validate + budget; sample run)", counts)]


def fuzz_rows(cases: int, seed: int):
    fuzz = _load("fuzz", ROOT / "benchmarks" / "fuzz.py")
    rows = []
    for target, (seeds_fn, call, allowed) in fuzz.TARGETS.items():
        rng = np.random.default_rng([seed, sum(target.encode())])
        seeds = seeds_fn()
        counts = Counter()
        for n in range(cases):
            data = fuzz.mutate(seeds[n % len(seeds)], rng)
            try:
                call(data)
                counts["clean run"] += 1
            except allowed:
                counts["clean error"] += 1
            except Exception:       # noqa: BLE001
                counts["other"] += 1
        rows.append((f"{target} (fuzz)", counts))
    return rows


def run_file_rows():
    sys.path.insert(0, str(ROOT / "tests" / "reliability"))
    tampered = _load("test_tampered_runs", ROOT / "tests" / "reliability" / "test_tampered_runs.py")
    damaged = _load("test_hdf5_inputs", ROOT / "tests" / "reliability" / "test_hdf5_inputs.py")
    from gmtiflow import pipeline
    from gmtiflow.compose import compose
    counts = {k: Counter() for k in ("convert-4607", "convert-geojson", "evaluate", "report")}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        good = tmp / "good"
        pipeline.run(compose(["scene.duration_s=10", "export=csv", "report=none",
                              "export.csv_tables=[detections,truth,tracks]", "progress=false",
                              "cache.enabled=false"]), good)
        jobs = [("t", v) for v in tampered.VARIANTS] + [("d", v) for v in damaged.VARIANTS]
        for n, (kind, variant) in enumerate(jobs):
            work = tmp / f"case{n}"
            work.mkdir()
            if kind == "t":
                bad = tampered.make_variant(good, work / "job", variant)
            else:
                (work / "job").mkdir()
                bad = work / "job" / "run.h5"
                damaged.VARIANTS[variant](good / "run.h5", bad)
            for prog, call in tampered.consumers(bad, work, good / "tracks.csv"):
                err = io.StringIO()
                try:
                    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
                        code = call()
                    outcome = ("clean run" if code == 0 else
                               "clean error" if code == 1 and "Traceback" not in err.getvalue()
                               else "other")
                except Exception:   # noqa: BLE001
                    outcome = "other"
                counts[prog][outcome] += 1
            shutil.rmtree(work)
    n = len(jobs)
    return [(f"run file -> gmtiflow-{prog} ({n} variants)", c) for prog, c in counts.items()]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--fuzz-cases", type=int, default=2000)
    p.add_argument("--config-runs", type=int, default=60)
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    start = time.perf_counter()
    rows = config_rows(args.config_runs, args.seed) + run_file_rows() + \
        fuzz_rows(args.fuzz_cases, args.seed)
    print(f"| entry point | inputs tried | clean error | clean run | other |")
    print(f"|---|---|---|---|---|")
    total_other = 0
    for name, c in rows:
        tried = c["clean error"] + c["clean run"] + c["other"] + c["accepted, not run"]
        extra = f" ({c['accepted, not run']} accepted, not run)" if c["accepted, not run"] else ""
        print(f"| {name} | {tried:,} | {c['clean error']:,} | {c['clean run']:,}{extra} | "
              f"{c['other']} |")
        total_other += c["other"]
    print(f"\n{time.perf_counter() - start:.0f} s")
    return 1 if total_other else 0


if __name__ == "__main__":
    sys.exit(main())
