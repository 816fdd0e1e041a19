"""CPU time of writing the run file (run.h5), replayed from the writes of real runs.

    python benchmarks/run_file_write.py [--scenes peer fast] [--rounds 5] [--against DIR]

Each scene runs once while every call its ``RunWriter`` receives is recorded: ``peer`` is the
10-target, 1,800-scan workload of ``stonesoup_peer.py`` (its gmtiflow child), ``fast`` the
scene of ``fidelity_tradeoff.py`` with ``fidelity=fast seed=1``.  The calls are then replayed
into a fresh file in child processes, and each child prints the median CPU time
(``time.process_time``: the whole process, so the compression threads count) of 5 replays of:

* ``whole``: the run file as the run writes it (137 datasets, 11 tables and ``/config``);
* ``fixed``: the same calls with every table cut to its first 10 rows: what writing a run file
  costs whatever the size of its tables (the file, 137 datasets and their attributes, the
  commit);
* ``deflate``: compressing the run's columns as the writer does
  (``gmtiflow.chunk_codec._deflated_chunk`` on each chunk) and, for comparison, HDF5's own
  filters on the same chunks (shuffle, then zlib level 1, what h5py's ``compression="gzip", compression_opts=1, shuffle=True`` does), with
  the bytes each stores.

With ``--against DIR`` (another revision's package: ``mkdir DIR && git archive COMMIT
gmtiflow | tar -x -C DIR``) every round runs one child on this checkout's gmtiflow and one on
DIR's (``PYTHONPATH=DIR``), alternated; the ratio of the medians is the figure to quote.  The
load is printed with each child.
"""
from __future__ import annotations

import argparse
import json
import os
import pickle
import statistics
import subprocess
import sys
import tempfile
import time
import zlib
from pathlib import Path

HERE = Path(__file__).resolve().parent


def record(scene: str, out: Path) -> list:
    """Run ``scene`` once into ``out`` and return the calls its RunWriter received."""
    from gmtiflow import pipeline, store
    from gmtiflow.compose import compose
    sys.path.insert(0, str(HERE))
    calls = []
    cls = store.RunWriter
    saved = {n: cls.__dict__[n] for n in ("__init__", "set_attrs", "write_text",
                                          "write_table", "append_table", "commit")}

    def recorded(name, method):
        def call(self, *a, **k):
            top = not getattr(self, "_recording", False)    # not write_table from append_table
            if top:     # the path of __init__ is the replay's own; a list of parts (a
                # TableSink's block) is replayed joined: what a revision before lists takes
                calls.append((name, () if name == "__init__" else
                              (a[0], _whole(a[1]), *a[2:]) if len(a) > 1 else a, k))
            self._recording = True
            try:
                return method(self, *a, **k)
            finally:
                if top:
                    self._recording = False
        return call

    for name, method in saved.items():
        setattr(cls, name, recorded(name, method))
    try:
        if scene == "peer":
            import stonesoup_peer
            stonesoup_peer.gmtiflow_child(10, 1800, str(out))
        else:
            import fidelity_tradeoff as ft
            pipeline.run(compose(ft.SCENE + ft.FIXED + ["fidelity=fast", "seed=1"]), out)
    finally:
        for name, method in saved.items():
            setattr(cls, name, method)
    return calls


def _whole(table) -> dict:
    """A table as the writer was given it: a table, or a list of parts (TableSink's blocks)."""
    import numpy as np
    if not isinstance(table, list):
        return table
    return {c: np.concatenate([p[c] for p in table]) for c in table[0]} if table else {}


def _cut(calls: list, rows: int) -> list:
    out = []
    for name, a, k in calls:
        if name in ("write_table", "append_table"):
            a = (a[0], {c: v[:rows] for c, v in a[1].items()}, *a[2:])
        out.append((name, a, k))
    return out


def _replay(calls: list, path: Path) -> None:
    from gmtiflow import store
    path.unlink(missing_ok=True)    # as a run's rundir.prepare does: no rename over a file
    w = None
    for name, a, k in calls:
        if name == "__init__":
            w = store.RunWriter(path, **k)
        else:
            getattr(w, name)(*a, **k)


def _chunks(calls: list):
    import numpy as np
    from gmtiflow import store
    for name, a, _ in calls:
        if name in ("write_table", "append_table"):
            for values in a[1].values():
                v = np.asarray(values)
                if v.dtype.kind in "biuf":
                    for i in range(0, len(v), store._CHUNK_ROWS):
                        yield np.ascontiguousarray(v[i:i + store._CHUNK_ROWS])


def _hdf5_filters(values) -> bytes:
    import numpy as np
    k = values.dtype.itemsize
    raw = values if k == 1 else np.ascontiguousarray(values.view(np.uint8).reshape(-1, k).T)
    return zlib.compress(raw, 1)


def child(pickle_path: str, repeat: int) -> dict:
    """Replay the recorded calls; median CPU seconds of each measure (printed as JSON)."""
    from gmtiflow import store
    try:
        from gmtiflow import chunk_codec    # the chunk encoder's module since 2026-11-28
    except ImportError:                     # an older revision (--against): store.py's own
        chunk_codec = store
    calls = pickle.loads(Path(pickle_path).read_bytes())
    small = _cut(calls, 10)
    chunks = list(_chunks(calls))
    res = {"load": os.getloadavg()[0], "store": store.__file__}
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "run.h5"
        _replay(calls, path)        # warm-up: imports, HDF5's first file
        for label, fn in (("whole", lambda: _replay(calls, path)),
                          ("fixed", lambda: _replay(small, path)),
                          ("deflate", lambda: sum(len(chunk_codec._deflated_chunk(c)) for c in chunks)),
                          ("hdf5_level1", lambda: sum(len(_hdf5_filters(c)) for c in chunks))):
            times = []
            for _ in range(repeat):
                t0 = time.process_time()
                size = fn()
                times.append(time.process_time() - t0)
            res[label] = statistics.median(times)
            if label in ("deflate", "hdf5_level1"):
                res[label + "_bytes"] = size
    res["raw_bytes"] = sum(c.nbytes for c in chunks)
    return res


def run_child(pickle_path: Path, repeat: int, against=None) -> dict:
    env = dict(os.environ)
    if against:
        env["PYTHONPATH"] = str(against) + os.pathsep + env.get("PYTHONPATH", "")
    proc = subprocess.run([sys.executable, __file__, "--child", str(pickle_path), str(repeat)],
                          capture_output=True, text=True, env=env, check=True)
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", nargs="+", default=["peer", "fast"], choices=["peer", "fast"])
    ap.add_argument("--rounds", type=int, default=5, help="children per side and scene")
    ap.add_argument("--repeat", type=int, default=5, help="replays per child")
    ap.add_argument("--against", type=Path, help="a checkout of another revision")
    ap.add_argument("--child", nargs=2, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        print(json.dumps(child(args.child[0], int(args.child[1]))))
        return
    sides = [("this", None)] + ([("against", args.against)] if args.against else [])
    measures = ("whole", "fixed", "deflate", "hdf5_level1")
    with tempfile.TemporaryDirectory() as tmp:
        for scene in args.scenes:
            pk = Path(tmp) / f"{scene}.pkl"
            pk.write_bytes(pickle.dumps(record(scene, Path(tmp) / scene)))
            got = {side: [] for side, _ in sides}
            for _ in range(args.rounds):
                for side, where in sides:
                    r = run_child(pk, args.repeat, where)
                    got[side].append(r)
                    print(f"{scene:5s} {side:8s} load {r['load']:5.2f}  " + "  ".join(
                        f"{m} {r[m] * 1000:6.1f}" for m in measures) + " ms CPU", flush=True)
            print(f"\n{scene}: medians over {args.rounds} children ({args.repeat} replays each), "
                  f"ms CPU")
            for side, where in sides:
                med = {m: statistics.median(r[m] for r in got[side]) for m in measures}
                r0 = got[side][0]
                print(f"  {side:8s} {where or ''}: " + ", ".join(
                    f"{m} {med[m] * 1000:.1f}" for m in measures) +
                    f"; stored {r0['deflate_bytes'] / 1e6:.2f} MB (HDF5 level 1: "
                    f"{r0['hdf5_level1_bytes'] / 1e6:.2f} MB) of {r0['raw_bytes'] / 1e6:.2f} MB")
            if args.against:
                for m in ("whole", "fixed", "deflate"):
                    a = statistics.median(r[m] for r in got["against"])
                    b = statistics.median(r[m] for r in got["this"])
                    print(f"  {m}: {a * 1000:.1f} -> {b * 1000:.1f} ms ({a / b:.2f}x)")
            print(flush=True)


if __name__ == "__main__":
    main()
