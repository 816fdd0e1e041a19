"""gmtiflow.allocator: glibc malloc settings for a run, and the user's way out."""
import os
import platform
import subprocess
import sys

import pytest

CODE = "from gmtiflow import allocator; print(allocator.tune(), allocator.tune())"


def _run(**env):
    clean = {k: v for k, v in os.environ.items()
             if not k.startswith("MALLOC_") and k not in ("GLIBC_TUNABLES", "GMTIFLOW_MALLOC")}
    out = subprocess.run([sys.executable, "-c", CODE], env={**clean, **env}, check=True,
                         capture_output=True, text=True)
    return out.stdout.split()


@pytest.mark.skipif(platform.system() != "Linux" or platform.libc_ver()[0] != "glibc",
                    reason="the settings are glibc's")
def test_tune_applies_once_and_the_user_choice_wins():
    assert _run() == ["True", "True"]
    assert _run(GMTIFLOW_MALLOC="default") == ["False", "False"]
    assert _run(MALLOC_ARENA_MAX="2") == ["False", "False"]
    assert _run(GLIBC_TUNABLES="glibc.malloc.trim_threshold=1") == ["False", "False"]
