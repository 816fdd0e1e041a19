"""The sweep report: one comparison PDF from any set of run dirs or Hydra sweep dirs.

Built from files only (``reference/hydra.md`` §5: ``on_multirun_end`` gets no job results and is
not called when a job failed), so the same plain function serves the Hydra callback and the
``gmtiflow-report DIR...`` command, and works on partial, aborted or cluster sweeps:

* a *job* is a directory with ``.hydra/`` or ``run.h5``; a directory with neither is searched one
  level down (a sweep dir holds ``0/ 1/ ...``);
* its parameters are its ``.hydra/overrides.yaml``; parameters whose value differs between jobs
  are the *swept* ones, the rest are listed once as common overrides;
* it is COMPLETED when ``run.h5`` opens as a complete run, else FAILED, with the error from
  ``timing.json`` (written by :class:`gmtiflow.report.callbacks.SweepReport.on_job_end`) or the
  last ERROR line of the job's log;
* its wall time is ``timing.json``'s ``run_file_s`` (job start to run file written, i.e. without
  the run report) when present.

Pages: title with the job table (paginated), each result against each swept parameter (one line
per combination of the other swept parameters, mean ± std over seeds and any other repeats),
speed vs accuracy when fidelity presets are swept, and the failed jobs with their errors.
"""
from __future__ import annotations

import json
import logging
import math
import os
import re
import textwrap
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Dict, Iterable, List, Optional, Sequence

import numpy as np
import yaml
from matplotlib.backends.backend_pdf import PdfPages
import matplotlib.cm as cm
from matplotlib.figure import Figure

from gmtiflow.formats import atomic_path
from gmtiflow import __version__
from gmtiflow.console import progress
from gmtiflow.errors import GmtiflowError

from . import figures as F
from .data import key_numbers, load_run, summary

log = logging.getLogger(__name__)

RUN_FILE = "run.h5"
TIMING_FILE = "timing.json"

# (key, label, unit) of the results compared across jobs, in table order.
RESULTS = (
    ("detections", "detections", ""),
    ("false_alarms", "false alarms", ""),
    ("pd_achieved", "P_D achieved", ""),
    ("ospa_mean_m", "OSPA mean", "m"),
    ("gospa_mean_m", "GOSPA mean", "m"),
    ("position_rmse_m", "position RMSE", "m"),
    ("speed_rmse_mps", "speed RMSE", "m/s"),
    ("identity_switches", "identity switches", ""),
    ("coverage_mean", "coverage", ""),
    ("wall_s", "wall time", "s"),
)
ACCURACY = ("pd_achieved", "position_rmse_m", "ospa_mean_m", "identity_switches")
_SUMMARY_TABLES = ("vehicles", "dwells", "detections", "looks", "tracks", "metrics")


class SweepReportError(GmtiflowError):
    """No job directories found in the given paths."""


@dataclass
class Job:
    dir: Path
    label: str
    overrides: Dict[str, str] = field(default_factory=dict)
    status: str = "FAILED"
    error: str = ""
    values: Dict[str, float] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.status == "COMPLETED"


def _is_job(d: Path) -> bool:
    return (d / ".hydra").is_dir() or (d / RUN_FILE).is_file()


def _natural(p: Path):
    return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", p.name)]


def find_job_dirs(paths: Iterable) -> List[Path]:
    """Job dirs among ``paths``: each path itself when it is a job, else its job subdirs."""
    out: List[Path] = []
    for p in map(Path, paths):
        if not p.is_dir():
            raise SweepReportError(f"{p}: not a directory")
        if _is_job(p):
            out.append(p)
        else:
            out += sorted((d for d in p.iterdir() if d.is_dir() and _is_job(d)), key=_natural)
    seen, unique = set(), []
    for d in out:
        if d.resolve() not in seen:
            seen.add(d.resolve())
            unique.append(d)
    if not unique:
        raise SweepReportError("no run or job directories (with run.h5 or .hydra/) in "
                               + ", ".join(map(str, paths)))
    return unique


def skipped_dirs(paths: Iterable) -> List[str]:
    """Subdirectories of the given sweep dirs that are not jobs (empty, or foreign)."""
    out: List[str] = []
    for p in map(Path, paths):
        if p.is_dir() and not _is_job(p):
            out += [d.name for d in sorted(p.iterdir(), key=_natural)
                    if d.is_dir() and not _is_job(d) and not d.name.startswith(".")]
    return out


def read_overrides(job_dir: Path) -> Dict[str, str]:
    """``.hydra/overrides.yaml`` as {key: value} (``+``/``~`` prefixes dropped)."""
    path = job_dir / ".hydra" / "overrides.yaml"
    if not path.is_file():
        return {}
    try:
        items = yaml.safe_load(path.read_text()) or []
    except yaml.YAMLError:
        return {}
    out = {}
    for item in items:
        key, _, value = str(item).partition("=")
        out[key.lstrip("+~")] = value
    return out


def _log_error(job_dir: Path) -> str:
    for log_path in sorted(job_dir.glob("*.log")):
        lines = [ln for ln in log_path.read_text(errors="replace").splitlines() if "ERROR" in ln]
        if lines:
            return lines[-1].split("] - ", 1)[-1].strip()
    return ""


def read_job(job_dir: Path, label: str) -> Job:
    """Status, parameters and results of one job dir (never raises for a broken job)."""
    job = Job(dir=job_dir, label=label, overrides=read_overrides(job_dir))
    timing = {}
    tpath = job_dir / TIMING_FILE
    if tpath.is_file():
        try:
            timing = json.loads(tpath.read_text())
        except (OSError, ValueError):
            timing = {}
    run_path = job_dir / RUN_FILE
    try:
        run = load_run(run_path, _SUMMARY_TABLES)
    except GmtiflowError as exc:
        job.status = "FAILED"
        job.error = (timing.get("error") or _log_error(job_dir) or str(exc)).strip()
        return job
    except Exception as exc:  # a corrupt file must not stop the report of the others
        job.status = "FAILED"
        job.error = f"{run_path}: unreadable ({exc})"
        return job
    job.status = "COMPLETED"
    job.values.update(key_numbers(run))
    job.values.update({k: v for k, (v, _) in summary(run.table("metrics")).items()})
    wall = timing.get("run_file_s", timing.get("wall_s"))
    job.values["wall_s"] = float(wall) if wall is not None else float("nan")
    if not job.overrides and run.config:
        job.overrides = {"seed": str(run.attrs.get("seed", ""))}
    return job


def collect_jobs(paths: Sequence) -> List[Job]:
    dirs = find_job_dirs(paths)
    common = os.path.commonpath([str(d.resolve()) for d in dirs]) if len(dirs) > 1 else None
    jobs = []
    for d in dirs:
        label = os.path.relpath(d.resolve(), common) if common else d.name
        jobs.append(read_job(d, label))
    return jobs


def swept_keys(jobs: Sequence[Job]) -> List[str]:
    """Override keys whose value differs between jobs (missing counts as a value), in order."""
    keys: List[str] = []
    for j in jobs:
        keys += [k for k in j.overrides if k not in keys]
    return [k for k in keys if len({j.overrides.get(k) for j in jobs}) > 1]


def _number(text) -> Optional[float]:
    try:
        v = float(text)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


def _fmt(v: float, key: str = "") -> str:
    if v is None or not math.isfinite(v):
        return "–"
    if key in ("detections", "false_alarms", "identity_switches") or (v.is_integer() and abs(v) >= 100):
        return f"{v:.0f}"
    return f"{v:.3g}"


# ----------------------------------------------------------------------------- pages

MAX_TABLE_COLUMNS = 14
"""Columns of one job table; beyond, parameters and results go on separate pages."""


def table_figures(jobs: Sequence[Job], keys: Sequence[str], sources: Sequence, rows_per_page=22,
                  skipped: Sequence[str] = ()) -> List[Figure]:
    """Title and the job table: swept parameters against key results, paginated; ``skipped``:
    directories of the sweep that are not jobs (named once, on the title page)."""
    common = {}
    if jobs:
        first = jobs[0].overrides
        common = {k: v for k, v in first.items() if k not in keys
                  and all(j.overrides.get(k) == v for j in jobs)}
    results = [r for r in RESULTS if any(math.isfinite(j.values.get(r[0], float("nan"))) for j in jobs)]
    # One table while it stays legible; with many swept keys the parameters and the results
    # get pages of their own (each row still starts with the job and its status).
    together = len(keys) + 2 + len(results) <= MAX_TABLE_COLUMNS
    parts = [(list(keys), results)] if together else [(list(keys), []), ([], results)]
    chunks = [jobs[i:i + rows_per_page] for i in range(0, max(len(jobs), 1), rows_per_page)]
    figs = []
    pages = len(chunks) * len(parts)
    n_ok = sum(j.ok for j in jobs)
    for page, (part_keys, part_results) in enumerate(
            (pk, pr) for pk, pr in parts for _ in range(len(chunks))):
        chunk = chunks[page % len(chunks)]
        what = "" if together else (" — swept parameters" if part_keys else " — results")
        fig = F.new_figure()
        if page == 0:
            fig.text(0.04, 0.94, "gmtiflow sweep report", fontsize=20, weight="bold")
            src = ", ".join(str(s) for s in sources)
            lines = [f"{len(jobs)} jobs: {n_ok} completed, {len(jobs) - n_ok} failed     "
                     f"built {datetime.now(timezone.utc):%Y-%m-%d %H:%M} UTC, gmtiflow {__version__}",
                     f"from: {textwrap.shorten(src, 150)}",
                     f"swept: {', '.join(keys) or 'nothing (all jobs share their overrides)'}",
                     f"common overrides: {textwrap.shorten(' '.join(f'{k}={v}' for k, v in common.items()) or 'none', 150)}",
                     "wall time: job start to run file written (timing.json of the sweep callback); "
                     "P_D achieved: detected / looks with a detection draw"]
            if skipped:
                lines.append(f"not jobs (no run.h5 and no .hydra/, left out): "
                             f"{textwrap.shorten(', '.join(skipped), 120)}")
            for i, ln in enumerate(lines):
                fig.text(0.04, 0.895 - 0.03 * i, ln, fontsize=9)
            top = 0.72
        else:
            fig.text(0.04, 0.94, f"Jobs{what} (page {page + 1} of {pages})", fontsize=14,
                     weight="bold")
            top = 0.9
        header = (["job", "status"] + list(part_keys)
                  + [f"{lab}" + (f" ({u})" if u else "") for _, lab, u in part_results])
        cells = []
        for j in chunk:
            row = [textwrap.shorten(j.label, 18), j.status]
            row += [textwrap.shorten(str(j.overrides.get(k, "–")), 22) for k in part_keys]
            row += [_fmt(j.values.get(k, float("nan")), k) if j.ok else "" for k, _, _ in part_results]
            cells.append(row)
        ax = fig.add_axes([0.03, 0.04, 0.94, top - 0.04])
        ax.axis("off")
        if cells:
            tab = ax.table(cellText=cells, colLabels=[textwrap.fill(h, 12) for h in header],
                           loc="upper center", cellLoc="center")
            tab.auto_set_font_size(False)
            tab.set_fontsize(7.5 if len(header) < 14 else 6)
            tab.scale(1.0, 1.35)
            for (r, c), cell in tab.get_celld().items():
                if r == 0:
                    cell.set_facecolor("#deebf7")
                    cell.set_height(cell.get_height() * 1.8)
                elif cells[r - 1][1] != "COMPLETED":
                    cell.set_facecolor("#fddbc7")
        figs.append(fig)
    return figs


def _groups(jobs: Sequence[Job], param: str, others: Sequence[str]):
    """{other-params combination: {x value: [jobs]}}, x values in order of first appearance."""
    out: Dict[tuple, Dict[str, List[Job]]] = {}
    for j in jobs:
        g = tuple(j.overrides.get(k, "–") for k in others)
        out.setdefault(g, {}).setdefault(j.overrides.get(param, "–"), []).append(j)
    return out


LOG_PARAMS = re.compile(r"(pfa|power|density|_w$|rate)", re.I)


def mean_ci95(values) -> tuple:
    """(mean, half-width of the 95 % t-interval, n) of the finite values; half-width 0 for n < 2.

    Student's t quantile t_{0.975, n−1}: the runs of one point differ by their seed only.
    """
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    if not len(v):
        return float("nan"), float("nan"), 0
    if len(v) < 2:
        return float(v.mean()), 0.0, len(v)
    from scipy.stats import t as student_t     # imported here: scipy.stats is slow to import
    half = float(student_t.ppf(0.975, len(v) - 1) * v.std(ddof=1) / math.sqrt(len(v)))
    return float(v.mean()), half, len(v)


def _x_axis(values: Sequence[str], param: str):
    """(positions, numeric, log) of the parameter values: numbers on a linear or log axis (log
    when all > 0 and spanning ≥ 50×, or a P_FA/power/density-like key), else categories."""
    numeric = bool(values) and all(_number(v) is not None for v in values)
    if numeric:
        nums = [float(v) for v in values]
        log_x = min(nums) > 0 and (max(nums) / min(nums) >= 50 or
                                   (LOG_PARAMS.search(param) is not None and max(nums) > min(nums)))
        return {v: float(v) for v in values}, True, log_x
    return {v: float(i) for i, v in enumerate(values)}, False, False


def _results_grid(count: int):
    """(figure, axes): one panel per result, 2 or 3 columns, room for a legend below."""
    fig = F.new_figure()
    ncols = 3 if count > 4 else 2
    axes = fig.subplots(max(1, math.ceil(count / ncols)), ncols, squeeze=False,
                        gridspec_kw=dict(left=0.07, right=0.98, top=0.86, bottom=0.14,
                                         hspace=0.6, wspace=0.3))
    return fig, axes


def _finish_grid(fig, axes, count: int) -> None:
    """Blank the unused panels; one legend (the first panel's entries) below them all."""
    for ax in axes.ravel()[count:]:
        ax.axis("off")
    handles, labels = axes.ravel()[0].get_legend_handles_labels()
    if labels:
        fig.legend(handles, labels, loc="lower center", ncol=min(4, len(labels)), fontsize=8,
                   frameon=False)


def parameter_figure(jobs: Sequence[Job], param: str, keys: Sequence[str]) -> Figure:
    """Every result against one swept parameter, mean ± 95 % interval over the seeds of a point
    (the jobs' own values as dots).  Numbers: one line per combination of the other swept
    parameters, log axis for P_FA/power-like keys or ranges ≥ 50×; categories: grouped bars."""
    ok = [j for j in jobs if j.ok]
    others = [k for k in keys if k != param and k != "seed"]
    results = [r for r in RESULTS if any(math.isfinite(j.values.get(r[0], float("nan"))) for j in ok)]
    fig, axes = _results_grid(len(results))
    values = list(dict.fromkeys(j.overrides.get(param, "–") for j in ok))
    if values and all(_number(v) is not None for v in values):
        values.sort(key=float)
    pos, numeric, log_x = _x_axis(values, param)
    groups = _groups(ok, param, others)
    colours = cm.tab10(np.arange(len(groups)) % 10)
    n_groups = max(len(groups), 1)
    width = 0.8 / n_groups
    repeats = max((len(js) for g in groups.values() for js in g.values()), default=1)
    for ax, (key, label, unit) in zip(axes.ravel(), results):
        for gi, ((g, by_x), c) in enumerate(zip(groups.items(), colours)):
            xs = [x for x in values if x in by_x]
            stats = [mean_ci95([j.values.get(key, np.nan) for j in by_x[x]]) for x in xs]
            means = [s[0] for s in stats]
            halves = [s[1] for s in stats]
            lab = ", ".join(f"{k}={v}" for k, v in zip(others, g)) or None
            if numeric:
                px = [pos[x] for x in xs]
                ax.errorbar(px, means, yerr=halves if repeats > 1 else None, color=c, marker="o",
                            ms=4, lw=1.2, capsize=3, label=lab)
            else:
                px = [pos[x] + (gi - (n_groups - 1) / 2) * width for x in xs]
                ax.bar(px, means, width=width * 0.95, color=c, alpha=0.75, label=lab,
                       yerr=halves if repeats > 1 else None, capsize=2,
                       error_kw=dict(lw=0.8))
            for x0, x in zip(px, xs):
                v = np.array([j.values.get(key, np.nan) for j in by_x[x]], float)
                ax.scatter([x0] * len(v), v, s=8, color="k" if not numeric else c, alpha=0.4,
                           lw=0, zorder=3)
        ax.set_title(label + (f" ({unit})" if unit else ""), fontsize=9)
        ax.grid(alpha=0.3)
        if log_x:
            ax.set_xscale("log")
        if not numeric:
            ax.set_xticks(list(pos.values()))
            ax.set_xticklabels([textwrap.shorten(v, 14) for v in values], fontsize=7,
                               rotation=20 if len(values) > 3 else 0)
        ax.tick_params(labelsize=7)
        ax.set_xlabel(param + (" (log)" if log_x else ""), fontsize=8)
    _finish_grid(fig, axes, len(results))
    if not results:
        F._note(axes.ravel()[0], "no completed jobs: nothing to plot")
    spread = (f"; mean ± 95 % interval (t) over up to {repeats} seeds per point, dots = jobs"
              if repeats > 1 else "")
    fig.suptitle(f"Results vs {param}{spread}", fontsize=13, weight="bold", x=0.04, ha="left")
    return fig


def paired_deltas(jobs: Sequence[Job], param: str, others: Sequence[str], key: str):
    """Per (other-parameter combination, value ≠ baseline): the per-seed differences
    value(x, seed) − value(baseline, seed) over the seeds run at both.  Baseline: the first
    value in order.  Returns (baseline, {group: {x: array of deltas}})."""
    ok = [j for j in jobs if j.ok]
    values = list(dict.fromkeys(j.overrides.get(param, "–") for j in ok))
    if values and all(_number(v) is not None for v in values):
        values.sort(key=float)
    if len(values) < 2:
        return None, {}
    base = values[0]
    out: Dict[tuple, Dict[str, np.ndarray]] = {}
    cell: Dict[tuple, Dict[str, Dict[str, float]]] = {}
    for j in ok:
        g = tuple(j.overrides.get(k, "–") for k in others)
        cell.setdefault(g, {}).setdefault(j.overrides.get(param, "–"), {})[
            j.overrides.get("seed", "–")] = j.values.get(key, float("nan"))
    for g, by_x in cell.items():
        b = by_x.get(base, {})
        for x in values[1:]:
            seeds = sorted(set(b) & set(by_x.get(x, {})))
            d = np.array([by_x[x][s] - b[s] for s in seeds], float)
            out.setdefault(g, {})[x] = d[np.isfinite(d)]
    return base, out


def paired_figure(jobs: Sequence[Job], param: str, keys: Sequence[str]) -> Figure:
    """Changes against the baseline value of ``param``, paired by seed: the common random
    numbers make every seed's truth and noise the same across values, so per-seed differences
    are far tighter than the spread of either side."""
    others = [k for k in keys if k != param and k != "seed"]
    ok = [j for j in jobs if j.ok]
    results = [r for r in RESULTS if r[0] != "wall_s" and
               any(math.isfinite(j.values.get(r[0], float("nan"))) for j in ok)]
    fig, axes = _results_grid(len(results))
    base = None
    for ax, (key, label, unit) in zip(axes.ravel(), results):
        base, deltas = paired_deltas(jobs, param, others, key)
        xs = list(dict.fromkeys(x for by_x in deltas.values() for x in by_x))
        n_groups = max(len(deltas), 1)
        width = 0.8 / n_groups
        colours = cm.tab10(np.arange(n_groups) % 10)
        for gi, ((g, by_x), c) in enumerate(zip(deltas.items(), colours)):
            px, means, halves = [], [], []
            for i, x in enumerate(xs):
                m, h, k = mean_ci95(by_x.get(x, []))
                px.append(i + (gi - (n_groups - 1) / 2) * width)
                means.append(m)
                halves.append(h)
            lab = ", ".join(f"{k}={v}" for k, v in zip(others, g)) or None
            ax.bar(px, means, width=width * 0.95, color=c, alpha=0.75, yerr=halves, capsize=2,
                   error_kw=dict(lw=0.8), label=lab)
        ax.axhline(0, color="k", lw=0.7)
        ax.set_xticks(range(len(xs)))
        ax.set_xticklabels([textwrap.shorten(str(x), 14) for x in xs], fontsize=7)
        ax.set_title(f"Δ {label}" + (f" ({unit})" if unit else ""), fontsize=9)
        ax.tick_params(labelsize=7)
        ax.grid(alpha=0.3, axis="y")
        ax.set_xlabel(param, fontsize=8)
    _finish_grid(fig, axes, len(results))
    fig.suptitle(f"Paired by seed: change from {param}={base} (mean ± 95 % interval of the "
                 f"per-seed differences)", fontsize=12, weight="bold", x=0.04, ha="left")
    return fig


def speed_accuracy_figure(jobs: Sequence[Job], param: str = "fidelity") -> Figure:
    """Wall time against accuracy per fidelity preset (mean ± std over repeats)."""
    ok = [j for j in jobs if j.ok]
    presets = list(dict.fromkeys(j.overrides.get(param, "–") for j in ok))
    fig = F.new_figure()
    axes = fig.subplots(2, 2, squeeze=False, gridspec_kw=dict(left=0.08, right=0.98, top=0.86,
                                                               bottom=0.08, hspace=0.35, wspace=0.25))
    colours = cm.tab10(np.arange(len(presets)) % 10)
    labels = {k: (lab, u) for k, lab, u in RESULTS}
    for ax, key in zip(axes.ravel(), ACCURACY):
        for p, c in zip(presets, colours):
            js = [j for j in ok if j.overrides.get(param, "–") == p]
            t = np.array([j.values.get("wall_s", np.nan) for j in js], float)
            v = np.array([j.values.get(key, np.nan) for j in js], float)
            m = np.isfinite(t) & np.isfinite(v)
            if not m.any():
                continue
            ax.scatter(t[m], v[m], color=c, s=14, alpha=0.5, lw=0)
            ax.errorbar([t[m].mean()], [v[m].mean()], xerr=[t[m].std()] if m.sum() > 1 else None,
                        yerr=[v[m].std()] if m.sum() > 1 else None, color=c, marker="o", ms=7,
                        capsize=3, label=f"{p} ({m.sum()} runs)")
            ax.annotate(p, (t[m].mean(), v[m].mean()), textcoords="offset points", xytext=(6, 4),
                        fontsize=8)
        lab, unit = labels[key]
        ax.set_ylabel(lab + (f" ({unit})" if unit else ""), fontsize=9)
        ax.set_xlabel("wall time per run (s)", fontsize=9)
        ax.grid(alpha=0.3)
        if not ax.has_data():
            F._note(ax, "no wall times (timing.json) or no values")
    h, l = axes[0, 0].get_legend_handles_labels()
    if l:
        fig.legend(h, l, loc="upper right", fontsize=8)
    fig.suptitle(f"Speed vs accuracy over {param} presets", fontsize=13, weight="bold", x=0.04,
                 ha="left")
    return fig


def failures_figure(jobs: Sequence[Job]) -> Figure:
    failed = [j for j in jobs if not j.ok]
    fig = F.new_figure()
    fig.text(0.04, 0.94, f"Failed jobs ({len(failed)} of {len(jobs)})", fontsize=14, weight="bold")
    y = 0.89
    for j in failed:
        ov = " ".join(f"{k}={v}" for k, v in j.overrides.items()) or "(no overrides)"
        lines = [f"{j.label}: {ov}"] + textwrap.wrap(j.error or "no error recorded", 150)[:4]
        for i, ln in enumerate(lines):
            fig.text(0.05 if i == 0 else 0.08, y, ln, fontsize=9 if i == 0 else 8,
                     weight="bold" if i == 0 else "normal", family=None if i == 0 else "monospace",
                     color="k" if i == 0 else "#b2182b")
            y -= 0.03
        y -= 0.01
        if y < 0.05:
            fig.text(0.05, 0.02, "… more failures in the job table", fontsize=8)
            break
    return fig


def sweep_figures(jobs: Sequence[Job], sources: Sequence) -> List[Figure]:
    keys = swept_keys(jobs)
    figs = table_figures(jobs, keys, sources, skipped=skipped_dirs(sources))
    plot_params = [k for k in keys if k != "seed"]     # seeds are the spread, not a parameter
    for k in plot_params:
        figs.append(parameter_figure(jobs, k, keys))
        others = [o for o in keys if o not in (k, "seed")]
        if "seed" in keys and any(len(d) for by_x in paired_deltas(
                jobs, k, others, "detections")[1].values() for d in by_x.values()):
            figs.append(paired_figure(jobs, k, keys))   # only when some seed ran at two values
    fidelity_key = next((k for k in keys if k == "fidelity" or k == "fidelity.name"), None)
    if fidelity_key:
        figs.append(speed_accuracy_figure(jobs, fidelity_key))
    if any(not j.ok for j in jobs):
        figs.append(failures_figure(jobs))
    return figs


def build_sweep_report(paths: Sequence, out_pdf) -> Path:
    """Build the comparison PDF of the jobs found in ``paths`` (run dirs and/or sweep dirs).

    Failed or unfinished jobs are listed, never fatal; raises :class:`SweepReportError` only
    when no job directory is found.
    """
    out_pdf = Path(out_pdf)
    jobs = collect_jobs(paths)
    with atomic_path(out_pdf) as tmp, PdfPages(
            tmp, metadata={"Title": "gmtiflow sweep report",
                           "Creator": f"gmtiflow {__version__}"}) as pdf:
        for fig in progress(sweep_figures(jobs, paths), "sweep report", "page"):
            pdf.savefig(fig)
    log.info("sweep report %s: %d jobs (%d failed)", out_pdf, len(jobs),
             sum(not j.ok for j in jobs))
    return out_pdf
