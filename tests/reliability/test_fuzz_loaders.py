"""gmtiflow's own file loaders (OSM, GeoJSON road map, RCS table, ASCII-grid DEM) under a short
fixed fuzz budget: only InputFileError (or a subclass) may escape, and whatever a loader accepts
must be usable data (finite, sorted, edges on known nodes).  Long runs: benchmarks/fuzz.py."""
from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

_NAME = "gmtiflow_benchmarks_fuzz"
fuzz = sys.modules.get(_NAME)
if fuzz is None:
    _spec = importlib.util.spec_from_file_location(
        _NAME, Path(__file__).resolve().parents[2] / "benchmarks" / "fuzz.py")
    fuzz = importlib.util.module_from_spec(_spec)
    sys.modules[_NAME] = fuzz
    _spec.loader.exec_module(fuzz)

LOADERS = ["osm", "roads_geojson", "rcs", "dem_ascii"]
CI_EXAMPLES = 100
CI_MUTATIONS = 300


@pytest.mark.parametrize("target", LOADERS)
def test_seeds_are_accepted(target):
    """The fuzz seeds are valid files, so mutations start from inputs that reach deep code."""
    seeds, call, _ = fuzz.TARGETS[target]
    for seed in seeds():
        call(seed)


@pytest.mark.parametrize("target", LOADERS)
def test_hypothesis_mutations_raise_only_input_file_error(target):
    seed = fuzz.TARGETS[target][0]()[0]
    count = [0]

    @settings(max_examples=CI_EXAMPLES, deadline=None, derandomize=True, database=None,
              suppress_health_check=list(HealthCheck))
    @given(cut=st.integers(0, len(seed)), pos=st.integers(0, len(seed)),
           new=st.sampled_from(fuzz._TOKENS) | st.binary(max_size=6), drop=st.integers(0, 16))
    def one(cut, pos, new, drop):
        b = bytearray(seed)
        b[pos:pos + drop] = new
        data = bytes(b[:max(cut, pos + len(new))])
        count[0] += 1
        exc = fuzz.run_case(target, data)
        assert exc is None, f"{type(exc).__name__}: {exc} on {data[:300]!r}"

    one()
    assert count[0] >= CI_EXAMPLES // 2


@pytest.mark.parametrize("target", LOADERS)
def test_seeded_mutations_raise_only_input_file_error(target):
    assert fuzz.fuzz(target, CI_MUTATIONS, seed=20261121) == (CI_MUTATIONS, 0)


def test_atheris_target_runs_when_installed(tmp_path):
    """Coverage-guided fuzzing is optional (extra ``fuzz``); CI does not depend on it."""
    pytest.importorskip("atheris")
    import subprocess
    proc = subprocess.run([sys.executable, str(fuzz.__file__), "--atheris", "csv", "--",
                           "-runs=300", f"-artifact_prefix={tmp_path}/"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "Done 300 runs" in proc.stderr
