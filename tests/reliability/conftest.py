"""Fixtures of the reliability tests."""
from __future__ import annotations

import shutil

import pytest

from gmtiflow import pipeline
from gmtiflow.compose import compose


@pytest.fixture(scope="session")
def small_run_dir(tmp_path_factory):
    """A complete 10 s run (run.h5 + tracks.csv), made once: copy it before changing it."""
    d = tmp_path_factory.mktemp("small_run")
    pipeline.run(compose(["scene.duration_s=10", "export=csv", "report=none",
                          "export.csv_tables=[detections,truth,tracks]",
                          "progress=false", "cache.enabled=false"]), d)
    return d


@pytest.fixture
def run_copy(small_run_dir, tmp_path):
    """A private copy of the small run's directory."""
    d = tmp_path / "run"
    shutil.copytree(small_run_dir, d)
    return d
