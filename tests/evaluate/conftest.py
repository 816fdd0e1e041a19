"""A short default-scene run and its baseline tracks as CSV, shared by the CLI tests of
``gmtiflow-evaluate`` and ``gmtiflow-report --tracks`` (one run per test module)."""
import pytest

from gmtiflow import convert, pipeline
from tests.conftest import compose_app

OVERRIDES = ["scene.duration_s=40", "fidelity.truth_output_dt_s=1.0", "progress=false"]


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    return pipeline.run(compose_app(OVERRIDES), tmp_path_factory.mktemp("run"))


@pytest.fixture(scope="module")
def tracks_csv(run, tmp_path_factory):
    """The run's own /tracks exported to a track CSV, as an external tracker would write it."""
    path = tmp_path_factory.mktemp("tracks") / "baseline.csv"
    assert convert.main([str(run), "--to", "csv", "--table", "tracks", "-o", str(path)]) == 0
    return path
