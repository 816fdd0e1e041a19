"""Hydra multiruns through the launchers of the ``sweep`` extra (joblib, submitit_local).

Each sweep writes into ``tmp_path`` (``hydra.sweep.dir=``) with its own stage cache, and runs
the real console entry point in a subprocess, as a user would.
"""
import os
import subprocess
import sys

import h5py
import numpy as np
import pytest

from gmtiflow import store

SMALL = ["scene.duration_s=30", "tracker=none", "progress=false"]


def sweep(tmp_path, *overrides, timeout=300):
    env = dict(os.environ, HYDRA_FULL_ERROR="1")
    cmd = [sys.executable, "-m", "gmtiflow.cli", "-m", f"hydra.sweep.dir={tmp_path / 'sweep'}",
           f"cache.dir={tmp_path / 'cache'}", *SMALL, *overrides]
    proc = subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True, env=env,
                          timeout=timeout)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return proc


def job_runs(tmp_path, n):
    runs = [tmp_path / "sweep" / str(i) / "run.h5" for i in range(n)]
    for run in runs:
        with store.open_run(run):   # complete, this layout
            pass
    return runs


def job_logs(tmp_path):
    return "".join(p.read_text() for p in sorted((tmp_path / "sweep").glob("*/gmtiflow.log")))


pytest.importorskip("hydra_plugins.hydra_joblib_launcher")


@pytest.mark.slow
def test_joblib_seed_sweep_runs_in_parallel(tmp_path):
    sweep(tmp_path, "hydra/launcher=joblib", "hydra.launcher.n_jobs=2", "seed=1,2,3,4")
    runs = job_runs(tmp_path, 4)
    seeds = [int(store.open_run(r).attrs["seed"]) for r in runs]
    assert seeds == [1, 2, 3, 4]
    x = [store.read_table(r, "truth")["x_m"] for r in runs]
    assert not np.array_equal(x[0], x[1])          # seeds differ, so do the truths
    pids = {line.split("pid=")[1].split()[0] for line in job_logs(tmp_path).splitlines()
            if "pid=" in line}
    assert len(pids) == 2, pids                    # two loky workers ran the four jobs
    # Determinism (DESIGN §2): joblib jobs (cache on) equal serial in-process runs (cache off),
    # every dataset bit for bit except /config, which records the cache settings
    from gmtiflow import pipeline
    from gmtiflow.compose import compose
    for job, seed in ((0, 1), (3, 4)):
        serial = pipeline.run(compose(SMALL + [f"seed={seed}", "cache.enabled=false",
                                               "export=none", "report=none"]),
                              tmp_path / f"serial{seed}")
        a, b = datasets(runs[job]), datasets(serial)
        assert sorted(a) == sorted(b)
        for name in set(a) - {"config"}:
            assert a[name].dtype == b[name].dtype and a[name].tobytes() == b[name].tobytes() \
                if a[name].dtype.kind in "fiub" else np.array_equal(a[name], b[name]), (seed, name)


def datasets(path) -> dict:
    out = {}
    with h5py.File(path, "r") as f:
        f.visititems(lambda name, obj: out.__setitem__(name, np.asarray(obj[()]))
                     if isinstance(obj, h5py.Dataset) else None)
    return out


@pytest.mark.slow
def test_joblib_sensor_sweep_computes_truth_once(tmp_path):
    """3 x 2 sensor settings in 2 parallel workers share one truth (the cache lock)."""
    sweep(tmp_path, "hydra/launcher=joblib", "hydra.launcher.n_jobs=2",
          "sensor.peak_power_w=100,500,2000", "sensor.pfa=1e-6,1e-4")
    job_runs(tmp_path, 6)
    logs = job_logs(tmp_path)
    assert logs.count("cache miss truth") == 1, logs
    assert logs.count("cache hit truth") == 5
    assert logs.count("cache miss sensor") == 6


@pytest.mark.slow
def test_submitit_local_sweep(tmp_path):
    pytest.importorskip("hydra_plugins.hydra_submitit_launcher")
    sweep(tmp_path, "hydra/launcher=submitit_local", "hydra.launcher.timeout_min=5",
          "seed=1,2", timeout=600)
    runs = job_runs(tmp_path, 2)
    assert [int(store.open_run(r).attrs["seed"]) for r in runs] == [1, 2]
    assert (tmp_path / "sweep" / ".submitit").is_dir()


@pytest.mark.slow
def test_joblib_jobs_read_a_relative_vehicles_file_from_the_launch_directory(tmp_path):
    """vehicles.file relative to where the command started, in joblib's worker processes too."""
    (tmp_path / "two.yaml").write_text("vehicles:\n  - {name: rel-1, start: g_0_0, end: g_6_2}\n"
                                       "  - {name: rel-2, start: g_3_2, end: hw_x4000}\n")
    sweep(tmp_path, "hydra/launcher=joblib", "hydra.launcher.n_jobs=2", "seed=1,2",
          "vehicles=file", "vehicles.file=two.yaml", "report=none", "export=none")
    for run in job_runs(tmp_path, 2):
        assert [str(n) for n in store.read_table(run, "vehicles")["name"]] == ["rel-1", "rel-2"]
