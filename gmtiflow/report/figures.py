"""The run report's figures, one module per page (:mod:`gmtiflow.report.pages`), re-exported
here so that ``from gmtiflow.report import figures as F; F.map_figure(...)`` keeps working.

Shared helpers (figure creation, subsampling, detection classes, colours) live in
:mod:`gmtiflow.report.common`.
"""
from __future__ import annotations

from .common import (A4_LANDSCAPE, DET_STYLE, OUTCOME_STYLE, RASTER_ABOVE, SNR_FLOOR_DB,  # noqa: F401
                     _col, _note, _scatter, _sub_note, detection_classes, even_subsample,
                     new_figure)
from .pages.map import (_clutter_patches, _draw_roads, _footprint_patch, _track_lines,  # noqa: F401
                        map_figure, revisit_footprints)
from .pages.ospa import EVENT_COLOUR, ospa_figure  # noqa: F401
from .pages.range_rate import clutter_range_rate, range_rate_figure  # noqa: F401
from .pages.sensor import normalised_errors, pd_vs_snr, sensor_figure, swerling1_pd  # noqa: F401
from .pages.timeline import _runs, timeline_figure  # noqa: F401
from .pages.title import title_figure  # noqa: F401
from .pages.track_errors import track_errors_figure  # noqa: F401
