"""``gmtiflow-bench``: the tracker benchmark in one command.

``gmtiflow-bench [--quick] [-j N] [--launcher L] [-o DIR] [--reference T]
[--command NAME=CMD ...] [OVERRIDE ...]`` runs ``gmtiflow -m +bench=suite`` (or
``+bench=quick``) through a Hydra launcher (joblib by default, when installed), scores any
external command trackers on the same runs (:mod:`gmtiflow.bench.external`), and writes the
verdict (``bench_results.csv``, ``bench_results.md``, ``bench_report.pdf``) into the sweep dir.
Extra arguments are Hydra overrides of the sweep (``tracker=nn_kalman,stonesoup_jpda``,
``seed='range(1,21)'``, ``experiment=challenge/tunnel``).

``gmtiflow-bench report DIR... [-o OUT] [--reference T] [--command NAME=CMD ...]`` builds the
verdict from existing job dirs (after a sweep with failed jobs, or to merge sweeps).

Exit status: 0 success, 1 a failed sweep or bad input (one line on stderr), 2 bad arguments.
"""
from __future__ import annotations

import argparse
import importlib.util
import logging
import math
import subprocess
import sys
from datetime import datetime
from pathlib import Path
from typing import List, Optional, Sequence

from gmtiflow.errors import GmtiflowError

PROG = "gmtiflow-bench"
log = logging.getLogger(PROG)


def _commands(items: Sequence[str]) -> dict:
    out = {}
    for item in items or ():
        name, sep, cmd = item.partition("=")
        if not sep or not name.strip() or not cmd.strip():
            raise SystemExit(f"{PROG}: --command needs NAME=COMMAND, got {item!r}")
        out[name.strip()] = cmd
    return out


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog=PROG, description=__doc__.split("\n\n")[1],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--quick", action="store_true", help="CI size: two seeds (+bench=quick)")
    p.add_argument("-j", "--jobs", type=int, default=2, help="parallel jobs (joblib n_jobs)")
    p.add_argument("--launcher", default=None,
                   help="Hydra launcher (default: joblib when installed, else basic)")
    p.add_argument("-o", "--out", type=Path, default=None,
                   help="sweep dir (default: outputs/bench/<date>/<time>)")
    p.add_argument("--reference", default=None, help="reference tracker (default: nn_kalman)")
    p.add_argument("--command", action="append", default=[], metavar="NAME=CMD",
                   help="an external tracker: a shell command with {detections} {dwells} "
                        "{scene} {tracks} placeholders (docs/benchmark.md)")
    p.add_argument("--timeout", type=float, default=600.0,
                   help="seconds allowed to one external command run")
    p.add_argument("overrides", nargs="*", help="Hydra overrides of the sweep")
    return p


def _report_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog=f"{PROG} report",
                                description="Build the benchmark verdict from job dirs.")
    p.add_argument("dirs", nargs="+", type=Path, help="sweep or job dirs")
    p.add_argument("-o", "--out", type=Path, default=None, help="output dir (default: first DIR)")
    p.add_argument("--reference", default=None)
    p.add_argument("--command", action="append", default=[], metavar="NAME=CMD")
    p.add_argument("--timeout", type=float, default=600.0)
    return p


def sweep_command(args, out: Path) -> List[str]:
    launcher = args.launcher
    if launcher is None:
        launcher = ("joblib" if importlib.util.find_spec("hydra_plugins.hydra_joblib_launcher")
                    else "basic")
    cmd = [sys.executable, "-m", "gmtiflow.cli", "-m",
           f"+bench={'quick' if args.quick else 'suite'}", f"hydra/launcher={launcher}",
           f"hydra.sweep.dir={out}", "~hydra.callbacks.sweep_report"]
    if launcher == "joblib":
        cmd.append(f"hydra.launcher.n_jobs={args.jobs}")
    if args.reference:
        cmd.append(f"hydra.callbacks.bench_verdict.reference={args.reference}")
    return cmd + list(args.overrides)


def _finish(dirs, out, reference, commands, timeout) -> int:
    from . import external, outputs
    if commands:
        for name, template in commands.items():
            external.score_command(name, template, dirs[0], timeout=timeout)
    paths = outputs.build(dirs, out, reference=reference)
    for p in paths.values():
        print(p)
    return 0


def _check_numbers(parser: argparse.ArgumentParser, args) -> None:
    """--jobs a whole number >= 1, --timeout a finite number of seconds > 0 (exit 2 otherwise,
    before any sweep starts)."""
    jobs = getattr(args, "jobs", 1)
    if jobs < 1:
        parser.error(f"--jobs must be at least 1, got {jobs}")
    timeout = args.timeout
    if not (math.isfinite(timeout) and timeout > 0):
        parser.error(f"--timeout must be a finite number of seconds > 0, got {timeout!r}")


def main(argv: Optional[Sequence[str]] = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    logging.basicConfig(level=logging.INFO, format=f"{PROG}: %(message)s")
    try:
        if argv[:1] == ["report"]:
            parser = _report_parser()
            args = parser.parse_args(argv[1:])
            _check_numbers(parser, args)
            return _finish(args.dirs, args.out, args.reference, _commands(args.command),
                           args.timeout)
        parser = _parser()
        args = parser.parse_args(argv)
        _check_numbers(parser, args)
        commands = _commands(args.command)
        out = args.out or Path("outputs/bench") / datetime.now().strftime("%Y-%m-%d/%H-%M-%S")
        cmd = sweep_command(args, out)
        log.info("%s", " ".join(cmd))
        proc = subprocess.run(cmd)
        if proc.returncode != 0:
            log.error("the sweep failed (exit %d); the verdict below covers the jobs that "
                      "completed", proc.returncode)
        from .outputs import CSV_NAME, MD_NAME, PDF_NAME
        done = [out / n for n in (CSV_NAME, MD_NAME, PDF_NAME)]
        if proc.returncode == 0 and not commands and all(p.is_file() for p in done):
            print("\n".join(map(str, done)))    # the sweep's callback wrote the verdict
            return 0
        _finish([out], out, args.reference, commands, args.timeout)
        return 0 if proc.returncode == 0 else 1
    except (GmtiflowError, ValueError, OSError) as exc:
        print(f"{PROG}: {exc}", file=sys.stderr)
        return 1


def console() -> None:
    sys.exit(main())
