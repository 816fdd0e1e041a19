"""Read a benchmark sweep: one record per job (scenario, tracker, seed, metric values).

A job is a Hydra job directory (``.hydra/`` and ``run.h5``) of a ``gmtiflow -m`` sweep; any set
of them will do (the sweep dir, several sweep dirs, single runs), so a partial or extended
benchmark is read the same way.  Per job:

* *scenario*: the ``experiment`` choice (``challenge/crossing`` → ``crossing``) from
  ``.hydra/hydra.yaml`` (``hydra.runtime.choices``), else the run's ``/config``;
* *tracker*: the ``tracker`` choice (the config file name: ``nn_kalman``, ``stonesoup_jpda``,
  ``python``), followed by any ``tracker.*`` overrides of the job in brackets, so a sweep over a
  tracker parameter compares its values as separate trackers;
* *seed*: the run file's ``seed`` attribute;
* *values*: ``/metrics`` plus the derived values of :mod:`gmtiflow.bench.metrics`.

Jobs whose run file is missing or incomplete are returned with ``ok=False`` and the reason.
Track files of external trackers scored by :mod:`gmtiflow.bench.external` are jobs too: they
carry their own ``bench.json`` with the same fields.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Dict, Iterable, List

import yaml

from gmtiflow.errors import GmtiflowError
from gmtiflow.report.data import load_run, summary
from gmtiflow.report.sweep_report import find_job_dirs, read_overrides

from .metrics import derived_values
from .scenarios import GROUP

RUN_FILE = "run.h5"
EXTERNAL_FILE = "bench.json"


@dataclass
class JobRecord:
    dir: Path
    scenario: str = ""
    tracker: str = ""
    seed: int = -1
    ok: bool = False
    error: str = ""
    values: Dict[str, float] = field(default_factory=dict)


def _choices(job_dir: Path) -> Dict[str, str]:
    path = job_dir / ".hydra" / "hydra.yaml"
    if not path.is_file():
        return {}
    try:
        doc = yaml.safe_load(path.read_text()) or {}
    except yaml.YAMLError:
        return {}
    choices = ((doc.get("hydra") or {}).get("runtime") or {}).get("choices") or {}
    return {str(k): str(v) for k, v in choices.items()}


def scenario_name(experiment: str) -> str:
    """``challenge/crossing`` → ``crossing``; other experiments keep their name."""
    prefix = GROUP + "/"
    return experiment[len(prefix):] if experiment.startswith(prefix) else experiment


def tracker_label(choice: str, overrides: Dict[str, str]) -> str:
    extra = [f"{k[len('tracker.'):]}={v}" for k, v in sorted(overrides.items())
             if k.startswith("tracker.")]
    return f"{choice}[{','.join(extra)}]" if extra else choice


def read_job(job_dir: Path) -> JobRecord:
    """One job's record (never raises for a broken job)."""
    rec = JobRecord(dir=job_dir)
    ext = job_dir / EXTERNAL_FILE
    if ext.is_file():
        try:
            doc = json.loads(ext.read_text())
            rec.scenario, rec.tracker, rec.seed = doc["scenario"], doc["tracker"], int(doc["seed"])
            rec.values = {k: float(v) for k, v in doc["values"].items()}
            rec.ok = True
        except (OSError, ValueError, KeyError, TypeError) as exc:
            rec.error = f"{ext}: unreadable ({exc})"
        return rec
    choices = _choices(job_dir)
    overrides = read_overrides(job_dir)
    try:
        run = load_run(job_dir / RUN_FILE, ("metrics",))
    except GmtiflowError as exc:
        rec.error = str(exc)
        return rec
    except Exception as exc:  # a corrupt file must not stop the others
        rec.error = f"{job_dir / RUN_FILE}: unreadable ({exc})"
        return rec
    cfg = run.config or {}
    experiment = choices.get("experiment") or overrides.get("experiment") or ""
    rec.scenario = scenario_name(str(experiment)) if experiment not in ("", "None", "null") \
        else "default"
    rec.tracker = tracker_label(choices.get("tracker") or overrides.get("tracker")
                                or "nn_kalman", overrides)
    rec.seed = int(run.attrs.get("seed", cfg.get("seed", -1)))
    metrics_cfg = cfg.get("metrics") or {}
    values = {k: v for k, (v, _) in summary(run.table("metrics")).items()}
    if not values:
        rec.error = f"{job_dir / RUN_FILE}: no /metrics (tracker or metrics disabled?)"
        return rec
    rec.values = derived_values(values, float(metrics_cfg.get("cutoff_m", 200.0)),
                                float(metrics_cfg.get("order_p", 2.0)))
    rec.ok = True
    return rec


def collect(paths: Iterable) -> List[JobRecord]:
    """Records of every job found in ``paths`` (sweep dirs or job dirs)."""
    dirs = []
    for p in map(Path, paths):
        if p.is_dir() and (p / EXTERNAL_FILE).is_file():
            dirs.append(p)
            continue
        dirs += find_job_dirs([p])
        if p.is_dir():   # external trackers' scored jobs live under <sweep>/external/
            ext = p / "external"
            if ext.is_dir():
                dirs += sorted(d for d in ext.glob("*/*") if (d / EXTERNAL_FILE).is_file())
    return [read_job(d) for d in dirs]
