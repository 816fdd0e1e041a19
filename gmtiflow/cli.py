"""Command-line entry point ``gmtiflow`` (a Hydra application).

The Hydra wrapper only converts the config and calls :func:`gmtiflow.pipeline.run` with the run
directory Hydra chose; errors a user can cause are printed as one line naming what is wrong and
exit with status 1, leaving no run file behind (and no empty run directory,
:func:`gmtiflow.console.discard_failed_run_dir`).

Start-up is kept short: ``--help`` is answered before Hydra is imported, and the pipeline
(matplotlib, the tracker, the sensor) is imported only once the config is valid, so ``--help``
and a config error answer quickly (``benchmarks/startup_time.py``).  The console shows warnings,
errors and a summary at the end; INFO lines go to the run's ``gmtiflow.log`` (``-v`` or
``hydra.verbose=true`` shows them).
"""
from __future__ import annotations

import logging
import sys

from gmtiflow import console

log = logging.getLogger("gmtiflow")
_VERBOSE = False


def _run_job(cfg) -> None:
    """The body of the Hydra job: validate, run, summarise (or one error line and exit 1)."""
    from hydra.core.hydra_config import HydraConfig
    from hydra.types import RunMode

    from gmtiflow import config
    from gmtiflow.errors import GmtiflowError

    hc = HydraConfig.get()
    out_dir = hc.runtime.output_dir
    multirun = hc.mode == RunMode.MULTIRUN
    console.set_verbosity(_VERBOSE or bool(hc.verbose))
    try:
        app = config.to_object(cfg)
        from gmtiflow import pipeline   # heavy: only once the config is valid
        path = pipeline.run(app, out_dir)
    except GmtiflowError as exc:
        if multirun:
            raise  # let the launcher record this job as failed
        log.error("%s", exc)    # console (stderr) and the run's log file, once
        console.discard_failed_run_dir(out_dir)
        sys.exit(1)
    if not multirun:
        print(console.run_summary(path, out_dir))


def _hydra_app():
    """The Hydra-decorated job (built on first use: importing Hydra and the config schema takes
    a second that ``--help`` should not pay)."""
    import hydra

    import gmtiflow.config  # noqa: F401  (registers the structured schema `base_config`)

    return hydra.main(version_base="1.3", config_path="pkg://gmtiflow.conf",
                      config_name="config")(_run_job)


def main() -> None:
    """Console script ``gmtiflow``."""
    global _VERBOSE
    if console.wants_app_help(sys.argv):
        print(console.help_text())
        return
    _VERBOSE = console.pop_verbose_flag(sys.argv)
    _hydra_app()()


if __name__ == "__main__":
    main()
