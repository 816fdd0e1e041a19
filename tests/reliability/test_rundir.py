"""The run directory (issue 17, items 4, 5, 7, 14; gmtiflow/rundir.py).

* Hydra's ``.hydra/config.yaml`` is written only after the earlier run's outputs are gone: a
  kill just before or just after that removal never pairs one run's config with another's
  ``run.h5``.
* A second run into a locked directory fails at once with one line and touches nothing.
* Symlinked Hydra outputs (``.hydra/*.yaml``, ``gmtiflow.log``) are refused, not written through.
* ``hydra/job_logging=disabled`` works; Ctrl-C prints one line, exits 130 and leaves
  ``outputs.json`` saying ``complete: false``.
"""
from __future__ import annotations

import gc
import json
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
import yaml

from gmtiflow import pipeline, rundir, store
from gmtiflow.compose import compose
from gmtiflow.errors import GmtiflowError

TINY = ["scene.duration_s=5", "export=none", "report=none", "progress=false",
        "cache.enabled=false"]

# The CLI with rundir.prepare wrapped: KILL=before|after ends the process (os._exit, like
# SIGKILL: no cleanup) just before or just after the earlier run's outputs are removed.
DRIVER = textwrap.dedent("""
    import os, sys
    from gmtiflow import cli, rundir
    orig = rundir.prepare
    def prepare(*a, **k):
        if os.environ.get("KILL") == "before":
            os._exit(9)
        out = orig(*a, **k)
        if os.environ.get("KILL") == "after":
            os._exit(9)
        return out
    rundir.prepare = prepare
    sys.argv = ["gmtiflow", *sys.argv[1:]]
    cli.main()
""")


def cli(out: Path, *args, kill=None, cwd=None, **popen):
    env = dict(os.environ, KILL=kill or "")
    return subprocess.run([sys.executable, "-c", DRIVER, f"hydra.run.dir={out}", *TINY, *args],
                          capture_output=True, text=True, env=env, cwd=cwd or out.parent,
                          timeout=300, **popen)


def config_seed(out: Path):
    path = out / ".hydra" / "config.yaml"
    return yaml.safe_load(path.read_text())["seed"] if path.exists() else None


def run_seed(out: Path):
    try:
        with store.open_run(out / "run.h5") as f:
            return int(f.attrs["seed"])
    except GmtiflowError:
        return None


@pytest.mark.slow
@pytest.mark.parametrize("kill", ["before", "after"])
def test_a_killed_rerun_never_pairs_its_config_with_the_earlier_run(tmp_path, kill):
    out = tmp_path / "run"
    first = cli(out, "seed=1")
    assert first.returncode == 0, first.stderr
    assert config_seed(out) == 1 and run_seed(out) == 1
    second = cli(out, "seed=2", kill=kill)
    assert second.returncode == 9, second.stderr
    if kill == "before":     # nothing touched: the earlier run and its own config
        assert config_seed(out) == 1 and run_seed(out) == 1
    else:                    # the earlier outputs are gone; no config of seed 2 beside them
        assert run_seed(out) is None and not (out / "run.h5").exists()
        assert json.loads((out / pipeline.MANIFEST).read_text())["complete"] is False
    third = cli(out, "seed=3")
    assert third.returncode == 0, third.stderr
    assert config_seed(out) == 3 and run_seed(out) == 3
    assert "seed=3" in yaml.safe_load((out / ".hydra" / "overrides.yaml").read_text())


def test_second_run_into_a_locked_directory_fails_cleanly(tmp_path):
    out = tmp_path / "run"
    out.mkdir()
    partial = out / ".run.h5.12345.partial"       # the first run's file in progress
    partial.write_bytes(b"first run writing")
    fd = rundir._lock(out)                          # the first run holds the directory
    try:
        with pytest.raises(rundir.RunDirBusyError, match="another gmtiflow run"):
            pipeline.run(compose(TINY), out)
        res = cli(out, "seed=2")
    finally:
        os.close(fd)
    assert res.returncode == 1
    errors = [ln for ln in res.stderr.splitlines() if "another gmtiflow run" in ln]
    assert len(errors) == 1 and "Traceback" not in res.stderr, res.stderr
    assert partial.read_bytes() == b"first run writing"
    assert not (out / ".hydra").exists() and not (out / "run.h5").exists()


class _Cycle:
    pass


def test_a_run_leaves_the_garbage_collector_as_it_found_it(tmp_path):
    """pipeline.run freezes what lives before it (its collections skip the config and the
    modules) and unfreezes on the way out, finished or failed: a cycle made before the run is
    collected after it."""
    import weakref
    assert gc.get_freeze_count() == 0
    cycle = _Cycle()
    cycle.me = cycle
    alive = weakref.ref(cycle)
    del cycle
    pipeline.run(compose(TINY), tmp_path / "ok")
    assert gc.get_freeze_count() == 0
    gc.collect()
    assert alive() is None
    busy = tmp_path / "busy"
    busy.mkdir()
    fd = rundir._lock(busy)
    try:
        with pytest.raises(rundir.RunDirBusyError):
            pipeline.run(compose(TINY), busy)
    finally:
        os.close(fd)
    assert gc.get_freeze_count() == 0


def test_claim_is_reentrant_and_released(tmp_path):
    with rundir.claim(tmp_path):
        with rundir.claim(tmp_path):
            pass
        with pytest.raises(rundir.RunDirBusyError):
            os.close(rundir._lock(tmp_path))        # another open file: refused
    os.close(rundir._lock(tmp_path))                # released


@pytest.mark.parametrize("link", [".hydra/config.yaml", "gmtiflow.log", ".hydra"])
def test_symlinked_hydra_outputs_are_refused_not_written_through(tmp_path, link):
    out = tmp_path / "run"
    (out / ".hydra").mkdir(parents=True)
    victim = tmp_path / ("victim_dir" if link == ".hydra" else "victim.txt")
    if link == ".hydra":
        victim.mkdir()
        (out / ".hydra").rmdir()
    else:
        victim.write_text("precious\n")
    (out / link).symlink_to(victim)
    res = cli(out, "seed=2")
    assert res.returncode == 1, res.stderr
    assert "symlink" in res.stderr and "Traceback" not in res.stderr, res.stderr
    if link == ".hydra":
        assert list(victim.iterdir()) == []
    else:
        assert victim.read_text() == "precious\n"
    assert not (out / "run.h5").exists()


def test_hydra_job_logging_disabled_runs_and_reports_errors(tmp_path):
    out = tmp_path / "run"
    ok = cli(out, "hydra/job_logging=disabled")
    assert ok.returncode == 0, ok.stderr
    assert run_seed(out) == 1 and config_seed(out) == 1
    bad = cli(tmp_path / "bad", "hydra/job_logging=disabled", "scene.duration_s=-1")
    assert bad.returncode == 1
    assert "scene.duration_s" in bad.stderr and "Traceback" not in bad.stderr, bad.stderr


def _sigint_as_in_a_terminal():
    """The child starts with SIGINT deliverable and at its default action, as under an
    interactive shell.  Both are inherited through fork and exec: a test-runner process whose
    SIGINT was left ignored or blocked (loky's and multiprocessing's resource trackers block it
    while they spawn) would pass that on, Python never sees the signal and the run ends with exit
    0 (happened twice under pytest-xdist at load)."""
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def test_ctrl_c_is_one_line_exit_130_and_outputs_marked_incomplete(tmp_path):
    out = tmp_path / "run"
    out.mkdir()
    proc = subprocess.Popen([sys.executable, "-m", "gmtiflow.cli", "-v", f"hydra.run.dir={out}",
                             "scene.duration_s=600", "export=none", "report=none",
                             "progress=false", "cache.enabled=false"],
                            stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True,
                            cwd=tmp_path, preexec_fn=_sigint_as_in_a_terminal)
    lines = []
    for line in proc.stderr:
        lines.append(line)
        if "run pid=" in line:
            proc.send_signal(signal.SIGINT)
            break
    rest = proc.stderr.read()
    rc = proc.wait(timeout=120)
    err = "".join(lines) + rest
    assert rc == 130, err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err
    assert rest.strip().splitlines()[-1].startswith("gmtiflow: interrupted"), err
    assert json.loads((out / pipeline.MANIFEST).read_text())["complete"] is False
    assert not (out / "run.h5").exists() and not list(out.glob(".run.h5.*"))


# Ctrl-C where the test above saw it go astray (once each under load), made to happen there:
# * h5py: the run file's first root attribute written the way h5py's conversion code reacts to
#   a Ctrl-C inside it, the KeyboardInterrupt coming out as a TypeError (exit 1 and "Error
#   executing job" with two tracebacks, before errors_as_interrupt);
# * weakref: a weakref callback receives it while the scene is built; Python swallows it there
#   and prints "Exception ignored in ..." with a traceback (in a WeakValueDictionary's
#   callback); the next stage boundary re-raises it.
CTRL_C_ASTRAY = {
    "h5py": """
        from gmtiflow import store as where
        orig = where._set_root_attr
        def astray(*a, **k):
            try:
                os.kill(os.getpid(), signal.SIGINT)
                time.sleep(5)
            except BaseException as exc:
                raise TypeError("Operation not defined for data type class") from exc
            return orig(*a, **k)
        where._set_root_attr = astray
    """,
    "weakref": """
        from gmtiflow import stages as where
        orig = where.build_scene
        class Thing:
            pass
        def ctrl_c(_ref):
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(5)
        def astray(*a, **k):
            thing = Thing()
            ref = weakref.ref(thing, ctrl_c)
            del thing                               # the callback runs here
            return orig(*a, **k)
        where.build_scene = astray
    """}


@pytest.mark.parametrize("where", sorted(CTRL_C_ASTRAY))
def test_ctrl_c_that_goes_astray_is_still_one_line_and_exit_130(tmp_path, where):
    driver = ("import os, signal, sys, time, weakref\n" + textwrap.dedent(CTRL_C_ASTRAY[where])
              + "from gmtiflow import cli\nsys.argv = ['gmtiflow', *sys.argv[1:]]\ncli.main()\n")
    out = tmp_path / "run"
    proc = subprocess.run([sys.executable, "-c", driver, f"hydra.run.dir={out}", *TINY],
                          capture_output=True, text=True, cwd=tmp_path, timeout=300,
                          preexec_fn=_sigint_as_in_a_terminal)
    assert proc.returncode == 130, proc.stderr
    for word in ("Traceback", "TypeError", "Exception ignored"):
        assert word not in proc.stderr, proc.stderr
    assert proc.stderr.strip().splitlines()[-1].startswith("gmtiflow: interrupted")
    assert json.loads((out / pipeline.MANIFEST).read_text())["complete"] is False
    assert not (out / "run.h5").exists() and not list(out.glob(".run.h5.*"))


def test_an_error_without_ctrl_c_stays_that_error():
    from gmtiflow import interrupts
    with pytest.raises(TypeError):
        with interrupts.errors_as_interrupt():
            raise TypeError("not an interrupt")


def test_temporaries_are_what_the_writers_glob_patterns_match(tmp_path):
    """rundir.temporaries lists the directory once for every name; it finds exactly the files
    glob's ``.<name>.*.partial*`` and ``<name>.*.part`` find (sorted, in that order),
    names with glob's special characters included."""
    import glob

    names = ["run.h5", "det.csv", "a[1].xml", "x*y.json", "run"]
    files = [".run.h5.123.0.partial", ".run.h5.9.partial.gif", ".run.h5.partial",
             ".run.h5..partial", "run.h5.tmp.part", "run.h5.part", "run.h5..part",
             ".det.csv.7.partial", "det.csv.1.part", "det.csv.1.part.x", ".a[1].xml.3.partial",
             "a[1].xml.2.part", ".x*y.json.1.partial", ".xzy.json.1.partial", "x*y.json.z.part",
             ".run.5.partial", "run.h5", "other.part", ".run.h5.5.Partial"]
    for f in files:
        (tmp_path / f).write_bytes(b"")
    entries = sorted(p.name for p in tmp_path.iterdir())
    for name in names:
        want = sorted(tmp_path.glob(f".{glob.escape(name)}.*.partial*")) + \
            sorted(tmp_path.glob(f"{glob.escape(name)}.*.part"))
        assert rundir.temporaries(tmp_path, name) == want, name
        assert rundir.temporaries(tmp_path, name, entries) == want, name
    assert rundir.temporaries(tmp_path / "missing", "run.h5") == []
