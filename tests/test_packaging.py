"""The configs ship in the wheel: a wheel installed in a fresh venv runs from an unrelated cwd."""
import subprocess
import sys
import sysconfig
import venv
from pathlib import Path

import pytest

from gmtiflow import store

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_wheel_installed_elsewhere_finds_its_configs(tmp_path):
    dist = tmp_path / "dist"
    subprocess.run([sys.executable, "-m", "build", "--wheel", "--outdir", str(dist), str(ROOT)],
                   check=True, capture_output=True, timeout=600)
    wheel = next(dist.glob("gmtiflow-*.whl"))
    env_dir = tmp_path / "venv"
    venv.EnvBuilder(with_pip=True).create(env_dir)
    py = env_dir / "bin" / "python"
    subprocess.run([str(py), "-m", "pip", "install", "-q", "--no-deps", "--no-index", str(wheel)],
                   check=True, capture_output=True, timeout=300)
    # Dependencies come from this interpreter's site-packages through a plain path entry, which
    # does not process that directory's .pth files, so an editable gmtiflow there stays invisible.
    site = Path(subprocess.check_output(
        [str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
        text=True).strip())
    (site / "zz_test_deps.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    where = subprocess.check_output([str(py), "-c", "import gmtiflow; print(gmtiflow.__file__)"],
                                    cwd=elsewhere, text=True).strip()
    assert where.startswith(str(env_dir)), where
    proc = subprocess.run([str(env_dir / "bin" / "gmtiflow"), "scene.duration_s=10",
                           f"hydra.run.dir={elsewhere / 'out'}", "vehicles=random"],
                          cwd=elsewhere, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    with store.open_run(elsewhere / "out" / "run.h5") as f:
        assert "truth" in f
    info = subprocess.run([str(env_dir / "bin" / "gmtiflow"), "--info", "searchpath"],
                          cwd=elsewhere, capture_output=True, text=True, timeout=120)
    assert "pkg://gmtiflow.conf" in info.stdout
