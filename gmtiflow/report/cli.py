"""``gmtiflow-report DIR...``: a comparison PDF from run dirs and/or sweep dirs.

    gmtiflow-report outputs/multirun/2026-11-21/14-00-00          # -> <that dir>/sweep_report.pdf
    gmtiflow-report runA runB runC -o compare.pdf
    gmtiflow-report --runs outputs/multirun/...                    # also (re)build report.pdf per run
    gmtiflow-report RUN_DIR --tracks my_tracks.csv [--baseline]    # the run report for your tracks

With ``--tracks`` (one run dir or run.h5): the track file is scored against the run's truth as
``gmtiflow-evaluate`` scores it, and the run report is built for it (default
``RUN_DIR/report_<tracks stem>.pdf``; beside it ``<pdf stem>.h5``, the run file with those
tracks and scores); ``--baseline`` adds a page comparing its scores with the run's own tracker's.

Exit status: 0 when the report was written (failed jobs are listed in it), 1 when no job
directory was found or a run report failed, 2 for bad arguments.
"""
from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path
from typing import List, Optional

from gmtiflow.errors import GmtiflowError

from gmtiflow.paths import refuse_same_file

from .config import ReportConfig


TRACKS_HELP = ("an external tracker's track file (CSV or .h5 with /tracks, as gmtiflow-evaluate "
               "reads it): build the run report for it")
BASELINE_HELP = "with --tracks: add a page comparing its scores with the run's own tracker's"


def main(argv: Optional[List[str]] = None) -> int:
    parser = argparse.ArgumentParser(
        prog="gmtiflow-report",
        description="Build a comparison PDF from gmtiflow run dirs or Hydra sweep dirs "
                    "(and optionally each run's own report.pdf).")
    parser.add_argument("dirs", nargs="+", metavar="DIR",
                        help="a run dir (with run.h5 or .hydra/) or a sweep dir holding them")
    parser.add_argument("-o", "--output", metavar="PDF",
                        help="output file (default: DIR/sweep_report.pdf for one DIR, "
                             "./sweep_report.pdf for several)")
    parser.add_argument("--runs", action="store_true",
                        help="also build report.pdf in every completed run dir")
    parser.add_argument("--tracks", metavar="CSV", help=TRACKS_HELP)
    parser.add_argument("--baseline", action="store_true", help=BASELINE_HELP)
    parser.add_argument("-q", "--quiet", action="store_true")
    args = parser.parse_args(argv)
    if args.baseline and not args.tracks:
        parser.error("--baseline goes with --tracks")
    if args.tracks:
        if len(args.dirs) != 1 or args.runs:
            parser.error("--tracks takes one run dir (or run.h5) and no --runs")
        logging.basicConfig(level=logging.WARNING if args.quiet else logging.INFO,
                            format="%(message)s")
        return _external_report(Path(args.dirs[0]), Path(args.tracks), args.output,
                                args.baseline)
    logging.basicConfig(level=logging.WARNING if args.quiet else logging.INFO,
                        format="%(message)s")
    from .run_report import build_run_report
    from .sweep_report import build_sweep_report, find_job_dirs

    out = Path(args.output) if args.output else (
        Path(args.dirs[0]) / "sweep_report.pdf" if len(args.dirs) == 1 else Path("sweep_report.pdf"))
    status = 0
    try:
        refuse_same_file(out, [d / "run.h5" for d in find_job_dirs(args.dirs)])
        if args.runs:
            cfg = ReportConfig()
            for d in find_job_dirs(args.dirs):
                if (d / "run.h5").is_file():
                    try:
                        print(build_run_report(cfg, d / "run.h5", d / cfg.filename))
                    except GmtiflowError as exc:
                        print(f"gmtiflow-report: error: {exc}", file=sys.stderr)
                        status = 1
        print(build_sweep_report(args.dirs, out))
    except GmtiflowError as exc:
        print(f"gmtiflow-report: error: {exc}", file=sys.stderr)
        return 1
    except OSError as exc:      # a full disk or an unwritable output: one line, no traceback
        print(f"gmtiflow-report: error: {exc.filename or out}: {exc.strerror or exc}",
              file=sys.stderr)
        return 1
    return status


def _external_report(run: Path, tracks: Path, output: Optional[str], baseline: bool) -> int:
    """``--tracks``: score ``tracks`` on the run and build its run report (see the docstring)."""
    from gmtiflow.evaluate.rescore import scored_run, summaries
    from gmtiflow.formats import FormatError

    from . import build_run_report
    from .pages.compare import compare_figure
    run_h5 = run / "run.h5" if run.is_dir() else run
    out = Path(output) if output else run_h5.parent / f"report_{tracks.stem}.pdf"
    scored = out.with_suffix(".h5")
    try:
        refuse_same_file(out, [run_h5, tracks])
        refuse_same_file(scored, [run_h5, tracks])
        scored_run(run_h5, tracks, scored)
        extra = []
        if baseline:
            ext, ext_ospa, _ = summaries(scored)
            base, base_ospa, name = summaries(run_h5)
            extra.append(("compare", lambda: compare_figure(
                ext, ext_ospa, base, base_ospa, external_label=tracks.name,
                baseline_label=f"run's tracker ({name})")))
        print(build_run_report(ReportConfig(), scored, out, extra_pages=extra))
    except (GmtiflowError, FormatError) as exc:
        print(f"gmtiflow-report: error: {exc}", file=sys.stderr)
        return 1
    except OSError as exc:
        print(f"gmtiflow-report: error: {exc.filename or out}: {exc.strerror or exc}",
              file=sys.stderr)
        return 1
    return 0


def entry() -> None:
    """Console script ``gmtiflow-report``."""
    sys.exit(main())


if __name__ == "__main__":
    entry()
