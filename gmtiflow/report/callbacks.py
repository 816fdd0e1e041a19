"""Hydra callback: per-job ``timing.json`` and the sweep's comparison PDF at multirun end.

Registered in ``conf/config.yaml``::

    hydra:
      callbacks:
        sweep_report:
          _target_: gmtiflow.report.callbacks.SweepReport

* ``on_job_start`` / ``on_job_end`` run in the job's own process (the worker, for joblib or
  submitit), so what they learn goes to a file in the job dir: ``timing.json`` with
  ``status`` (COMPLETED / FAILED), ``wall_s`` (job start to end, including the run report),
  ``run_file_s`` (job start to the mtime of ``run.h5``: the simulation without the report, what
  the speed/accuracy page plots), ``started_utc`` and ``error`` for a failed job.
* ``on_multirun_end`` runs once in the launching process, gets no job results and is not called
  when any job failed (Hydra 1.3); it builds ``<sweep dir>/<report.sweep_filename>`` from the job
  dirs.  After a sweep with failures run ``gmtiflow-report <sweep dir>`` instead: same function.
  A report error is logged, never raised, so it cannot turn a finished sweep into a failure.
"""
from __future__ import annotations

import json
import logging
import time
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Dict

from hydra.experimental.callback import Callback
from omegaconf import DictConfig, OmegaConf

log = logging.getLogger(__name__)

TIMING_FILE = "timing.json"


def _output_dir(config: DictConfig) -> Path:
    return Path(OmegaConf.select(config, "hydra.runtime.output_dir"))


class SweepReport(Callback):
    def __init__(self) -> None:
        self._start: Dict[str, float] = {}

    def on_job_start(self, config: DictConfig, **kwargs: Any) -> None:
        self._start[str(_output_dir(config))] = time.time()

    def on_job_end(self, config: DictConfig, job_return: Any, **kwargs: Any) -> None:
        try:
            from gmtiflow.formats import write_atomic   # not at import: the callback is built
            out = _output_dir(config)                     # on every start (--help, typos)
            end = time.time()
            start = self._start.pop(str(out), None)
            status = getattr(getattr(job_return, "status", None), "name", "UNKNOWN")
            info: Dict[str, Any] = {
                "status": status,
                "overrides": OmegaConf.select(config, "hydra.job.override_dirname", default=""),
                "started_utc": (datetime.fromtimestamp(start, timezone.utc).isoformat()
                                if start else None),
                "wall_s": (end - start) if start else None,
                "run_file_s": None,
            }
            run_file = out / "run.h5"
            if start and run_file.is_file():
                info["run_file_s"] = max(run_file.stat().st_mtime - start, 0.0)
            if status == "FAILED":
                info["error"] = repr(getattr(job_return, "_return_value", None))
            out.mkdir(parents=True, exist_ok=True)
            # temporary name + rename: a killed job never leaves a torn timing.json
            write_atomic(out / TIMING_FILE, (json.dumps(info, indent=1) + "\n").encode())
        except Exception as exc:  # bookkeeping must never fail a job
            log.warning("timing.json not written: %s", exc)

    def on_multirun_end(self, config: DictConfig, **kwargs: Any) -> None:
        sweep_dir = Path(OmegaConf.select(config, "hydra.sweep.dir"))
        name = OmegaConf.select(config, "report.sweep_filename", default="sweep_report.pdf")
        try:
            from gmtiflow.report.sweep_report import build_sweep_report
            path = build_sweep_report([sweep_dir], sweep_dir / name)
            log.info("sweep report: %s", path)
        except Exception as exc:
            log.error("sweep report not written (%s); run `gmtiflow-report %s`", exc, sweep_dir)
