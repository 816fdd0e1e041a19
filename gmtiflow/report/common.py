"""Helpers shared by the report pages: figure creation, even subsampling, notes, the
detection classes and the colour styles.

Figures are built with :class:`matplotlib.figure.Figure` and an Agg canvas, never through
``pyplot``, so building a report touches no global state and works in any thread or worker.
Dense layers are subsampled evenly to ``max_points`` (the title says "every k-th") and
rasterised in the PDF above a few thousand points, so big runs stay fast and small.

Units on the pages: km for map coordinates, degrees for angles, m/s for speeds, dB for SNR.
"""
from __future__ import annotations

import math
from typing import Dict

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from gmtiflow.sensor.outcome import Outcome
from gmtiflow.tables import Table

from .data import n

A4_LANDSCAPE = (11.69, 8.27)
SNR_FLOOR_DB = -10.0  # the P_D-vs-SNR plot starts here (lower bins hold notch-suppressed looks)
RASTER_ABOVE = 500  # points per layer above which a layer is rasterised in the PDF (vector markers cost ~50 µs each)

OUTCOME_STYLE = {  # colour, label, marker size on the timeline
    Outcome.DETECTED: ("#1a9850", "detected", 9),
    Outcome.MERGED: ("#984ea3", "merged", 9),
    Outcome.PD_MISS: ("#d73027", "missed: P_D draw", 9),
    Outcome.DOPPLER_BLIND: ("#fc8d59", "missed: Doppler notch", 9),
    Outcome.TERRAIN: ("#8c510a", "missed: terrain", 9),
    Outcome.INVISIBLE_ROAD: ("#543005", "missed: tunnel", 9),
    Outcome.OUTSIDE_FOV: ("#bdbdbd", "outside FoV", 3),
}
DET_STYLE = {  # detection class -> colour, marker, label
    "true": ("#2166ac", "o", "true detection"),
    "merged": ("#984ea3", "D", "merged report"),
    "false": ("#d6604d", "x", "false alarm"),
}


# ----------------------------------------------------------------------------- helpers

def new_figure(size=A4_LANDSCAPE) -> Figure:
    fig = Figure(figsize=size)
    FigureCanvasAgg(fig)
    return fig


def even_subsample(count: int, max_count: int) -> np.ndarray:
    """Indices of at most ``max_count`` of ``count`` items, evenly spread (all when few)."""
    if count <= max_count:
        return np.arange(count)
    return np.unique(np.linspace(0, count - 1, max_count).round().astype(np.int64))


def rectangles(x0, x1, y0, y1) -> np.ndarray:
    """Vertices (N, 4, 2) of axis-aligned rectangles, for one PolyCollection: drawing N bars
    as one collection costs what one bar does (``bar``/``barh`` make a patch, and redo the
    autoscale, per bar)."""
    x0, x1, y0, y1 = np.broadcast_arrays(*(np.ravel(np.asarray(v, float)) for v in (x0, x1, y0, y1)))
    return np.stack([np.c_[x0, y0], np.c_[x1, y0], np.c_[x1, y1], np.c_[x0, y1]], 1)


def _note(ax, text: str) -> None:
    ax.text(0.5, 0.5, text, transform=ax.transAxes, ha="center", va="center", fontsize=11,
            color="0.35", wrap=True)


def _col(table: Table, name: str, idx=None) -> np.ndarray:
    col = np.asarray(table[name])
    return col if idx is None else col[idx]


def _sub_note(count: int, kept: int) -> str:
    return "" if kept >= count else f" (every {math.ceil(count / max(kept, 1))}th of {count})"


def _scatter(ax, x, y, *, max_points: int, **kw):
    idx = even_subsample(len(x), max_points)
    kw.setdefault("rasterized", len(idx) > RASTER_ABOVE)
    return ax.scatter(np.asarray(x)[idx], np.asarray(y)[idx], **kw), len(idx)


def detection_classes(det: Table) -> Dict[str, np.ndarray]:
    """Row masks of the three detection classes: true (unmerged), merged, false alarm."""
    if not n(det):
        return {k: np.zeros(0, bool) for k in DET_STYLE}
    false = np.asarray(det["truth_id"]) < 0
    merged = np.asarray(det["merged"], bool) & ~false
    return {"true": ~false & ~merged, "merged": merged, "false": false}

