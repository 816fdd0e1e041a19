"""benchmarks/all.py regenerates every figure docs/ quotes: each benchmark script that a page
names must have an entry there (issue 18, "one command regenerates every figure")."""
from __future__ import annotations

import importlib.util
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: Quoted in docs/ but not timing figures: the fuzzers back docs/reliability.md through
#: reliability_table.py, and all.py is the index itself.
NOT_FIGURES = {"fuzz", "config_extremes", "all"}


def _index():
    spec = importlib.util.spec_from_file_location("bench_all", ROOT / "benchmarks" / "all.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_every_quoted_benchmark_has_an_entry():
    quoted = set()
    for page in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        quoted |= set(re.findall(r"benchmarks/(\w+)\.py", page.read_text()))
    listed = {script for script, *_ in _index().BENCHMARKS.values()}
    assert quoted - NOT_FIGURES <= listed, sorted(quoted - NOT_FIGURES - listed)
    assert all((ROOT / "benchmarks" / f"{s}.py").exists() for s in listed)


def test_run_readers_follow_the_run_they_read():
    mod = _index()
    names = list(mod.BENCHMARKS)
    for reader, maker in mod.NEEDS.items():
        assert names.index(maker) < names.index(reader)
        script, _, full, quick = mod.BENCHMARKS[reader]
        assert any("{out}/" + maker in a for a in full + quick)
