"""One module per run-report page; each exposes a ``*_figure`` function taking tables and
returning a :class:`matplotlib.figure.Figure` (docs/reports.md)."""
