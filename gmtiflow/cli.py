"""The ``gmtiflow`` command: a thin Hydra entry point (``reference/hydra.md``).

The Hydra wrapper only converts the config and calls :func:`gmtiflow.pipeline.run` with the run
directory Hydra chose; errors a user can cause are printed as one line naming what is wrong and
exit with status 1, leaving no run file behind (and no empty run directory,
:func:`gmtiflow.console.discard_failed_run_dir`).  Hydra's composition errors (an unknown group
option or key, a malformed override) are one line too, and at most a hint line
(:func:`_report_composition_errors`).  Ctrl-C prints one line and exits with 130; the
run directory's ``outputs.json`` then still says ``complete: false``.

The run directory (:mod:`gmtiflow.rundir`) is locked for the run, refused if Hydra's outputs in
it are symlinks, and Hydra's ``.hydra/*.yaml`` are written only after the previous run's outputs
are gone (the packaged config sets ``hydra.output_subdir: null``).

Start-up is kept short: ``--help`` is answered before Hydra is imported, and the pipeline
(matplotlib, the tracker, the sensor) is imported only once the config is valid, so ``--help``
and a config error answer quickly (``benchmarks/startup_time.py``).  The console shows warnings,
errors and a summary at the end; INFO lines go to the run's ``gmtiflow.log`` (``-v`` or
``hydra.verbose=true`` shows them).
"""
from __future__ import annotations

import logging
import os
import sys
from pathlib import Path
from typing import Dict

from gmtiflow import console

log = logging.getLogger("gmtiflow")
_VERBOSE = False


def _hydra_files(cfg) -> Dict[str, str]:
    """What Hydra writes to ``.hydra/`` when ``hydra.output_subdir`` is set (same content)."""
    from hydra.core.hydra_config import HydraConfig
    from omegaconf import OmegaConf

    from gmtiflow import config

    hc = HydraConfig.get()
    return {"config.yaml": config.omegaconf_text(cfg),      # OmegaConf.to_yaml's text, faster
            "hydra.yaml": OmegaConf.to_yaml(HydraConfig.instance().cfg),
            "overrides.yaml": OmegaConf.to_yaml(hc.overrides.task)}


def _run_locked(cfg, out_dir: Path):
    """Validate and run inside the locked run directory; returns the run file's path."""
    from hydra.core.hydra_config import HydraConfig

    from gmtiflow import config, rundir
    from gmtiflow.errors import GmtiflowError

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
            from gmtiflow import pipeline   # heavy: only once the config is valid
            return pipeline.run(app, out_dir, on_prepared=on_prepared)
        except GmtiflowError:
            # A run that failed before touching the directory leaves an earlier run's files and
            # config together; a fresh directory (a sweep job) gets the config that failed.
            if files and not prepared and not rundir.holds_earlier_run(out_dir):
                rundir.write_hydra_files(out_dir, files)
            raise


def _run_job(cfg) -> None:
    """The body of the Hydra job: validate, run, summarise (or one error line and exit 1)."""
    from hydra.core.hydra_config import HydraConfig
    from hydra.types import RunMode

    from gmtiflow import interrupts
    from gmtiflow.errors import GmtiflowError

    hc = HydraConfig.get()
    out_dir = Path(hc.runtime.output_dir)
    multirun = hc.mode == RunMode.MULTIRUN
    console.set_verbosity(_VERBOSE or bool(hc.verbose))
    try:
        with interrupts.errors_as_interrupt():     # Ctrl-C that h5py turned into a TypeError
            path = _run_locked(cfg, out_dir)
    except GmtiflowError as exc:
        if multirun:    # the launcher records this job as failed; Hydra prints the message
            from gmtiflow.sweep_errors import JobError
            raise JobError(str(exc), type(exc).__name__) from None
        _say(f"{exc}")
        console.discard_failed_run_dir(out_dir)
        sys.exit(1)
    except OSError as exc:  # a full disk or an unwritable output: one line
        message = f"{exc.filename or out_dir}: {exc.strerror or exc}"
        if multirun:
            from gmtiflow.sweep_errors import JobError
            raise JobError(message, type(exc).__name__) from None
        _say(message)
        sys.exit(1)
    except MemoryError:     # a backstop: gmtiflow.budget refuses what it can foresee
        _say("out of memory; reduce scene.duration_s, vehicles.random.count, "
             "fidelity.time_step_s or fidelity.truth_output_dt_s, or set tracker=none "
             "metrics.enabled=false")
        sys.exit(1)
    if not multirun:
        print(console.run_summary(path, out_dir))


def _say(message: str) -> None:
    """One error line on the console and in the run's log (or on stderr without logging)."""
    log.error("%s", message)
    if not logging.getLogger().handlers:    # hydra/job_logging=disabled: still say it
        print(f"gmtiflow: error: {message}", file=sys.stderr)


def _report_composition_errors() -> None:
    """One line (and at most a hint line) for Hydra's composition errors, exit 1.

    Hydra printed an unknown group option (``sensor=wide_fvo``), an unknown key, a value of the
    wrong type or an override it cannot parse in 6-12 lines (its message, OmegaConf's
    ``full_key`` block, the config search path, "Set the environment variable
    HYDRA_FULL_ERROR=1 ...").  Its reporter ``hydra._internal.utils.run_and_report`` (it runs
    the job, the sweep and ``--cfg``; hydra-core is pinned below 1.4) is wrapped: those errors
    are said as :mod:`gmtiflow.compose_errors` words them; anything else (a sweep job's error,
    a bug) goes to Hydra's reporter as before, and so does everything with
    ``HYDRA_FULL_ERROR=1``."""
    from hydra._internal import utils as hydra_utils

    report = hydra_utils.run_and_report
    if getattr(report, "gmtiflow_composition", False):
        return

    def run_and_report(func):
        return report(lambda: _composed(func))

    run_and_report.gmtiflow_composition = True
    hydra_utils.run_and_report = run_and_report


def _composed(func):
    """``func()``; a composition error said in one line (and a hint), exit 1."""
    from gmtiflow.compose_errors import COMPOSITION_ERRORS, composition_error
    try:
        return func()
    except COMPOSITION_ERRORS as exc:
        error = composition_error(exc)
        if error is None or os.environ.get("HYDRA_FULL_ERROR") == "1":
            raise
        _discard_empty_sweep_dir(exc)
        print(f"gmtiflow: error: {error}", file=sys.stderr)
        if error.hint:
            print(f"gmtiflow: hint: {error.hint}", file=sys.stderr)
        sys.exit(1)


def _discard_empty_sweep_dir(exc: BaseException) -> None:
    """A sweep refused when its jobs are composed leaves the sweep directory holding only the
    ``multirun.yaml`` Hydra wrote before composing them: removed (and Hydra's
    ``multirun/<date>`` when that became empty), as :func:`gmtiflow.console.
    discard_failed_run_dir` removes a run directory that did no work.  The directory is the
    sweeper's (its ``sweep_dir`` on ``exc``'s stack: the launching process has no HydraConfig);
    one holding anything else is left alone."""
    import re

    tb, sweep = exc.__traceback__, None
    while tb is not None:
        found = tb.tb_frame.f_locals.get("sweep_dir") if tb.tb_frame.f_code.co_name == "sweep" \
            else None
        sweep = Path(found) if isinstance(found, (str, Path)) else sweep
        tb = tb.tb_next
    if sweep is None:
        return
    try:
        if [p.name for p in sweep.iterdir()] != ["multirun.yaml"]:
            return
        (sweep / "multirun.yaml").unlink()
        sweep.rmdir()
        if re.fullmatch(r"\d{4}-\d{2}-\d{2}", sweep.parent.name):     # multirun/<date>
            sweep.parent.rmdir()                                     # only when empty
    except OSError:
        pass


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
    from gmtiflow import allocator, interrupts
    allocator.tune()        # before the run allocates: large temporaries reused, not faulted
    interrupts.install()
    _report_composition_errors()
    try:
        _hydra_app()()
    except KeyboardInterrupt:
        print("gmtiflow: interrupted; the run directory's outputs.json says complete: false",
              file=sys.stderr)
        sys.exit(130)


if __name__ == "__main__":
    main()
