"""Outputs are all-or-nothing and never mix runs (docs/reliability.md, "Outputs" and "Re-runs").

* A ``gmtiflow`` run killed with SIGKILL at several moments leaves nothing that reads as a
  complete run unless it is one: ``store.open_run`` raises StoreError or gives a complete run of
  the killed run's own seed; exports and the report exist only beside a complete run file and
  parse; the manifest ``outputs.json`` is valid JSON and, when it says complete, true.
* A re-run into the same directory removes the files the earlier run claimed, so a re-run with
  ``export=none`` (or one that fails) leaves no old exports or run file that look like its own.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from gmtiflow.formats import csvtable, geojson, stanag4607, xmldoc
from gmtiflow import pipeline, store
from gmtiflow.compose import compose
from gmtiflow.errors import RoadMapError, StoreError

SCENE = ["scene.duration_s=30", "progress=false", "export=all", "report=default"]
QUIET = ["report=none", "progress=false", "cache.enabled=false"]
EXPORT_READERS = {
    "detections.4607": stanag4607.read_4607, "detections.xml": xmldoc.read_xml,
    "scene.geojson": geojson.read_geojson, "detections.csv": csvtable.read_detections_csv,
    "truth.csv": csvtable.read_truth_csv, "tracks.csv": csvtable.read_tracks_csv,
}


def launch(out: Path, seed: int, kill_at: str | float | None):
    """Run the CLI into ``out`` and SIGKILL it (this process only) at ``kill_at``: a number of
    seconds after the run starts, or the moment its log shows a line containing that text;
    None: let it finish.  Returns (return code, launch time).
    """
    cmd = [sys.executable, "-m", "gmtiflow.cli", "-v", f"hydra.run.dir={out}", f"seed={seed}",
           *SCENE]   # -v: the INFO lines the kill points wait for go to the console too
    launched = time.time()
    proc = subprocess.Popen(cmd, stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True,
                            cwd=out.parent, env=dict(os.environ, HYDRA_FULL_ERROR="1"))
    started, marker = threading.Event(), threading.Event()
    lines = []

    def read():
        for line in proc.stderr:
            if isinstance(kill_at, str) and kill_at in line:
                proc.kill()                              # at once, before reading on
                marker.set()
            lines.append(line)
            if "run pid=" in line:
                started.set()
        started.set()
        marker.set()

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    assert started.wait(120), "".join(lines)
    if isinstance(kill_at, (int, float)):
        try:
            proc.wait(timeout=kill_at)
        except subprocess.TimeoutExpired:
            proc.kill()
    rc = proc.wait(timeout=300)
    reader.join(10)
    if kill_at is None:
        assert rc == 0, "".join(lines[-20:])
    return rc, launched


def check_dir(out: Path, seed: int, launched: float, ignore=()) -> str:
    """The directory's invariants after a run ended, however it ended; returns its state."""
    complete = False
    for h5 in [*out.glob("*.h5"), *out.glob(".*.partial")]:
        try:
            with store.open_run(h5) as f:
                assert h5.name == pipeline.RUN_FILE, f"{h5.name} reads as a complete run"
                assert int(f.attrs["seed"]) == seed, "a complete run.h5 of an earlier run"
                complete = True
        except StoreError:
            pass
    products = [out / n for n in [*EXPORT_READERS, "report.pdf"]
                if (out / n).exists() and n not in ignore]
    if not complete:
        assert not products, f"outputs without a complete run file: {products}"
    for path in products:
        assert path.stat().st_mtime >= launched - 1, f"{path.name} left by an earlier run"
        if path.name == "report.pdf":
            data = path.read_bytes()
            assert data.startswith(b"%PDF") and data.rstrip().endswith(b"%%EOF")
        else:
            EXPORT_READERS[path.name](path)             # parses: FormatError would fail here
    manifest = out / pipeline.MANIFEST
    if manifest.exists():
        doc = json.loads(manifest.read_text())          # never a torn JSON file
        if doc["complete"]:
            assert complete and doc["seed"] == seed
            for f in doc["files"]:
                assert (out / f["name"]).stat().st_size == f["bytes"]
    return "complete" if complete else "none"


@pytest.mark.slow
def test_sigkill_at_any_moment_leaves_no_output_that_reads_as_complete(tmp_path):
    out = tmp_path / "run"
    out.mkdir()
    (out / "detections.xml").write_text("<left over by hand/>")   # unclaimed: must not count
    states = []
    # Kill points: 50 ms into the run, in the scene stages, while run.h5 is being written
    # (truth written, sensor not yet), right after the commit while exports are written,
    # during the report.  All into one directory: each is also a killed re-run.
    points = [0.05, "stage truth_table", "wrote ", "export: wrote",
              "stage export"]
    for i, point in enumerate(points):
        seed = 101 + i
        rc, launched = launch(out, seed=seed, kill_at=point)
        states.append((point, rc, check_dir(out, seed, launched, ignore={"detections.xml"}
                                            if i == 0 else ())))
    print(states)
    assert all(rc == -9 for _, rc, _ in states), states
    assert [s for *_, s in states] == ["none"] * 2 + ["complete"] * 3, states
    _, launched = launch(out, seed=200, kill_at=None)           # a clean re-run tidies up
    assert check_dir(out, 200, launched) == "complete"
    assert not list(out.glob(".*.partial*")) and not list(out.glob("*.part"))


def test_rerun_with_export_none_removes_the_earlier_exports(tmp_path):
    cfg = compose(["scene.duration_s=10", "export=all", *QUIET,
                   "export.csv_tables=[detections,truth,tracks]"])
    pipeline.run(cfg, tmp_path)
    (tmp_path / "notes.txt").write_text("mine")
    first = {p.name for p in tmp_path.iterdir()}
    assert {"detections.4607", "detections.xml", "truth.csv", "run.h5"} <= first
    cfg2 = compose(["scene.duration_s=10", "export=none", *QUIET,
                    "seed=2"])
    pipeline.run(cfg2, tmp_path)
    left = {p.name for p in tmp_path.iterdir()}
    assert left == {"run.h5", pipeline.MANIFEST, "notes.txt"}, left   # the user's file stays
    doc = json.loads((tmp_path / pipeline.MANIFEST).read_text())
    assert doc["complete"] and [f["name"] for f in doc["files"]] == ["run.h5"]


def test_failed_rerun_leaves_no_run_file_of_the_earlier_run(tmp_path):
    pipeline.run(compose(["scene.duration_s=10", "export=csv", *QUIET]), tmp_path)
    assert (tmp_path / "run.h5").is_file()
    (tmp_path / "empty.osm").write_text("<osm version='0.6'></osm>")
    bad = compose(["scene.duration_s=10", "export=csv", *QUIET,
                   "roadmap=osm", f"roadmap.path={tmp_path / 'empty.osm'}"])
    with pytest.raises(RoadMapError):
        pipeline.run(bad, tmp_path)
    assert {p.name for p in tmp_path.iterdir()} == {"empty.osm", pipeline.MANIFEST}
    assert json.loads((tmp_path / pipeline.MANIFEST).read_text())["complete"] is False


def test_first_run_into_a_folder_leaves_unclaimed_files_alone(tmp_path):
    (tmp_path / "truth.csv").write_text("the user's own truth\n")
    pipeline.run(compose(["scene.duration_s=5", "export=none", *QUIET]), tmp_path)
    assert (tmp_path / "truth.csv").read_text() == "the user's own truth\n"
