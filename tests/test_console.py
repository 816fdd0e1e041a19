"""What the ``gmtiflow`` command says: a short --help, a quiet run with a summary at the end,
INFO lines only with -v, and no empty run directory after a config error."""
import io
import os
import subprocess
import sys
from pathlib import Path

from gmtiflow import bars, console


def _cli(cwd: Path, *args):
    env = dict(os.environ, HYDRA_FULL_ERROR="0")
    return subprocess.run([sys.executable, "-m", "gmtiflow.cli", *args], cwd=cwd,
                          capture_output=True, text=True, env=env, timeout=300)


def test_help_lists_every_group_on_one_line_without_the_config_dump(tmp_path):
    proc = _cli(tmp_path, "--help")
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    groups = console.config_groups()
    assert {"sensor", "roadmap", "vehicles", "tracker", "report"} <= set(groups)
    for group, options in groups.items():
        assert f"{group}: {', '.join(options)}" in lines
    assert "wide_fov" in groups["sensor"]
    assert len(lines) < 60            # Hydra's default help printed the ~500-line config
    assert "peak_power_w:" not in proc.stdout      # no YAML dump
    assert not list(tmp_path.iterdir())            # --help runs nothing, writes nothing


def test_run_prints_a_summary_and_keeps_info_in_the_log(tmp_path):
    proc = _cli(tmp_path, "hydra.run.dir=run", "scene.duration_s=20", "report.enabled=false",
                "export=csv")
    assert proc.returncode == 0, proc.stderr
    out = proc.stdout
    nums = console.summary_numbers(tmp_path / "run" / "run.h5")
    assert f"detections  {nums['detections']:.0f}: {nums['targets']:.0f} on targets, " \
           f"{nums['false_alarms']:.0f} false alarms, {nums['merged']:.0f} merged" in out
    assert f"P_D achieved {nums['pd_achieved']:.3f}" in out
    assert "tracks" in out and "OSPA" in out and "run.h5" in out and "detections.csv" in out
    assert "stage " not in proc.stderr and "cache:" not in proc.stderr       # quiet console
    log = (tmp_path / "run" / "gmtiflow.log").read_text()
    assert "stage sensor" in log                                             # all in the log
    verbose = _cli(tmp_path, "-v", "hydra.run.dir=run2", "scene.duration_s=20",
                   "report.enabled=false", "export=none")
    assert verbose.returncode == 0 and "stage sensor" in verbose.stderr


def test_summary_counts_match_the_run_file(tmp_path):
    import numpy as np

    from gmtiflow import pipeline, store
    from gmtiflow.compose import compose
    path = pipeline.run(compose(["progress=false", "scene.duration_s=20", "export=none",
                                 "report.enabled=false", "clutter=lake"]), tmp_path)
    nums = console.summary_numbers(path)
    det = store.read_table(path, "detections")
    assert nums["false_alarms"] == np.sum(det["truth_id"] < 0) > 0
    assert nums["targets"] + nums["false_alarms"] == len(det["truth_id"])
    assert nums["merged"] == np.sum(det["merged"])


def test_missing_map_names_the_key_and_the_data_dir_and_leaves_no_run_dir(tmp_path):
    env = {k: v for k, v in os.environ.items() if k != "GMTIFLOW_DATA_DIR"}
    proc = subprocess.run([sys.executable, "-m", "gmtiflow.cli", "experiment=monaco",
                           "hydra.run.dir=outputs/2026-01-02/00-00-00"], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 1
    assert "roadmap.path" in proc.stderr and "GMTIFLOW_DATA_DIR" in proc.stderr, proc.stderr
    assert not (tmp_path / "outputs" / "2026-01-02").exists()


def test_config_error_leaves_no_run_directory(tmp_path):
    proc = _cli(tmp_path, "hydra.run.dir=outputs/2026-01-01/00-00-00", "sensor.peak_power_w=-1")
    assert proc.returncode == 1
    assert "sensor.peak_power_w" in proc.stderr and "Traceback" not in proc.stderr
    assert not (tmp_path / "outputs" / "2026-01-01").exists()     # run dir and empty date dir


def test_discard_keeps_a_directory_with_a_log_worth_keeping(tmp_path):
    run = tmp_path / "run"
    (run / ".hydra").mkdir(parents=True)
    (run / "outputs.json").write_text('{"complete": false, "planned": ["run.h5"]}')
    (run / "gmtiflow.log").write_text("[..][gmtiflow.pipeline][INFO] - stage roads   0.1 s\n"
                                      "[..][gmtiflow][ERROR] - boom\n")
    assert not console.discard_failed_run_dir(run) and run.is_dir()
    (run / "gmtiflow.log").write_text("[..][gmtiflow.pipeline][INFO] - run pid=1 seed=1\n"
                                      "[..][gmtiflow][ERROR] - boom\n")
    (run / "notes.txt").write_text("mine")
    assert not console.discard_failed_run_dir(run) and run.is_dir()      # a file of the user's
    (run / "notes.txt").unlink()
    assert console.discard_failed_run_dir(run) and not run.exists()
    assert tmp_path.is_dir()          # not a Hydra date dir: the parent stays


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_progress_bar_only_on_a_terminal_and_only_for_slow_steps():
    quiet, slow, fast = io.StringIO(), _Terminal(), _Terminal()
    assert list(console.progress(range(3), "export", "file", file=quiet, delay_s=0)) == [0, 1, 2]
    assert quiet.getvalue() == ""                        # a pipe or a log: nothing
    list(console.progress(range(3), "export", "file", file=slow, delay_s=0))
    assert "export:" in slow.getvalue() and "/3 [" in slow.getvalue()   # the bar
    list(console.progress(range(3), "report", "page", file=fast))   # done within 2 s
    assert fast.getvalue() == ""


def test_stage_bars_only_when_asked_for_and_on_a_terminal(monkeypatch):
    items = [1, 2, 3]
    monkeypatch.setattr(sys, "stderr", io.StringIO())
    assert bars.stage_progress(items, True) is items            # a pipe: no bar at all
    bar = bars.stage_counter(3, True)
    bar.update(3), bar.close()
    assert sys.stderr.getvalue() == ""
    term = _Terminal()
    monkeypatch.setattr(sys, "stderr", term)
    assert bars.stage_progress(items, False) is items           # progress=false
    assert list(bars.stage_progress(items, True, desc="truth table")) == items
    assert "truth table:" in term.getvalue() and "3/3" in term.getvalue()
    bar = bars.stage_counter(5, True, desc="truth", file=term)
    bar.update(5), bar.close()
    assert "truth:" in term.getvalue() and "5/5" in term.getvalue()


def test_a_run_without_a_terminal_never_imports_tqdm(tmp_path):
    """A bar that is not shown costs nothing: tqdm (and the multiprocessing lock it makes)
    is never imported by a run whose stderr is a pipe, progress on or off."""
    code = ("import sys\n"
            "from gmtiflow.compose import compose\n"
            "from gmtiflow import pipeline\n"
            "for p in ('true', 'false'):\n"
            "    pipeline.run(compose(['scene.duration_s=30', 'report=none', 'export=none',\n"
            "                          'cache.enabled=false', f'progress={p}']), sys.argv[1] + p)\n"
            "print(sorted(m for m in sys.modules if m.split('.')[0] in\n"
            "             ('tqdm', 'multiprocessing')))\n")
    proc = subprocess.run([sys.executable, "-c", code, str(tmp_path / "run")],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.strip().splitlines()[-1] == "[]"


def test_summary_counts_only_vehicles_that_appear(tmp_path):
    """A vehicle that starts after the scene's end never appears: the summary's vehicle count
    is of those that do, and says how many of the listed ones never appear."""
    from gmtiflow import pipeline
    from gmtiflow.compose import compose
    from gmtiflow.store import read_table
    cfg = compose(["progress=false", "scene.duration_s=20", "export=none", "report=none",
                   "tracker=none", "metrics.enabled=false", "vehicles=random",
                   "vehicles.random.count=6", "vehicles.random.start_time_min_s=0",
                   "vehicles.random.start_time_max_s=40"])
    path = pipeline.run(cfg, tmp_path)
    start = read_table(path, "vehicles")["start_time_s"]
    appear = int((start <= 20.0).sum())
    assert 0 < appear < len(start)                # the seed gives both kinds
    nums = console.summary_numbers(path)
    assert nums["vehicles"] == appear and nums["vehicles_listed"] == len(start)
    text = console.run_summary(path, tmp_path)
    assert f"({appear} of {len(start)} vehicles appear in the scene)" in text
