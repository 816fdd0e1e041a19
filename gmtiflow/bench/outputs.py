"""The benchmark verdict's files: ``bench_results.csv``, ``bench_results.md`` and
``bench_report.pdf`` in a sweep dir, from the job dirs under one or more sweeps.

:func:`build` collects (:mod:`.collect`), compares (:mod:`.verdict`) and writes; the PDF is
:mod:`.pdf`'s.  Kept apart from :mod:`.verdict` so that the PDF page code can use the verdict's
formatting without an import cycle.
"""
from __future__ import annotations

from pathlib import Path
from typing import Dict, Iterable, Optional

from gmtiflow.formats import write_atomic

from .collect import collect
from .verdict import Comparison, compare, to_csv, to_markdown

CSV_NAME, MD_NAME, PDF_NAME = "bench_results.csv", "bench_results.md", "bench_report.pdf"


def write_outputs(comp: Comparison, out_dir, pdf: bool = True) -> Dict[str, Path]:
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = {"csv": out_dir / CSV_NAME, "md": out_dir / MD_NAME}
    write_atomic(paths["csv"], to_csv(comp).encode())
    write_atomic(paths["md"], to_markdown(comp).encode())
    if pdf:
        from .pdf import build_pdf      # matplotlib: only when a PDF is written
        paths["pdf"] = build_pdf(comp, out_dir / PDF_NAME)
    return paths


def build(paths: Iterable, out_dir=None, reference: Optional[str] = None,
          pdf: bool = True) -> Dict[str, Path]:
    """Collect the jobs under ``paths``, compare, and write the outputs (into the first path)."""
    paths = [Path(p) for p in paths]
    records = collect(paths)
    comp = compare(records, reference)
    return write_outputs(comp, out_dir or paths[0], pdf=pdf)
