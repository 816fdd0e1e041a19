"""Reports: a PDF per run (:func:`build_run_report`) and a comparison PDF per sweep
(:func:`build_sweep_report`), with matplotlib only (docs/reports.md).

The builders are imported lazily so that ``gmtiflow.config`` (which types ``report:
ReportConfig``) does not pull in matplotlib.
"""
from .config import ReportConfig

__all__ = ["ReportConfig", "build_run_report", "build_sweep_report"]


def build_run_report(cfg: ReportConfig, run_path, out_pdf, extra_pages=()):
    """The run report (:func:`gmtiflow.report.run_report.build_run_report`), imported on first
    call: matplotlib's PDF backend costs a second that ``import gmtiflow.pipeline`` (and with it
    ``gmtiflow --help`` and config errors) should not pay."""
    from .run_report import build_run_report as build
    return build(cfg, run_path, out_pdf, extra_pages)


def __getattr__(name):
    if name == "build_sweep_report":
        from .sweep_report import build_sweep_report
        return build_sweep_report
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
