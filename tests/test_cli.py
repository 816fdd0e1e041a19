"""The CLI end to end on small scenes, and its errors (one clear line, non-zero exit, no file)."""
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from gmtiflow import store

ROOT = Path(__file__).resolve().parents[1]
LEAN = ["report=none", "export=none"]    # for tests that read only run.h5


def gmtiflow(tmp_path, *overrides, cwd=None):
    """Run the CLI into tmp_path/run; returns the CompletedProcess."""
    env = dict(os.environ, HYDRA_FULL_ERROR="0")
    tmp_path.mkdir(parents=True, exist_ok=True)
    cmd = [sys.executable, "-m", "gmtiflow.cli", f"hydra.run.dir={tmp_path / 'run'}", *overrides]
    return subprocess.run(cmd, cwd=cwd or tmp_path, capture_output=True, text=True, env=env,
                          timeout=300)


def test_default_scene_writes_truth_and_platform(tmp_path):
    proc = gmtiflow(tmp_path, "scene.duration_s=60")
    assert proc.returncode == 0, proc.stderr
    run = tmp_path / "run" / "run.h5"
    with store.open_run(run) as f:
        for name in ("config", "roads/nodes", "roads/edges", "vehicles", "truth", "platform"):
            assert name in f, name
        assert f.attrs["seed"] == 1
    truth = store.read_table(run, "truth")
    platform = store.read_table(run, "platform")
    assert len(truth["time_s"]) > 0
    assert np.all(truth["speed_mps"] >= 0)
    assert np.array_equal(np.unique(platform["time_s"]), np.arange(61.0))
    assert "seed: 1" in store.read_text(run, "config")


def test_same_config_and_seed_give_identical_datasets(tmp_path):
    runs = []
    for name in ("a", "b"):
        proc = gmtiflow(tmp_path / name, "scene.duration_s=30", "cache.enabled=false", *LEAN)
        assert proc.returncode == 0, proc.stderr
        runs.append(tmp_path / name / "run" / "run.h5")
    for table in ("truth", "platform", "vehicles", "roads/nodes"):
        a, b = (store.read_table(r, table) for r in runs)
        assert a.keys() == b.keys()
        for col in a:
            assert np.array_equal(a[col], b[col]), (table, col)
    other = gmtiflow(tmp_path / "c", "scene.duration_s=30", "seed=2", *LEAN)
    assert other.returncode == 0
    c = store.read_table(tmp_path / "c" / "run" / "run.h5", "truth")
    a = store.read_table(runs[0], "truth")
    assert not (len(a["x_m"]) == len(c["x_m"]) and np.array_equal(a["x_m"], c["x_m"]))


@pytest.mark.parametrize("overrides, needle", [
    (["sensr=wide"], "sensr"),                                  # unknown group
    (["platform=nowhere"], "platform/nowhere"),                 # unknown option
    (["platform.speed=3"], "speed"),                            # unknown key
    (["platform.speed_mps=fast"], "speed_mps"),                 # wrong type
    (["platform.speed_mps=-5"], "platform.speed_mps"),          # out of range
    (["scene.epoch_utc=yesterday"], "scene.epoch_utc"),         # malformed value
])
def test_bad_config_is_one_clear_error_and_no_output(tmp_path, overrides, needle):
    proc = gmtiflow(tmp_path, *overrides)
    assert proc.returncode != 0
    assert needle in proc.stderr
    assert "Traceback" not in proc.stderr
    assert not list(tmp_path.rglob("*.h5"))
