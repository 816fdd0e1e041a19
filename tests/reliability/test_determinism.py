"""Same config + same seed => bit-identical HDF5 datasets (DESIGN §2): run twice, with the stage
cache on (cold and warm) or off, and with 1 or 3 sensor worker threads.  Serial vs joblib sweeps:
tests/test_sweeps.py::test_joblib_seed_sweep_runs_in_parallel."""
from __future__ import annotations

import h5py
import numpy as np

from gmtiflow import pipeline
from gmtiflow.compose import compose

SCENE = ["scene.duration_s=30", "vehicles=random", "vehicles.random.count=8",
         "clutter=urban", "export=none", "report=none", "progress=false", "seed=7"]


def datasets(path) -> dict:
    out = {}
    with h5py.File(path, "r") as f:
        f.visititems(lambda name, obj: out.__setitem__(name, obj[()])
                     if isinstance(obj, h5py.Dataset) else None)
    return out


def assert_bit_identical(a, b, skip=("config",)):
    da, db = datasets(a), datasets(b)
    for name in skip:
        da.pop(name, None), db.pop(name, None)
    assert sorted(da) == sorted(db)
    for name in da:
        x, y = np.asarray(da[name]), np.asarray(db[name])
        assert (x.dtype, x.shape) == (y.dtype, y.shape), name
        if x.dtype.kind in "fiub":
            assert x.tobytes() == y.tobytes(), name             # bitwise, NaNs included
        else:
            assert np.array_equal(x, y), name


def test_same_seed_is_bit_identical_with_cache_on_off_and_any_worker_count(tmp_path):
    runs = {}
    for name, extra in [("a", ["cache.enabled=false"]), ("b", ["cache.enabled=false"]),
                        ("cold", [f"cache.dir={tmp_path / 'cache'}"]),
                        ("warm", [f"cache.dir={tmp_path / 'cache'}"]),
                        ("threads", ["cache.enabled=false", "sensor_workers=3",
                                     "chunk_s=7"])]:
        runs[name] = pipeline.run(compose(SCENE + extra), tmp_path / name)
    assert len(datasets(runs["a"])["detections/det_id"]) > 0
    assert_bit_identical(runs["a"], runs["b"], skip=())      # /config identical too
    for name in ("cold", "warm", "threads"):
        assert_bit_identical(runs["a"], runs[name])          # /config records cache/workers
    with h5py.File(runs["a"]) as fa, h5py.File(runs["b"]) as fb:
        assert dict(fa.attrs).keys() == dict(fb.attrs).keys()
        for k in fa.attrs:
            assert np.array_equal(fa.attrs[k], fb.attrs[k]), k


def test_same_seed_is_bit_identical_from_one_process_to_the_next(tmp_path):
    """The default scene with its tracker and metrics, run by the gmtiflow command in two
    processes whose string hashes are salted differently (PYTHONHASHSEED): anything that
    follows the order of a set of strings, or of objects hashed by address, shows up here
    (it did for the Stone Soup GM-PHD, tests/evaluate/test_stonesoup_trackers.py)."""
    import os
    import subprocess
    import sys

    runs = []
    for salt in ("1", "2"):
        out = tmp_path / salt
        subprocess.run([sys.executable, "-m", "gmtiflow.cli", f"hydra.run.dir={out}",
                        "export=none", "report=none", "progress=false", "cache.enabled=false"],
                       cwd=tmp_path, env={**os.environ, "PYTHONHASHSEED": salt}, check=True,
                       capture_output=True, timeout=300)
        runs.append(out / "run.h5")
    assert len(datasets(runs[0])["tracks/track_id"]) > 0
    assert_bit_identical(*runs, skip=())
