"""A full disk (issue 17, item 10): one clear message, nothing that reads as complete, and the
cache never blocks a run (its cases: ``test_cache_integrity.py``).

The run file's writer checks the free space before every block (HDF5 itself, on ENOSPC, prints
destructor errors and segfaulted, exit 139); exports and reports that hit ENOSPC end the CLI
with one error line.  Where tmpfs can be mounted (root in a container) a real 17 MiB file
system is filled; elsewhere the free-space query is monkeypatched.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from gmtiflow import pipeline, store
from gmtiflow.compose import compose
from gmtiflow.errors import StoreError

QUIET = ["report=none", "progress=false", "cache.enabled=false"]


def test_run_file_on_a_full_disk_is_a_store_error_and_leaves_nothing(tmp_path, monkeypatch):
    calls = []

    def free(directory):
        calls.append(1)
        return store.MIN_FREE_BYTES * 4 if len(calls) < 6 else store.MIN_FREE_BYTES // 2
    monkeypatch.setattr(store, "free_bytes", free)
    with pytest.raises(StoreError, match="the disk is full"):
        pipeline.run(compose(["scene.duration_s=10", "export=csv", *QUIET]), tmp_path)
    assert len(calls) >= 6                              # it failed mid-write, not up front
    assert not (tmp_path / "run.h5").exists() and not list(tmp_path.glob(".run.h5.*"))
    assert json.loads((tmp_path / pipeline.MANIFEST).read_text())["complete"] is False


DRIVER = textwrap.dedent("""
    import errno, sys
    from contextlib import contextmanager
    from gmtiflow.formats import _io
    real = _io.atomic_path
    @contextmanager
    def full(dest, suffix=".partial"):       # the manifest fits; the exports do not
        if str(dest).endswith("outputs.json"):
            with real(dest, suffix) as tmp:
                yield tmp
            return
        raise OSError(errno.ENOSPC, "No space left on device", str(dest))
        yield
    _io.atomic_path = full
    from gmtiflow import cli
    sys.argv = ["gmtiflow", *sys.argv[1:]]
    cli.main()
""")


def test_exports_on_a_full_disk_end_with_one_line(tmp_path):
    out = tmp_path / "run"
    res = subprocess.run([sys.executable, "-c", DRIVER, f"hydra.run.dir={out}",
                          "scene.duration_s=5", "export=csv", *QUIET], capture_output=True,
                         text=True, cwd=tmp_path, timeout=300)
    assert res.returncode == 1, res.stderr
    assert "Traceback" not in res.stderr, res.stderr
    errors = [ln for ln in res.stderr.splitlines() if "ERROR" in ln or "error:" in ln]
    assert len(errors) == 1 and "No space left on device" in errors[0], res.stderr
    assert json.loads((out / pipeline.MANIFEST).read_text())["complete"] is False


def _mount_tmpfs(path: Path, size: str) -> bool:
    if os.geteuid() != 0:
        return False
    path.mkdir()
    res = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(path)],
                         capture_output=True)
    return res.returncode == 0


@pytest.mark.slow
def test_a_real_full_tmpfs_gives_one_message_and_no_complete_run(tmp_path):
    disk = tmp_path / "disk"
    if not _mount_tmpfs(disk, "17m"):
        pytest.skip("cannot mount a tmpfs here")
    try:
        out = disk / "run"
        res = subprocess.run([sys.executable, "-m", "gmtiflow.cli", f"hydra.run.dir={out}",
                              "scene.duration_s=600", "export=none", *QUIET],
                             capture_output=True, text=True, cwd=tmp_path, timeout=600)
        assert res.returncode == 1, res.stderr[-2000:]
        assert "the disk is full" in res.stderr and "Traceback" not in res.stderr
        assert not (out / "run.h5").exists() and not list(out.glob(".run.h5.*"))
        assert json.loads((out / pipeline.MANIFEST).read_text())["complete"] is False
    finally:
        subprocess.run(["umount", str(disk)], capture_output=True)
