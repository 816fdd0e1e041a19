"""Command-line entry point ``gmtiflow`` (a Hydra application).

The Hydra wrapper only converts the config and calls :func:`gmtiflow.pipeline.run` with the run
directory Hydra chose; errors a user can cause are printed as one line naming what is wrong and
exit with status 1, leaving no run file behind.  Ctrl-C prints one line and exits with 130; the
run directory's ``outputs.json`` then still says ``complete: false``.

The run directory (:mod:`gmtiflow.rundir`) is locked for the run, refused if Hydra's outputs in
it are symlinks, and Hydra's ``.hydra/*.yaml`` are written only after the previous run's outputs
are gone (the packaged config sets ``hydra.output_subdir: null``).
"""
from __future__ import annotations

import logging
import sys
from pathlib import Path
from typing import Dict

import hydra
from hydra.core.hydra_config import HydraConfig
from hydra.types import RunMode
from omegaconf import DictConfig, OmegaConf

from gmtiflow import config, pipeline, rundir
from gmtiflow.errors import GmtiflowError

log = logging.getLogger("gmtiflow")


def _hydra_files(cfg: DictConfig) -> Dict[str, str]:
    """What Hydra writes to ``.hydra/`` when ``hydra.output_subdir`` is set (same content)."""
    hc = HydraConfig.get()
    return {"config.yaml": OmegaConf.to_yaml(cfg),
            "hydra.yaml": OmegaConf.to_yaml(HydraConfig.instance().cfg),
            "overrides.yaml": OmegaConf.to_yaml(hc.overrides.task)}


def _run_job(cfg: DictConfig, out_dir: Path) -> None:
    hc = HydraConfig.get()
    ours = hc.output_subdir is None    # else Hydra wrote its files itself (user's choice)
    files = _hydra_files(cfg) if ours else {}
    with rundir.claim(out_dir):
        rundir.check_hydra_outputs(out_dir, [f"{hc.job.name}.log"])
        prepared = []

        def on_prepared() -> None:
            prepared.append(True)
            if files:
                rundir.write_hydra_files(out_dir, files)

        try:
            app = config.to_object(cfg)
            pipeline.run(app, out_dir, on_prepared=on_prepared)
        except GmtiflowError:
            # A run that failed before touching the directory leaves an earlier run's files and
            # config together; a fresh directory (a sweep job) gets the config that failed.
            if files and not prepared and not rundir.holds_earlier_run(out_dir):
                rundir.write_hydra_files(out_dir, files)
            raise


@hydra.main(version_base="1.3", config_path="pkg://gmtiflow.conf", config_name="config")
def _hydra_main(cfg: DictConfig) -> None:
    out_dir = Path(HydraConfig.get().runtime.output_dir)
    try:
        _run_job(cfg, out_dir)
    except GmtiflowError as exc:
        if HydraConfig.get().mode == RunMode.MULTIRUN:
            raise  # let the launcher record this job as failed
        _say(f"{exc}")
        sys.exit(1)
    except OSError as exc:  # a full disk or an unwritable output: one line
        if HydraConfig.get().mode == RunMode.MULTIRUN:
            raise
        _say(f"{exc.filename or out_dir}: {exc.strerror or exc}")
        sys.exit(1)
    except MemoryError:     # a backstop: gmtiflow.budget refuses what it can foresee
        _say("out of memory; reduce scene.duration_s, vehicles.random.count, "
             "fidelity.time_step_s or fidelity.truth_output_dt_s, or set tracker=none "
             "metrics.enabled=false")
        sys.exit(1)


def _say(message: str) -> None:
    """One error line on the console and in the run's log (or on stderr without logging)."""
    log.error("%s", message)
    if not logging.getLogger().handlers:    # hydra/job_logging=disabled: still say it
        print(f"gmtiflow: error: {message}", file=sys.stderr)


def main() -> None:
    """Console script ``gmtiflow``."""
    try:
        _hydra_main()
    except KeyboardInterrupt:
        print("gmtiflow: interrupted; the run directory's outputs.json says complete: false",
              file=sys.stderr)
        sys.exit(130)


if __name__ == "__main__":
    main()
