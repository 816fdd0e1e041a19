"""The 4607, XML, CSV and GeoJSON readers under hypothesis: for a short fixed budget, mutated
and random inputs raise FormatError or read cleanly, nothing else (docs/reliability.md).

The long runs are ``python benchmarks/fuzz.py`` (and ``--atheris`` where atheris installs).
"""
from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

_spec = importlib.util.spec_from_file_location(
    "gmtiflow_benchmarks_fuzz", Path(__file__).resolve().parents[2] / "benchmarks" / "fuzz.py")
fuzz = sys.modules.get("gmtiflow_benchmarks_fuzz")
if fuzz is None:
    fuzz = importlib.util.module_from_spec(_spec)
    sys.modules["gmtiflow_benchmarks_fuzz"] = fuzz
    _spec.loader.exec_module(fuzz)

READERS = ["4607", "xml", "csv", "csv_truth", "geojson"]
CI_EXAMPLES = 150          # hypothesis cases per reader in CI (benchmarks/fuzz.py: long runs)
CI_MUTATIONS = 400         # seeded mutation cases per reader in CI

edits = st.lists(st.tuples(st.integers(0, 1 << 16), st.integers(0, 64), st.binary(max_size=8)),
                 max_size=6)


def apply_edits(seed: bytes, cut: int, ops) -> bytes:
    """Hypothesis-driven mutation: truncate at ``cut``, then replace spans with given bytes."""
    b = bytearray(seed[: cut % (len(seed) + 1)] if cut >= 0 else seed)
    for pos, length, new in ops:
        i = pos % (len(b) + 1)
        b[i:i + length] = new
    return bytes(b)


@pytest.mark.parametrize("target", READERS)
def test_hypothesis_mutations_raise_only_format_error(target):
    seeds = fuzz.TARGETS[target][0]()
    count = [0]

    @settings(max_examples=CI_EXAMPLES, deadline=None, derandomize=True, database=None,
              suppress_health_check=list(HealthCheck))
    @given(which=st.integers(0, len(seeds) - 1), cut=st.integers(-1, 1 << 16), ops=edits,
           raw=st.one_of(st.none(), st.binary(max_size=512)))
    def one(which, cut, ops, raw):
        data = raw if raw is not None else apply_edits(seeds[which], cut, ops)
        count[0] += 1
        exc = fuzz.run_case(target, data)
        assert exc is None, f"{type(exc).__name__}: {exc} on {data[:200]!r}"

    one()
    assert count[0] >= CI_EXAMPLES // 2


@pytest.mark.parametrize("target", READERS)
def test_seeded_mutations_raise_only_format_error(target):
    cases, crashes = fuzz.fuzz(target, CI_MUTATIONS, seed=20261121)
    assert (cases, crashes) == (CI_MUTATIONS, 0)
