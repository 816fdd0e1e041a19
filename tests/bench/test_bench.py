"""The benchmark end to end at CI size, as a user runs it: ``gmtiflow-bench --quick``.

Every scenario × two trackers (``nn_kalman`` and ``nn_kalman_coast``) × two seeds through the
joblib launcher, in a subprocess; then the verdict files, the stage cache (a second tracker
recomputes only tracking and scoring), every scenario's challenge in these runs, and the PDF
rendered to PNG.  An external command tracker is scored on a smaller sweep.
"""
import csv
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from gmtiflow.bench import challenges, collect, scenarios
from gmtiflow.compose import compose
from gmtiflow.config import sensor_slots
from gmtiflow.bench.metrics import scenario_metrics
from tests.report.conftest import page_count, pixel_std, render_png

pytest.importorskip("hydra_plugins.hydra_joblib_launcher")

HERE = Path(__file__).parent
SEEDS, TRACKERS = (1, 2), ("nn_kalman", "nn_kalman_coast")


def bench(tmp_path, *args, timeout=900):
    env = dict(os.environ, HYDRA_FULL_ERROR="1")
    cmd = [sys.executable, "-c", "from gmtiflow.bench.cli import console; console()", *args,
           f"cache.dir={tmp_path / 'cache'}"]
    proc = subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True, env=env,
                          timeout=timeout)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return proc


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("bench")
    bench(tmp, "--quick", "-j", "2", "-o", str(tmp / "sweep"))
    return tmp / "sweep"


@pytest.mark.slow
def test_quick_bench_writes_one_row_per_scenario_metric_and_tracker(quick):
    rows = list(csv.DictReader((quick / "bench_results.csv").open()))
    expected = {(s, m, t) for s in scenarios.SCENARIOS for m in scenario_metrics(s)
                for t in TRACKERS}
    assert {(r["scenario"], r["metric"], r["tracker"]) for r in rows} == expected
    assert {r["seeds"] for r in rows} == {"1 2"}
    assert {r["verdict"] for r in rows if r["tracker"] == "nn_kalman"} == {"reference"}
    assert {r["verdict"] for r in rows if r["tracker"] != "nn_kalman"} <= {"better", "worse",
                                                                            "tie"}
    md = (quick / "bench_results.md").read_text()
    for s in scenarios.SCENARIOS:
        assert f"\n| {s} | " in md and f"\n## {s}\n" in md


@pytest.mark.slow
def test_second_tracker_reuses_truth_and_sensor_from_the_cache(quick):
    logs = "".join(p.read_text() for p in sorted(quick.glob("*/gmtiflow.log")))
    runs = len(scenarios.SCENARIOS) * len(SEEDS)
    # one truth per run; one sensor stage per sensor of the scene (two_sensors has two)
    sensor_stages = len(SEEDS) * sum(
        len(sensor_slots(compose([f"experiment=challenge/{s}"]))) for s in scenarios.SCENARIOS)
    for stage, computed in (("truth", runs), ("sensor", sensor_stages)):
        assert logs.count(f"cache miss {stage}") == computed, stage
        assert logs.count(f"cache hit {stage}") == computed * (len(TRACKERS) - 1), stage
    assert logs.count("stage track ") == runs * len(TRACKERS)


@pytest.mark.slow
def test_every_challenge_occurs_in_the_benchmark_runs(quick):
    records = [r for r in collect.collect([quick]) if r.tracker == TRACKERS[0]]
    assert sorted((r.scenario, r.seed) for r in records) == sorted(
        (s, seed) for s in scenarios.SCENARIOS for seed in SEEDS)
    for r in records:
        result = challenges.check(r.scenario, r.dir / "run.h5")
        assert result.occurred, f"{r.scenario} seed {r.seed}: {result.summary}"


@pytest.mark.slow
def test_comparison_pdf_renders_a_summary_and_a_page_per_scenario(quick, tmp_path):
    pdf = quick / "bench_report.pdf"
    assert page_count(pdf) == 1 + len(scenarios.SCENARIOS)
    pngs = render_png(pdf, tmp_path / "page", 1, 2)
    assert len(pngs) == 2
    for png in pngs:
        assert pixel_std(png) > 0.05, png     # not blank: tables, bars, text


@pytest.mark.slow
def test_external_command_tracker_is_scored_like_the_same_tracker_in_process(tmp_path):
    """The command runs the baseline on the blind CSVs: its scores equal tracker=nn_kalman's."""
    tracker = (f"ext={{python}} {HERE / 'command_tracker.py'} {{detections}} {{dwells}} "
               f"{{scene}} {{tracks}}")
    bench(tmp_path, "-j", "1", "--launcher", "basic", "-o", str(tmp_path / "sweep"),
          "--command", tracker, "tracker=nn_kalman", "experiment=challenge/tunnel", "seed=1,2")
    det = (tmp_path / "sweep/external/ext/tunnel-1/detections.csv").read_text().splitlines()[0]
    assert "truth_id" not in det and "true_" not in det and "merged" not in det
    rows = list(csv.DictReader((tmp_path / "sweep/bench_results.csv").open()))
    ext = {r["metric"]: r for r in rows if r["tracker"] == "ext"}
    ref = {r["metric"]: r for r in rows if r["tracker"] == "nn_kalman"}
    assert set(ext) == set(scenario_metrics("tunnel"))
    for metric, row in ext.items():
        assert row["values"] == ref[metric]["values"], metric
        assert row["verdict"] == "tie"


def test_external_command_gets_each_dwells_reports_by_range_not_by_truth(tmp_path):
    """run.h5 lists a dwell's reports by vehicle id, then its false alarms; the blind
    detections.csv an external tracker reads lists them by measured slant range, det_ids
    handed out in that order, as the tracker protocol's batches do."""
    from gmtiflow import formats, pipeline, store
    from gmtiflow.bench import external
    from gmtiflow.evaluate.protocol import batches
    from tests.evaluate.helpers import check_truth_free_order
    run = pipeline.run(compose(["scene.duration_s=60", "export=none", "report=none",
                                "progress=false", "cache.enabled=false", "tracker=none",
                                "metrics.enabled=false"]), tmp_path / "run")
    paths = external.write_blind_inputs(run, tmp_path / "in", "default", 1)
    seen = formats.read_detections_csv(paths["detections"])
    ref = store.read_table(run, "detections")
    mixed, truth_ordered = check_truth_free_order(seen, ref)
    assert mixed > 10 and truth_ordered < mixed / 2, (mixed, truth_ordered)
    # the same reports, order and det_ids as the protocol's batches
    got = [b.detections for b in batches(ref, store.read_table(run, "dwells"))]
    for c in ("det_id", "dwell_id", "range_m", "azimuth_rad", "x_m", "y_m"):
        assert np.array_equal(seen[c], np.concatenate([b[c] for b in got])), c


def test_failing_external_command_is_one_clear_error(tmp_path):
    from gmtiflow import pipeline
    from gmtiflow.bench import external
    from gmtiflow.compose import compose
    run = pipeline.run(compose(["experiment=challenge/tunnel", "scene.duration_s=20",
                                "export=none", "report=none", "progress=false",
                                "cache.enabled=false"]), tmp_path / "run")
    with pytest.raises(external.ExternalTrackerError, match=r"'bad' on tunnel seed 1: exit "
                                                            r"status 3: oops"):
        external.run_one("bad", "echo oops >&2; exit 3", run, tmp_path / "x", "tunnel", 1)
    with pytest.raises(external.ExternalTrackerError, match="wrote no track file"):
        external.run_one("lazy", "true", run, tmp_path / "y", "tunnel", 1)
    with pytest.raises(external.ExternalTrackerError, match=r"bad placeholder.*\{tracks\}"):
        external.run_one("typo", "x {trakcs}", run, tmp_path / "z", "tunnel", 1)
