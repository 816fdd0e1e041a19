"""The sweep report: a real tiny `gmtiflow -m` sweep (callback), the CLI, failed jobs."""
import json
import os
import shutil
import subprocess
import sys

import pytest

from gmtiflow.report.sweep_report import SweepReportError, collect_jobs, swept_keys

from .conftest import page_count, pixel_std, render_png


def _run(cmd, cwd):
    env = dict(os.environ, HYDRA_FULL_ERROR="0")
    return subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, env=env, timeout=300)


def _sweep(tmp_path, name, *overrides):
    sweep_dir = tmp_path / name
    proc = _run([sys.executable, "-m", "gmtiflow.cli", "-m", f"hydra.sweep.dir={sweep_dir}",
                 "progress=false", "report=none", *overrides], tmp_path)
    return sweep_dir, proc


def _report_cli(*args, cwd):
    return _run([sys.executable, "-m", "gmtiflow.report.cli", *map(str, args)], cwd)


@pytest.fixture(scope="module")
def sweep(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("sweep")
    sweep_dir, proc = _sweep(tmp, "sw", "scene.duration_s=20", "fidelity=fast,standard", "seed=1,2")
    assert proc.returncode == 0, proc.stderr
    return sweep_dir


def test_multirun_ends_with_a_comparison_pdf_and_timing(sweep, tmp_path):
    pdf = sweep / "sweep_report.pdf"
    assert pdf.is_file()
    # title+table, results vs fidelity, speed vs accuracy (fidelity presets swept)
    assert page_count(pdf) == 3
    for job in sorted(p for p in sweep.iterdir() if p.is_dir()):
        timing = json.loads((job / "timing.json").read_text())
        assert timing["status"] == "COMPLETED" and timing["run_file_s"] > 0
    jobs = collect_jobs([sweep])
    assert [j.ok for j in jobs] == [True] * 4
    assert swept_keys(jobs) == ["fidelity", "seed"]
    assert all(j.values["wall_s"] > 0 for j in jobs)
    pngs = render_png(pdf, tmp_path / "s", 1, 3)
    assert all(pixel_std(p) > 0.03 for p in pngs)


def test_cli_on_run_dirs(sweep, tmp_path, capsys):
    from gmtiflow.report.cli import main
    out = tmp_path / "cmp.pdf"
    assert main([str(sweep / "0"), str(sweep / "3"), "-o", str(out), "--runs", "-q"]) == 0
    assert out.is_file() and (sweep / "0" / "report.pdf").is_file()
    assert page_count(out) == 3        # table, results vs fidelity (seed is the spread), speed
    assert main([str(tmp_path), "-q"]) == 1  # no job dirs here
    assert "no run or job directories" in capsys.readouterr().err


def test_cli_on_a_sweep_with_a_failed_job(tmp_path):
    sweep_dir, proc = _sweep(tmp_path, "fail", "scene.duration_s=20,-5")
    assert proc.returncode != 0                           # Hydra: a job failed
    assert not (sweep_dir / "sweep_report.pdf").exists()   # on_multirun_end was not called
    proc = _report_cli(sweep_dir, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    pdf = sweep_dir / "sweep_report.pdf"
    assert pdf.is_file()
    jobs = collect_jobs([sweep_dir])
    assert [j.status for j in jobs] == ["COMPLETED", "FAILED"]
    assert "duration_s" in jobs[1].error and "must be a finite number > 0" in jobs[1].error
    # table, results vs scene.duration_s, failed jobs
    assert page_count(pdf) == 3
    if shutil.which("pdftotext"):
        text = subprocess.run(["pdftotext", str(pdf), "-"], capture_output=True, text=True).stdout
        assert "Failed jobs (1 of 2)" in text and "FAILED" in text


def test_failed_job_without_timing_uses_its_log(tmp_path):
    job = tmp_path / "7"
    (job / ".hydra").mkdir(parents=True)
    (job / ".hydra" / "overrides.yaml").write_text("- sensor=wide_fov\n")
    (job / "gmtiflow.log").write_text("[2026][gmtiflow][ERROR] - boom: bad thing\n")
    jobs = collect_jobs([tmp_path])
    assert jobs[0].status == "FAILED" and jobs[0].error == "boom: bad thing"
    assert jobs[0].overrides == {"sensor": "wide_fov"}
    with pytest.raises(SweepReportError):
        collect_jobs([job / ".hydra"])
