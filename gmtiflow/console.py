"""What ``gmtiflow`` says on the terminal: quiet by default, a short summary at the end.

* :func:`set_verbosity` — INFO lines (cache hashes, stage timings) go to the run's log file
  only; the console shows warnings and errors, unless ``-v``/``--verbose`` or
  ``hydra.verbose`` was given.
* :func:`run_summary` — the end-of-run block: detections (targets / false alarms / merged),
  P_D achieved, tracks, OSPA/GOSPA and the files written, read back from the finished run file.
* :func:`progress` — a tqdm bar for the slow steps after the simulation (export, report): only
  on a terminal, and only once the step has taken 2 s, so short runs and logs stay quiet (the
  simulation stages' bars are in :mod:`gmtiflow.bars`).
* :func:`discard_failed_run_dir` — a run that failed before finishing any stage (a config
  range error, a missing map file) leaves no empty run directory behind; a log that records
  finished stages is worth keeping and stays.

Kept apart from :mod:`gmtiflow.cli` so the entry point stays a thin Hydra wrapper; nothing
here imports the pipeline, matplotlib or scipy (``gmtiflow --help`` must start fast).
"""
from __future__ import annotations

import logging
import re
import shutil
from pathlib import Path
from typing import Dict, List, Optional, Sequence

from gmtiflow.bars import on_terminal

VERBOSE_FLAGS = ("-v", "--verbose")


def pop_verbose_flag(argv: List[str]) -> bool:
    """Remove ``-v``/``--verbose`` from ``argv`` (Hydra's parser does not know them); True if
    one was there."""
    found = False
    for flag in VERBOSE_FLAGS:
        while flag in argv:
            argv.remove(flag)
            found = True
    return found


HELP_FLAGS = ("--help", "-h")


def wants_app_help(argv: Sequence[str]) -> bool:
    """``--help``/``-h`` (not ``--hydra-help``) among the arguments."""
    return any(a in HELP_FLAGS for a in argv[1:])


def config_groups() -> Dict[str, List[str]]:
    """``{group: [options]}`` of the packaged config (``gmtiflow.conf``), read off the files."""
    from importlib import resources
    root = resources.files("gmtiflow.conf")
    out: Dict[str, List[str]] = {}
    for d in sorted(root.iterdir(), key=lambda p: p.name):
        if d.is_dir() and d.name not in ("hydra", "__pycache__"):
            opts = sorted(f.name[:-5] for f in d.iterdir() if f.name.endswith(".yaml"))
            if opts:
                out[d.name] = opts
    return out


def help_text() -> str:
    """``gmtiflow --help``: the header and footer of ``conf/hydra/help/gmtiflow.yaml`` around
    the config groups, one line each.

    The same layout as Hydra's help template, built without Hydra: Hydra's ``--help`` copies
    the whole config repository once per group option (~2 s for this config), this reads the
    group directories (milliseconds).
    """
    from importlib import resources

    import yaml
    spec = yaml.safe_load(resources.files("gmtiflow.conf").joinpath(
        "hydra", "help", "gmtiflow.yaml").read_text(encoding="utf-8"))
    groups = "\n".join(f"{g}: {', '.join(opts)}" for g, opts in config_groups().items())
    return (f"{spec['header']}\nConfig groups (choose one option per group with GROUP=OPTION):\n\n"
            f"{groups}\n\n{spec['footer']}")


PROGRESS_DELAY_S = 2.0
"""A progress bar appears only once its step has run this long."""


def progress(items, desc: str, unit: str, *, file=None, delay_s: float = PROGRESS_DELAY_S):
    """``items`` wrapped in a tqdm bar that shows on a terminal (``file``, default stderr) and
    only after ``delay_s``; elsewhere (a log, a pipe, a test) it writes nothing."""
    if not on_terminal(file):
        return items
    from tqdm import tqdm
    return tqdm(items, desc=desc, unit=unit, leave=False, delay=delay_s, disable=None, file=file)


def set_verbosity(verbose: bool) -> None:
    """Console handlers of the root logger show WARNING and above unless ``verbose``; file
    handlers (the run's ``gmtiflow.log``) keep every INFO line."""
    level = logging.DEBUG if verbose else logging.WARNING
    for handler in logging.getLogger().handlers:
        if isinstance(handler, logging.StreamHandler) and not isinstance(handler, logging.FileHandler):
            handler.setLevel(level)


def _fmt_size(size: int) -> str:
    for unit in ("B", "kB", "MB", "GB"):
        if size < 1000 or unit == "GB":
            return f"{size:.0f} {unit}" if unit == "B" else f"{size:.1f} {unit}"
        size /= 1000.0
    return f"{size} B"


def summary_numbers(run_path) -> Dict[str, float]:
    """The counts of the summary, read from the run file: detections, false alarms, merged,
    P_D achieved (detected or merged looks over looks with a detection draw), vehicles (those
    that appear; ``vehicles_listed``: all in the config), tracks
    (confirmed), OSPA/GOSPA means.  Reads only the columns it needs."""
    import h5py
    import numpy as np

    from gmtiflow.sensor.outcome import Outcome
    from gmtiflow.store import open_run

    drawn = [int(o) for o in (Outcome.DETECTED, Outcome.DOPPLER_BLIND, Outcome.PD_MISS,
                              Outcome.MERGED)]
    detected = [int(Outcome.DETECTED), int(Outcome.MERGED)]
    out: Dict[str, float] = {}

    def col(f: h5py.File, table: str, column: str) -> Optional[np.ndarray]:
        path = f"{table}/{column}"
        return f[path][()] if path in f else None

    with open_run(run_path) as f:
        truth_id = col(f, "detections", "truth_id")
        merged = col(f, "detections", "merged")
        if truth_id is not None:
            out["detections"] = float(len(truth_id))
            out["false_alarms"] = float(np.sum(truth_id < 0))
            out["targets"] = out["detections"] - out["false_alarms"]
            out["merged"] = float(np.sum(np.asarray(merged, bool))) if merged is not None else 0.0
        outcome = col(f, "looks", "outcome")
        if outcome is not None:
            d = np.isin(outcome, drawn)
            out["looks_drawn"] = float(d.sum())
            out["pd_achieved"] = float(np.isin(outcome[d], detected).mean()) if d.any() else float("nan")
        vid = col(f, "vehicles", "vehicle_id")
        if vid is not None:
            # the vehicles that appear: a listed vehicle starting after the scene's end does not
            out["vehicles_listed"] = float(len(vid))
            start = col(f, "vehicles", "start_time_s")
            end = f.attrs.get("scene_duration_s")
            late = 0
            if start is not None and end is not None:
                late = np.count_nonzero(np.asarray(start, float) > float(end))
            out["vehicles"] = float(len(vid) - late)
        tid, conf = col(f, "tracks", "track_id"), col(f, "tracks", "confirmed")
        if tid is not None:
            out["tracks"] = float(len(np.unique(tid)))
            if conf is not None:
                out["confirmed_tracks"] = float(len(np.unique(tid[np.asarray(conf, bool)])))
        names, values = col(f, "metrics", "name"), col(f, "metrics", "value")
        if names is not None and values is not None:
            for name, value in zip(names, values):
                name = name.decode() if isinstance(name, bytes) else str(name)
                if name in ("ospa_mean_m", "gospa_mean_m", "position_rmse_m", "identity_switches"):
                    out[name] = float(value)
    return out


def run_summary(run_path, out_dir, written: Sequence[Path] = ()) -> str:
    """The end-of-run block printed on the terminal (a few lines)."""
    import math

    run_path, out_dir = Path(run_path), Path(out_dir)
    s = summary_numbers(run_path)

    def num(key, fmt="{:.0f}"):
        v = s.get(key)
        return "n/a" if v is None or not math.isfinite(v) else fmt.format(v)

    lines = [f"gmtiflow: run finished -> {out_dir}"]
    if "detections" in s:
        lines.append(f"  detections  {num('detections')}: {num('targets')} on targets, "
                     f"{num('false_alarms')} false alarms, {num('merged')} merged")
    if "pd_achieved" in s:
        vehicles = (f"{num('vehicles')} vehicles" if s.get("vehicles") == s.get("vehicles_listed")
                    else f"{num('vehicles')} of {num('vehicles_listed')} vehicles appear in the "
                         f"scene")
        lines.append(f"  P_D achieved {num('pd_achieved', '{:.3f}')} over {num('looks_drawn')} "
                     f"looks on visible targets ({vehicles})")
    if "tracks" in s:
        lines.append(f"  tracks      {num('tracks')} ({num('confirmed_tracks')} confirmed)"
                     + (f", OSPA {num('ospa_mean_m', '{:.1f}')} m, GOSPA "
                        f"{num('gospa_mean_m', '{:.1f}')} m (means), position RMSE "
                        f"{num('position_rmse_m', '{:.1f}')} m, identity switches "
                        f"{num('identity_switches')}" if "ospa_mean_m" in s else ""))
    else:
        lines.append("  tracks      none (tracker off)")
    files = sorted({Path(p) for p in written} | {p for p in out_dir.iterdir()
                                                   if p.is_file() and not p.name.startswith(".")
                                                   and p.suffix != ".log"})
    if files:
        lines.append("  wrote       " + ", ".join(f"{p.name} ({_fmt_size(p.stat().st_size)})"
                                                   for p in files))
    lines.append(f"  log         {out_dir / 'gmtiflow.log'} (stage timings, cache; -v shows them here)")
    return "\n".join(lines)


def discard_failed_run_dir(out_dir) -> bool:
    """After a failed run: remove ``out_dir`` when the run did no work worth keeping — it holds
    only Hydra's ``.hydra/``, the run's manifest still saying ``complete: false`` and a log
    that records no finished stage (no ``stage`` line) — then its parent when that is Hydra's
    ``outputs/<date>`` and became empty.  Returns True when removed.

    A run that failed after doing work (its log records stages) keeps its directory: the log
    tells what happened.
    """
    import json

    out_dir = Path(out_dir)
    if not out_dir.is_dir():
        return False
    for p in out_dir.iterdir():
        if p.name == ".hydra" and p.is_dir():
            continue
        if p.suffix == ".log" and p.is_file():
            with open(p, "r", encoding="utf-8", errors="replace") as fh:
                if not any("] - stage " in line for line in fh):
                    continue
        if p.name == "outputs.json" and p.is_file():
            try:
                if json.loads(p.read_text(encoding="utf-8")).get("complete") is False:
                    continue
            except (OSError, ValueError, AttributeError):
                pass
        return False    # output, a partial file or a log worth keeping
    root = logging.getLogger()
    for h in list(root.handlers):    # release the run's log file before removing it
        if isinstance(h, logging.FileHandler) and Path(h.baseFilename).parent == out_dir.resolve():
            root.removeHandler(h)
            h.close()
    shutil.rmtree(out_dir, ignore_errors=True)
    if re.fullmatch(r"\d{4}-\d{2}-\d{2}", out_dir.parent.name):   # Hydra's outputs/<date>
        try:
            out_dir.parent.rmdir()          # only succeeds when empty
        except OSError:
            pass
    return not out_dir.exists()
