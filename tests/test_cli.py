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
    (["platform=nowhere"], "platform has no option 'nowhere'"),  # unknown option
    (["platform.speed=3"], "speed"),                            # unknown key
    (["+platform.speed=3"], "platform.speed: unknown config key"),  # ... added with +
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


@pytest.mark.parametrize("overrides, line", [
    (["sensor=wide_fvo"], "config group sensor has no option 'wide_fvo'; did you mean "
                          "sensor=wide_fov? (options: default, no_stap, wide_fov)"),
    (["experiment=challenge/tunel"], "config group experiment has no option 'challenge/tunel'; "
                                     "did you mean experiment=challenge/tunnel? (options: "),
    (["sensr=wide_fov"], "invalid config: sensr: unknown config group or key; did you mean "
                         "sensor?"),
    (["sensor.freq_hzz=1e10"], "invalid config: sensor.freq_hzz: unknown config key; did you "
                               "mean sensor.freq_hz?"),
    (["sensor.freq_hz=abc"], "invalid config: sensor.freq_hz: Value 'abc' of type 'str' could "
                             "not be converted to Float"),
    (["sensor.freq_hz=[1"], "cannot parse the override 'sensor.freq_hz=[1': "),
    (["sensor.freq_hz"], "cannot parse the override 'sensor.freq_hz': missing EQUAL"),
    (["+sensor.freq_hz=1e10"], "Could not append to config. An item is already at "
                               "'sensor.freq_hz'."),
    (["sensor=1"], "cannot use the override 'sensor=1': Config group override must be a string "
                   "or a list. Got int"),
    (["-m", "sensor=default,wide_fvo"], "config group sensor has no option 'wide_fvo'"),
    (["--cfg", "job", "sensor=wide_fvo"], "config group sensor has no option 'wide_fvo'"),
])
def test_composition_errors_are_one_line_and_a_hint_at_most(tmp_path, overrides, line):
    """Hydra's own report of these was 6-12 lines (its message, OmegaConf's full_key block, the
    config search path, 'Set the environment variable HYDRA_FULL_ERROR=1 ...')."""
    flags = [o for o in overrides if o.startswith("-") or o == "job"]   # before the overrides
    rest = [o for o in overrides if o not in flags]
    proc = subprocess.run([sys.executable, "-m", "gmtiflow.cli", *flags,
                           f"hydra.run.dir={tmp_path / 'run'}", f"hydra.sweep.dir={tmp_path / 'run'}",
                           "scene.duration_s=60", *rest], capture_output=True, text=True,
                          env=dict(os.environ, HYDRA_FULL_ERROR="0"), timeout=300, cwd=tmp_path)
    assert proc.returncode == 1
    lines = proc.stderr.splitlines()
    assert 1 <= len(lines) <= 2, proc.stderr
    assert lines[0].startswith(f"gmtiflow: error: {line}"), proc.stderr
    assert all(x.startswith("gmtiflow: hint: ") for x in lines[1:]), proc.stderr
    assert proc.stdout == ""
    assert not (tmp_path / "run").exists()


def test_hydra_full_error_still_gives_hydras_own_report(tmp_path):
    env = dict(os.environ, HYDRA_FULL_ERROR="1")
    proc = subprocess.run([sys.executable, "-m", "gmtiflow.cli", f"hydra.run.dir={tmp_path}/run",
                           "sensor=wide_fvo"], capture_output=True, text=True, env=env,
                          timeout=300, cwd=tmp_path)
    assert proc.returncode == 1
    assert "Traceback" in proc.stderr and "Could not find 'sensor/wide_fvo'" in proc.stderr


def many_vehicles_text(copies: int = 8) -> str:
    """The default group's 8 vehicles (convoy, stop points, tunnel, off-road ...) ``copies``
    times, renamed and staggered: a group file of 64 vehicles, in the group file's own text."""
    import yaml
    group = yaml.safe_load((ROOT / "conf" / "vehicles" / "default.yaml").read_text())
    listed = []
    for k in range(copies):
        for spec in group["vehicles"]:
            listed.append({**spec, "name": f"{spec['name']}-{k}",
                           "start_time_s": spec.get("start_time_s", 0) + 7 * k})
    return yaml.safe_dump({"vehicles": listed, "random": group["random"]}, sort_keys=False)


def h5_contents(path):
    """Every dataset (dtype and values, bit for bit) and every attribute of a run file."""
    import h5py
    out = {}

    def bits(value):
        value = np.asarray(value)
        return (str(value.dtype), value.shape,
                value.tolist() if value.dtype == object else value.tobytes())

    def record(name, obj):
        out[f"{name}@attrs"] = {k: bits(v) for k, v in obj.attrs.items()}
        if isinstance(obj, h5py.Dataset):
            out[name] = bits(obj[()])

    with h5py.File(path, "r") as f:
        record("", f)
        f.visititems(record)
    return out


def test_vehicles_file_gives_the_run_of_the_same_group_file(tmp_path):
    """64 vehicles as a vehicles group file (on hydra.searchpath) and as ``vehicles.file``
    (relative to the launch directory): the same run file, /config and attributes included."""
    text = many_vehicles_text()
    (tmp_path / "conf" / "vehicles").mkdir(parents=True)
    (tmp_path / "conf" / "vehicles" / "many.yaml").write_text(text)
    (tmp_path / "many.yaml").write_text(text)
    common = ["scene.duration_s=30", "cache.enabled=false", *LEAN]
    group = gmtiflow(tmp_path / "group", f"hydra.searchpath=[file://{tmp_path / 'conf'}]",
                     "vehicles=many", *common)
    assert group.returncode == 0, group.stderr
    from_file = gmtiflow(tmp_path / "file", "vehicles=file", "vehicles.file=many.yaml", *common,
                         cwd=tmp_path)
    assert from_file.returncode == 0, from_file.stderr
    a = h5_contents(tmp_path / "group" / "run" / "run.h5")
    b = h5_contents(tmp_path / "file" / "run" / "run.h5")
    assert a["vehicles/name"][1] == (64 + 2 * 8,)     # each convoy brings two more trucks
    assert a.keys() == b.keys()
    assert [k for k in a if a[k] != b[k]] == []
    hydra_config = (tmp_path / "file" / "run" / ".hydra" / "config.yaml").read_text()
    assert "file: many.yaml" in hydra_config      # Hydra's record keeps the path as given


def test_vehicles_file_in_a_multirun_reads_the_launch_directory(tmp_path):
    """``-m`` with the basic launcher: every job reads the relative path from where the
    command started (hydra.job.chdir is false); tests/test_sweeps.py does the same with joblib."""
    (tmp_path / "two.yaml").write_text("vehicles:\n  - {name: rel-1, start: g_0_0, end: g_6_2}\n"
                                       "  - {name: rel-2, start: g_3_2, end: hw_x4000}\n")
    env = dict(os.environ, HYDRA_FULL_ERROR="0")
    cmd = [sys.executable, "-m", "gmtiflow.cli", "-m", f"hydra.sweep.dir={tmp_path / 'sweep'}",
           "scene.duration_s=20", "tracker=none", "progress=false", "cache.enabled=false",
           *LEAN, "vehicles=file", "vehicles.file=two.yaml", "seed=1,2"]
    proc = subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True, env=env,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr
    for job in ("0", "1"):
        names = store.read_table(tmp_path / "sweep" / job / "run.h5", "vehicles")["name"]
        assert [str(n) for n in names] == ["rel-1", "rel-2"]


@pytest.mark.parametrize("text, needle", [
    ("vehicles:\n  - {name: a, start: g_0_0, end: g_6_2}\n  - {name: b, cruise_speed_mps: fast}\n",
     "big.yaml: vehicles[1].cruise_speed_mps: expected a number, got 'fast'"),
    ("vehicles:\n  - {name: a, start: g_0_0\n", "big.yaml: line 3, column 1: "),
    ("vehicles:\n  - {name: a, start: g_0_0, end: g_6_2}\n  - {name: a, start: g_0_0, end: g_6_2}\n",
     "big.yaml: vehicles[1].name: vehicle name 'a' is used twice"),
    (None, "big.yaml: no such file"),
])
def test_a_bad_vehicles_file_is_one_error_line_and_no_run_file(tmp_path, text, needle):
    if text is not None:
        (tmp_path / "big.yaml").write_text(text)
    proc = gmtiflow(tmp_path, "vehicles=file", "vehicles.file=big.yaml", "scene.duration_s=20")
    assert proc.returncode == 1, proc.stderr
    assert f"vehicles.file {tmp_path / 'big.yaml'}: " in proc.stderr, proc.stderr
    assert needle in proc.stderr, proc.stderr
    assert "Traceback" not in proc.stderr
    assert len([line for line in proc.stderr.splitlines() if "vehicles.file" in line]) == 1
    assert not list(tmp_path.rglob("*.h5")) and not list(tmp_path.rglob("*.partial"))


def test_a_sweep_job_with_a_bad_config_fails_alone_without_a_traceback(tmp_path):
    """A user error in one job of a sweep used to end the sweep with Hydra's printed Python
    traceback (through cli.py and config.py) after the other jobs had run."""
    import json
    env = dict(os.environ, HYDRA_FULL_ERROR="0")
    cmd = [sys.executable, "-m", "gmtiflow.cli", "-m", f"hydra.sweep.dir={tmp_path / 'sweep'}",
           "scene.duration_s=20", *LEAN, "sensor.pfa=2,1e-6"]
    proc = subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True, env=env,
                          timeout=300)
    assert proc.returncode == 1, proc.stderr
    assert "Traceback" not in proc.stderr and 'File "' not in proc.stderr, proc.stderr
    assert "sensor.pfa: must be in (0.0, 1.0), got 2.0" in proc.stderr, proc.stderr
    with store.open_run(tmp_path / "sweep" / "1" / "run.h5"):     # the good job ran
        pass
    timing = json.loads((tmp_path / "sweep" / "0" / "timing.json").read_text())
    assert timing["status"] == "FAILED"
    assert timing["error"] == ("ConfigError('invalid config: sensor.pfa: must be in (0.0, 1.0), "
                               "got 2.0')")
    assert not (tmp_path / "sweep" / "0" / "run.h5").exists()
