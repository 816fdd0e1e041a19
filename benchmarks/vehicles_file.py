"""The ``gmtiflow`` command with 1,000 listed vehicles: as a group file vs as ``vehicles.file``.

    python benchmarks/vehicles_file.py [--vehicles 1000] [--repeat 3]

The vehicles: the Stone Soup peer's (``stonesoup_peer.py``, as ``config_scale.py`` lists them:
N explicit off-road vehicles, each with its waypoints for 600 s), written once as YAML.  Two
cases, each the ``gmtiflow`` console command in a fresh process (``user_wait.run_once``: wall
seconds from launch to exit, CPU seconds of the process from ``wait4``), on a short scene
(``scene.duration_s=60 tracker=none metrics.enabled=false report=none export=none
cache.enabled=false``):

* ``group``: the list as a vehicles group file, ``hydra.searchpath=[file://DIR] vehicles=peerN``
  (Hydra composes it twice, converts every vehicle into the typed schema, copies the config);
* ``file``: the same text as ``vehicles=file vehicles.file=DIR/peerN.yaml`` (read past Hydra,
  gmtiflow/scene/vehicles_file.py).

The cases alternate within each repeat; every run, the medians and the UTC time with the
1-minute load before and after are printed.  The two run files are checked equal (every
dataset, /config included), and the loader's own CPU time for the file is printed (in this
process, best of 3).
"""
from __future__ import annotations

import argparse
import datetime as dt
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

SHORT = ["scene.duration_s=60", "tracker=none", "metrics.enabled=false", "report=none",
         "export=none", "cache.enabled=false", "progress=false"]


def stamp() -> str:
    now = dt.datetime.now(dt.timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC")
    return f"{now}, load {os.getloadavg()[0]:.2f} (1-min average, {os.cpu_count()} cores)"


def same_datasets(a: Path, b: Path) -> bool:
    import h5py
    import numpy as np

    def contents(path):
        out = {}
        with h5py.File(path, "r") as f:
            f.visititems(lambda name, obj: out.__setitem__(name, np.asarray(obj[()]))
                         if isinstance(obj, h5py.Dataset) else None)
        return out

    ca, cb = contents(a), contents(b)
    return ca.keys() == cb.keys() and all(
        ca[k].dtype == cb[k].dtype and (ca[k].tolist() == cb[k].tolist() if ca[k].dtype == object
                                        else ca[k].tobytes() == cb[k].tobytes()) for k in ca)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vehicles", type=int, default=1000)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    from stonesoup_peer import peer_vehicles
    from user_wait import run_once

    from gmtiflow import config
    from gmtiflow.scene import vehicles_file

    n = args.vehicles
    print(f"start: {stamp()}", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        text = config.pyyaml_text(peer_vehicles(n, 600.0))
        (tmp / "conf" / "vehicles").mkdir(parents=True)
        (tmp / "conf" / "vehicles" / f"peer{n}.yaml").write_text(text)
        (tmp / f"peer{n}.yaml").write_text(text)
        print(f"{n} vehicles, {len(text) / 1e6:.2f} MB of YAML; each case: gmtiflow "
              f"{' '.join(SHORT)} and", flush=True)
        cases = {"group": [f"hydra.searchpath=[file://{tmp / 'conf'}]", f"vehicles=peer{n}"],
                 "file": ["vehicles=file", f"vehicles.file={tmp / f'peer{n}.yaml'}"]}
        for case, overrides in cases.items():
            print(f"  {case:5s}: {' '.join(overrides)}")
        results = {case: [] for case in cases}
        for i in range(args.repeat):
            for case, overrides in cases.items():
                r = run_once(SHORT + overrides, tmp / "runs" / case)
                results[case].append(r)
                print(f"  repeat {i + 1} {case:5s}: {r['wall_s']:6.2f} s wall "
                      f"{r['cpu_s']:6.2f} s CPU   ({stamp()})", flush=True)
        same = same_datasets(tmp / "runs" / "group" / "run.h5", tmp / "runs" / "file" / "run.h5")
        print(f"run.h5 of the two cases identical (every dataset, /config included): {same}")
        best = float("inf")
        for _ in range(3):
            t0 = time.process_time()
            vehicles_file.load(str(tmp / f"peer{n}.yaml"))
            best = min(best, time.process_time() - t0)
        print(f"vehicles_file.load of the file: {best:.3f} s CPU (best of 3, this process)")
    med = {c: (statistics.median(r["wall_s"] for r in rs), statistics.median(r["cpu_s"] for r in rs))
           for c, rs in results.items()}
    for case, (wall, cpu) in med.items():
        print(f"median {case:5s}: {wall:6.2f} s wall {cpu:6.2f} s CPU")
    print(f"group / file: {med['group'][0] / med['file'][0]:.1f}x wall, "
          f"{med['group'][1] / med['file'][1]:.1f}x CPU")
    print(f"end: {stamp()}")
    if not same:
        raise SystemExit("the two run files differ")


if __name__ == "__main__":
    main()
