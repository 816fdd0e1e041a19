"""docs/reliability.md's table: hostile inputs tried per entry point and their outcomes.

Outcomes: *clean error* (the documented error type: one line, exit 1), *clean run* (accepted and
finished), *other* (any other exception, a traceback, a hang: a bug).

* config: every numeric leaf at 0, tiny, huge, the largest accepted magnitude and -1
  (``benchmarks/config_extremes.py``); a seeded sample of the accepted ones is run.
* loaders and format readers: ``benchmarks/fuzz.py``'s mutation cases per target.
* run files: the tampered (``tests/reliability/test_tampered_runs.py``) and damaged
  (``tests/reliability/test_hdf5_inputs.py``) variants of one run file, each given to
  ``gmtiflow-convert`` (4607 and GeoJSON), ``gmtiflow-evaluate``, ``gmtiflow-report --runs``
  and ``gmtiflow-view``.
* the newer entry points, each case a fresh process of the installed console script
  (:func:`entry_rows`): ``gmtiflow-view`` arguments and outputs, ``gmtiflow-bench`` numbers and
  inputs, ``gmtiflow-convert udp://`` / ``tcp://`` addresses, options and hostile datagrams,
  ``gmtiflow tracker=python tracker.target=...`` import paths and misbehaving trackers, and
  external trajectory CSVs (``platform=trajectory``).

    python benchmarks/reliability_table.py                      # the recorded run
    python benchmarks/reliability_table.py --fuzz-cases 200 --config-runs 10   # quicker
"""
from __future__ import annotations

import argparse
import contextlib
import importlib.util
import io
import os
import shutil
import signal
import socket
import subprocess
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
    from gmtiflow.report import viewer
    counts = {k: Counter() for k in ("convert-4607", "convert-geojson", "evaluate", "report",
                                     "view")}
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
            calls = tampered.consumers(bad, work, good / "tracks.csv") + [
                ("view", lambda: viewer.main([str(bad), "-o", str(work / "v.html")]))]
            for prog, call in calls:
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


def _script(name: str) -> str:
    return str(Path(sys.executable).parent / name)


def _outcome(argv, timeout_s=180.0, env=None, during=None) -> str:
    """clean run (exit 0) / clean error (exit 1 or 2 with an error line and no traceback) /
    other, for one fresh process; ``during()`` runs while it does (a sender)."""
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=env, start_new_session=True)
    if during is not None:
        during()
    try:
        _, err = proc.communicate(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)      # this case's own process group
        proc.communicate()
        return "other"
    if proc.returncode == 0:
        return "clean run"
    lines = [ln for ln in err.splitlines() if ln.strip()]
    if proc.returncode in (1, 2) and lines and "Traceback" not in err:
        return "clean error"           # a message, a documented exit status, no traceback
    return "other"


def _sender(port, payloads, proto="udp"):
    def send():
        time.sleep(1.0)                          # the receiver is listening by then
        try:
            if proto == "udp":
                with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
                    for b in payloads:
                        s.sendto(b, ("127.0.0.1", port))
            else:
                with socket.create_connection(("127.0.0.1", port), timeout=5) as s:
                    for b in payloads:
                        s.sendall(b)
        except OSError:
            pass
    return send


def entry_rows(tmp: Path):
    """Hostile inputs to the newer entry points (module doc); returns table rows."""
    from gmtiflow import pipeline
    from gmtiflow.compose import compose
    good = tmp / "good"
    pipeline.run(compose(["scene.duration_s=10", "export=stanag4607", "report=none",
                          "progress=false", "cache.enabled=false"]), good)
    run_h5 = good / "run.h5"
    packets = (good / "detections.4607").read_bytes()
    (tmp / "empty").mkdir()
    (tmp / "text.h5").write_text("not hdf5\n")
    (tmp / "alias.html").symlink_to(run_h5)
    view = _script("gmtiflow-view")
    cases = {"gmtiflow-view": [
        [view, str(tmp / "nonexistent")], [view, str(tmp / "empty")],
        [view, str(tmp / "text.h5")], [view, "/dev/zero"],
        [view, str(good), "--max-frames", "0"], [view, str(good), "--max-labels", "-1"],
        [view, str(good), "-o", str(tmp / "empty")], [view, str(good), "-o", str(run_h5)],
        [view, str(good), "-o", str(tmp / "alias.html")],
        [view, str(good), "-o", str(tmp / "v.html")]]}
    bench = _script("gmtiflow-bench")
    cases["gmtiflow-bench"] = [
        [bench, "--jobs", "0"], [bench, "--jobs", "-3"], [bench, "--timeout", "-1"],
        [bench, "--timeout", "nan"], [bench, "report", "--timeout", "inf", str(tmp)],
        [bench, "report", str(tmp / "nonexistent")], [bench, "report", str(tmp / "text.h5")],
        [bench, "report", str(tmp / "empty")], [bench, "--command", "x"],
        [bench, "--command", "=cmd"]]
    conv = _script("gmtiflow-convert")
    out = str(tmp / "live.h5")
    live = [[conv, url, "--to", "h5", "-o", out, "--idle-timeout", "0.5"] for url in (
        "udp://", "udp://:70000", "udp://:abc", "udp://nohost.invalid:47101",
        "ftp://:47101", "udp://:47101", "tcp://:47101")]
    live += [[conv, "udp://:47101", "--to", "csv", "-o", out],
             [conv, "udp://:47101", "--to", "h5"],
             [conv, "udp://:47101", "--to", "h5", "-o", out, "--idle-timeout", "-1"],
             [conv, "udp://:47101", "--to", "h5", "-o", out, "--idle-timeout", "nan"],
             [conv, "udp://:47101", "--to", "h5", "-o", out, "--max-packets", "-1",
              "--idle-timeout", "0.5"]]
    cases["gmtiflow-convert udp:// tcp:// (arguments)"] = live
    g = np.random.default_rng(0)
    streams = [("udp", [bytes(g.integers(0, 256, 200, dtype=np.uint8)) for _ in range(5)]),
               ("udp", [packets[:37]]), ("udp", [packets[:len(packets) // 2]]), ("udp", [b""]),
               ("tcp", [bytes(g.integers(0, 256, 500, dtype=np.uint8))]),
               ("tcp", [packets[:len(packets) // 2]]), ("tcp", [packets])]
    rows = []
    for title, argv_list in cases.items():
        c = Counter(_outcome(a) for a in argv_list)
        rows.append((f"{title} ({len(argv_list)} cases)", c))
    c = Counter()
    for k, (proto, payloads) in enumerate(streams):
        port = 47110 + k
        c[_outcome([conv, f"{proto}://127.0.0.1:{port}", "--to", "h5", "-o", out,
                    "--idle-timeout", "2"], during=_sender(port, payloads, proto))] += 1
    rows.append((f"gmtiflow-convert udp:// tcp:// (hostile streams, {len(streams)} cases)", c))
    # tracker import paths: the user's modules on PYTHONPATH
    mods = tmp / "user"
    mods.mkdir()
    (mods / "raises_at_import.py").write_text("raise ZeroDivisionError('boom')\n")
    (mods / "does_not_compile.py").write_text("x = (\n")
    (mods / "bad_trackers.py").write_text(
        "class Garbage:\n    def reset(self, scene): pass\n"
        "    def update(self, batch): return {'track_id': ['a'], 'x_m': [None]}\n"
        "    def finish(self): return None\n"
        "class Raises:\n    def reset(self, scene): pass\n"
        "    def update(self, batch): raise ValueError('bug')\n"
        "    def finish(self): return None\n"
        "class BadInit:\n    def __init__(self): raise RuntimeError('init')\n"
        "class NaNs:\n    def reset(self, scene): pass\n"
        "    def update(self, batch): return {'track_id': [1], 'x_m': [float('nan')], "
        "'y_m': [float('inf')]}\n    def finish(self): return None\n")
    env = dict(os.environ, PYTHONPATH=str(mods))
    gm = _script("gmtiflow")
    base = ["scene.duration_s=10", "report=none", "export=none", "cache.enabled=false",
            "progress=false"]
    c = Counter()
    targets = ["raises_at_import.T", "does_not_compile.T", "bad_trackers.Garbage",
               "bad_trackers.Raises", "bad_trackers.BadInit", "bad_trackers.NaNs", "math.pi",
               "no_such_module.T", "json.loads", "''"]
    for k, t in enumerate(targets):
        c[_outcome([gm, f"hydra.run.dir={tmp / f'tr{k}'}", *base, "tracker=python",
                    f"tracker.target={t}"], env=env)] += 1
    rows.append((f"gmtiflow tracker=python tracker.target=... ({len(targets)} cases)", c))
    # external trajectory CSVs
    log_csv = ROOT / "tests" / "data" / "platform_log.csv"
    (tmp / "nan.csv").write_text("time_s,lat_deg,lon_deg,height_m\n0,50,7,100\n1,nan,7,100\n")
    (tmp / "digits.csv").write_text("time_s,lat_deg,lon_deg,height_m\n0,50,7,"
                                    + "9" * 5000 + "\n1,50,7,100\n")
    (tmp / "etc.csv").symlink_to("/etc/hostname")
    trajectories = [(log_csv, "250"), (log_csv, "100"), (tmp / "nan.csv", "1"),
                    (tmp / "digits.csv", "1"), (tmp / "etc.csv", "10"), (Path("/dev/zero"), "10"),
                    (tmp / "empty", "10"), (tmp / "nonexistent.csv", "10")]
    c = Counter()
    for k, (path, duration) in enumerate(trajectories):
        c[_outcome([gm, f"hydra.run.dir={tmp / f'pl{k}'}", *base, "tracker=none",
                    "metrics.enabled=false", f"scene.duration_s={duration}",
                    "platform=trajectory", f"platform.path={path}"])] += 1
    rows.append((f"gmtiflow platform=trajectory platform.path=... ({len(trajectories)} cases)",
                 c))
    return rows


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--fuzz-cases", type=int, default=2000)
    p.add_argument("--config-runs", type=int, default=60)
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        entries = entry_rows(Path(tmp))
    rows = config_rows(args.config_runs, args.seed) + run_file_rows() + entries + \
        fuzz_rows(args.fuzz_cases, args.seed)
    print("| entry point | inputs tried | clean error | clean run | other |")
    print("|---|---|---|---|---|")
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
