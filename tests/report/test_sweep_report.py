"""The sweep report: a real tiny `gmtiflow -m` sweep (callback), the CLI, failed jobs."""
import json
from pathlib import Path
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


@pytest.mark.slow
def test_multirun_ends_with_a_comparison_pdf_and_timing(sweep, tmp_path):
    pdf = sweep / "sweep_report.pdf"
    assert pdf.is_file()
    # title+table, results vs fidelity, paired-by-seed deltas, speed vs accuracy
    assert page_count(pdf) == 4
    for job in sorted(p for p in sweep.iterdir() if p.is_dir()):
        timing = json.loads((job / "timing.json").read_text())
        assert timing["status"] == "COMPLETED" and timing["run_file_s"] > 0
    jobs = collect_jobs([sweep])
    assert [j.ok for j in jobs] == [True] * 4
    assert swept_keys(jobs) == ["fidelity", "seed"]
    assert all(j.values["wall_s"] > 0 for j in jobs)
    pngs = render_png(pdf, tmp_path / "s", 1, 4)
    assert all(pixel_std(p) > 0.03 for p in pngs)


@pytest.mark.slow
def test_cli_on_run_dirs(sweep, tmp_path, capsys):
    from gmtiflow.report.cli import main
    out = tmp_path / "cmp.pdf"
    assert main([str(sweep / "0"), str(sweep / "3"), "-o", str(out), "--runs", "-q"]) == 0
    assert out.is_file() and (sweep / "0" / "report.pdf").is_file()
    assert page_count(out) == 3        # table, results vs fidelity (seed is the spread), speed
    assert main([str(tmp_path), "-q"]) == 1  # no job dirs here
    assert "no run or job directories" in capsys.readouterr().err


@pytest.mark.slow
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


def test_mean_ci95_and_paired_deltas():
    import math

    import numpy as np
    from scipy import stats

    from gmtiflow.report.sweep_report import Job, mean_ci95, paired_deltas, parameter_figure
    m, h, n = mean_ci95([1.0, 2.0, 4.0, float("nan")])
    ref = stats.t.interval(0.95, 2, loc=np.mean([1, 2, 4]), scale=stats.sem([1, 2, 4]))
    assert n == 3 and m == 7 / 3 and h == pytest.approx((ref[1] - ref[0]) / 2)
    assert mean_ci95([5.0]) == (5.0, 0.0, 1) and math.isnan(mean_ci95([])[0])

    def job(pfa, seed, v):
        return Job(dir=Path("."), label=f"{pfa}-{seed}", status="COMPLETED",
                   overrides={"sensor.pfa": pfa, "seed": str(seed)}, values={"detections": v})
    # seeds differ a lot, the paired change is exactly +10 on every seed
    jobs = [job(p, s, base + (10 if p == "1e-4" else 0))
            for s, base in ((1, 100.0), (2, 300.0), (3, 700.0)) for p in ("1e-6", "1e-4")]
    base, deltas = paired_deltas(jobs, "sensor.pfa", [], "detections")
    assert base == "1e-6" and list(deltas[()]["1e-4"]) == [10.0, 10.0, 10.0]
    fig = parameter_figure(jobs, "sensor.pfa", ["sensor.pfa", "seed"])
    assert fig.axes[0].get_xscale() == "log"                 # P_FA on a log axis
    cat = [Job(dir=Path("."), label=str(i), status="COMPLETED",
               overrides={"fidelity": f, "seed": str(s)}, values={"detections": float(i)})
           for i, (f, s) in enumerate([("fast", 1), ("full", 1), ("fast", 2), ("full", 2)])]
    fig = parameter_figure(cat, "fidelity", ["fidelity", "seed"])
    from matplotlib.patches import Rectangle
    bars = [p for p in fig.axes[0].patches if isinstance(p, Rectangle)]
    assert len(bars) == 2                                    # categories as bars


def test_many_swept_keys_split_the_table_and_empty_dirs_are_named_once(tmp_path):
    from gmtiflow.report.sweep_report import (MAX_TABLE_COLUMNS, Job, RESULTS, skipped_dirs,
                                              table_figures)
    keys = [f"sensor.key_{i}" for i in range(8)]
    jobs = [Job(dir=tmp_path / str(i), label=str(i), status="COMPLETED",
                overrides={k: str(i * 10 + n) for n, k in enumerate(keys)},
                values={k: float(i) for k, _, _ in RESULTS}) for i in range(30)]
    jobs[3].status = "FAILED"
    assert len(keys) + 2 + len(RESULTS) > MAX_TABLE_COLUMNS
    figs = table_figures(jobs, keys, [tmp_path], rows_per_page=22, skipped=["5", "9"])
    assert len(figs) == 4                  # (parameters, results) x 2 pages of rows
    headers = []
    for fig in figs:
        (table,) = [t for ax in fig.axes for t in ax.tables]
        cells = table.get_celld()
        ncols = max(c for _, c in cells) + 1
        headers.append([cells[0, c].get_text().get_text().replace("\n", "") for c in range(ncols)])
        assert ncols <= MAX_TABLE_COLUMNS
    assert headers[0][:3] == ["job", "status", "sensor.key_0"] and len(headers[0]) == 10
    assert headers[2][:2] == ["job", "status"] and "sensor.key_0" not in headers[2]
    titles = [" ".join(t.get_text() for t in f.texts) for f in figs]
    assert sum("not jobs (no run.h5 and no .hydra/, left out): 5, 9" in t for t in titles) == 1
    for name in ("0", "empty"):
        (tmp_path / name).mkdir()
    (tmp_path / "0" / ".hydra").mkdir()
    assert skipped_dirs([tmp_path]) == ["empty"]
