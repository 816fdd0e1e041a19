"""Side-by-side page of ``gmtiflow-report RUN_DIR --tracks T.csv --baseline``: the external
tracks' scores next to the run's own tracker's, on the same truth and metrics config."""
from __future__ import annotations

import math
from typing import Mapping, Optional

import numpy as np
from matplotlib.figure import Figure

from ..common import _col, _note, new_figure
from ..data import n

#: (summary name, label, higher is better) of the rows, in order.
ROWS = (("ospa_mean_m", "OSPA mean (m)", False), ("gospa_mean_m", "GOSPA mean (m)", False),
        ("coverage_mean", "coverage", True), ("track_purity_mean", "track purity", True),
        ("identity_switches", "identity switches", False),
        ("fragmentations", "fragmentations", False),
        ("position_rmse_m", "position RMSE (m)", False),
        ("speed_rmse_mps", "speed RMSE (m/s)", False), ("mota", "MOTA", True),
        ("motp_m", "MOTP (m)", False), ("idf1", "IDF1", True), ("n_tracks", "tracks", None),
        ("stop_id_kept_fraction", "id kept after stops", True),
        ("doppler_blind_id_kept_fraction", "id kept after Doppler-blind gaps", True),
        ("invisible_road_id_kept_fraction", "id kept through tunnels", True),
        ("terrain_id_kept_fraction", "id kept through terrain shadow", True))


def _values(summary: Optional[Mapping]) -> dict:
    if not summary or not n(summary):
        return {}
    return {str(k): float(v) for k, v in zip(summary["name"], summary["value"])}


def _fmt(v: Optional[float]) -> str:
    if v is None or not math.isfinite(v):
        return "–"
    return f"{v:.0f}" if abs(v) >= 100 or float(v).is_integer() else f"{v:.3g}"


def compare_figure(external: Mapping, external_ospa: Mapping, baseline: Optional[Mapping],
                   baseline_ospa: Optional[Mapping], *, external_label: str,
                   baseline_label: str) -> Figure:
    """A table of the two summaries (the better of each row in bold green) and both OSPA series."""
    fig = new_figure()
    fig.suptitle(f"Side by side: {external_label} vs {baseline_label} (same truth, same metrics "
                 f"config)", fontsize=14, weight="bold", x=0.05, ha="left")
    ext, base = _values(external), _values(baseline)
    ax_t = fig.add_axes([0.03, 0.08, 0.46, 0.80])
    ax_t.axis("off")
    if not base:
        _note(ax_t, f"{baseline_label}: the run has no tracker results to compare with")
    cells, colours = [], []
    for name, label, higher in ROWS:
        e, b = ext.get(name), base.get(name)
        row_c = ["white", "white", "white"]
        if higher is not None and e is not None and b is not None and \
                math.isfinite(e) and math.isfinite(b) and e != b:
            better = 1 if (e > b) == higher else 2
            row_c[better] = "#d9f0d3"
        cells.append([label, _fmt(e), _fmt(b)])
        colours.append(row_c)
    table = ax_t.table(cellText=cells, cellColours=colours,
                       colLabels=["metric", external_label[:28], baseline_label[:28]],
                       colWidths=[0.5, 0.25, 0.25], loc="upper center", cellLoc="center",
                       colLoc="center")
    table.auto_set_font_size(False)
    table.set_fontsize(8.5)
    table.scale(1.0, 1.35)
    ax_t.text(0.0, -0.02, "green: the better of the two (lower or higher, as the metric says)",
              transform=ax_t.transAxes, fontsize=8, va="top")
    ax = fig.add_axes([0.56, 0.12, 0.41, 0.70])
    for series, label, colour in ((external_ospa, external_label, "#d6604d"),
                                  (baseline_ospa, baseline_label, "#2166ac")):
        if series is not None and n(series):
            ax.plot(_col(series, "time_s"), _col(series, "ospa_m"), lw=1.2, color=colour,
                    label=f"{label}: mean {_fmt(float(np.nanmean(_col(series, 'ospa_m'))))} m")
    ax.set_ylim(bottom=0)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("OSPA (m)")
    ax.set_title("OSPA over time", fontsize=10)
    ax.grid(alpha=0.3)
    if ax.lines:
        ax.legend(fontsize=8, loc="upper left")
    else:
        _note(ax, "no OSPA series")
    return fig
