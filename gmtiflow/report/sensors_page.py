"""Report page "sensors" (runs with several sensors): each sensor's coverage and the fused one.

From ``/metrics/sensors`` (:mod:`gmtiflow.coverage`): detection coverage, detection gaps and
Doppler-blind gaps per sensor and for all sensors fused, as bars, with the numbers in a table.
"""
from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from gmtiflow.tables import Table

from .figures import new_figure

COLUMNS = (("detection_coverage", "detection coverage", "{:.3f}"),
           ("detection_gaps", "detection gaps", "{:d}"),
           ("doppler_blind_gaps", "Doppler-blind gaps", "{:d}"),
           ("doppler_blind_gap_s", "Doppler gap span s", "{:.0f}"),
           ("n_detections", "detections", "{:d}"))


def sensors_figure(sensors: Table, window_s: float) -> Figure:
    """Bars of each sensor's and the fused detection coverage and gaps, and their numbers."""
    fig = new_figure()
    names = [str(n) for n in sensors["name"]]
    colors = ["0.45" if sid < 0 else f"C{sid}" for sid in np.asarray(sensors["sensor_id"])]
    x = np.arange(len(names))
    ax = fig.add_subplot(2, 2, 1)
    ax.bar(x, sensors["detection_coverage"], color=colors)
    ax.set_xticks(x, names)
    ax.set_ylim(0, 1)
    ax.set_ylabel("fraction of truth samples")
    ax.set_title(f"Detection coverage (detected within {window_s:g} s)")
    ax = fig.add_subplot(2, 2, 2)
    ax.bar(x - 0.2, sensors["detection_gaps"], width=0.4, color=colors, label="all gaps")
    ax.bar(x + 0.2, sensors["doppler_blind_gaps"], width=0.4, color=colors, hatch="//",
           edgecolor="white", label="Doppler-blind")
    ax.set_xticks(x, names)
    ax.set_ylabel("gaps (vehicle, > window)")
    ax.set_title("Detection gaps (hatched: Doppler-blind)")
    ax.legend(loc="upper right", fontsize=8)
    ax = fig.add_subplot(2, 1, 2)
    ax.axis("off")
    cells = [[fmt.format(int(v) if "d" in fmt else float(v)) for v in sensors[c]]
             for c, _, fmt in COLUMNS]
    ax.table(cellText=cells, rowLabels=[label for _, label, _ in COLUMNS],
             colLabels=names, cellLoc="center", bbox=[0.25, 0.1, 0.7, 0.8])
    fig.suptitle("Sensors: each alone and fused (all sensors' detections together)")
    return fig
