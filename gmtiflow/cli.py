"""Command-line entry point ``gmtiflow`` (a Hydra application).

The Hydra wrapper only converts the config and calls :func:`gmtiflow.pipeline.run` with the run
directory Hydra chose; errors a user can cause are printed as one line naming what is wrong and
exit with status 1, leaving no run file behind.
"""
from __future__ import annotations

import logging
import sys

import hydra
from hydra.core.hydra_config import HydraConfig
from hydra.types import RunMode
from omegaconf import DictConfig

from gmtiflow import config, pipeline
from gmtiflow.errors import GmtiflowError

log = logging.getLogger("gmtiflow")


@hydra.main(version_base="1.3", config_path="pkg://gmtiflow.conf", config_name="config")
def _hydra_main(cfg: DictConfig) -> None:
    out_dir = HydraConfig.get().runtime.output_dir
    try:
        app = config.to_object(cfg)
        pipeline.run(app, out_dir)
    except GmtiflowError as exc:
        if HydraConfig.get().mode == RunMode.MULTIRUN:
            raise  # let the launcher record this job as failed
        log.error("%s", exc)    # console (stderr) and the run's log file, once
        sys.exit(1)


def main() -> None:
    """Console script ``gmtiflow``."""
    _hydra_main()


if __name__ == "__main__":
    main()
