"""Wall time of a 4-job seed sweep: Hydra's basic (serial) launcher vs joblib with 2 workers.

    python benchmarks/sweep_parallel.py [--out DIR] [--jobs 4] [-- extra overrides]

Runs the real ``gmtiflow -m`` console entry point twice, into ``DIR/serial`` and
``DIR/joblib``, each with its own empty stage cache (seeds differ, so every job computes its
own truth and nothing is shared), and prints both wall times and their ratio.  On a 2-core
machine the ideal ratio is 2; process start-up and the import of numpy/scipy/h5py per loky
worker take some of it back.  On a shared machine other users' processes take their share too,
so the script first measures how many cores two CPU-bound processes actually get
(``available parallelism``): the speed-up cannot exceed it.
"""
from __future__ import annotations

import argparse
import os
import resource
import shutil
import subprocess
import sys
import time
from pathlib import Path

DEFAULT = ["scene.duration_s=600", "vehicles=random", "vehicles.random.count=300",
           "clutter=urban", "progress=false"]


def _busy(n: int = 15_000_000) -> float:
    start = time.perf_counter()
    x = 0
    for i in range(n):
        x += i
    return time.perf_counter() - start


def available_parallelism() -> float:
    """How many cores two CPU-bound processes get right now (2.0 on an idle 2-core machine).

    The ratio (one busy loop alone) / (two at once) x 2: on a shared machine other users'
    processes take their share, which bounds any launcher's speed-up.
    """
    import multiprocessing as mp
    alone = _busy()
    with mp.get_context("spawn").Pool(2) as pool:
        pair = pool.map(_busy, [15_000_000] * 2)
    return 2.0 * alone / max(pair)


def sweep(out: Path, launcher_args, seeds, extra):
    if out.exists():
        shutil.rmtree(out)
    cmd = [sys.executable, "-m", "gmtiflow.cli", "-m", f"hydra.sweep.dir={out / 'sweep'}",
           f"cache.dir={out / 'cache'}", f"seed={','.join(map(str, seeds))}", *DEFAULT,
           *launcher_args, *extra]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    # One BLAS/OpenMP thread per process in both sweeps (loky sets this in its workers anyway),
    # so the comparison is of process-level parallelism only.
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
    subprocess.run(cmd, check=True, capture_output=True, text=True, env=env)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="outputs/benchmarks/sweep_parallel")
    ap.add_argument("--jobs", type=int, default=4)
    ap.add_argument("extra", nargs="*", help="more Hydra overrides for every job")
    args = ap.parse_args(argv)
    out = Path(args.out)
    seeds = list(range(1, args.jobs + 1))
    avail = available_parallelism()
    serial, cpu_s = sweep(out / "serial", [], seeds, args.extra)
    par, cpu_p = sweep(out / "joblib", ["hydra/launcher=joblib", "hydra.launcher.n_jobs=2"],
                       seeds, args.extra)
    print(f"{args.jobs} jobs ({' '.join(DEFAULT + args.extra)}); load average before: "
          f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    print(f"serial (basic launcher)  {serial:7.1f} s wall {cpu_s:7.1f} s CPU")
    print(f"joblib, 2 workers        {par:7.1f} s wall {cpu_p:7.1f} s CPU")
    print(f"speed-up                 {serial / par:7.2f} x")
    print(f"available parallelism    {avail:7.2f} cores for two CPU-bound processes "
          f"(calibration before the sweeps; 2.0 = an idle 2-core machine)")


if __name__ == "__main__":
    main()
