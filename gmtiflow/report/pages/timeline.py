"""Page 5: the per-vehicle timeline (every look by outcome, stops, tunnels)."""
from __future__ import annotations

from typing import List, Tuple

import numpy as np
from matplotlib.collections import LineCollection, PolyCollection
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from gmtiflow.sensor.outcome import Outcome
from gmtiflow.tables import Table

from ..common import OUTCOME_STYLE, RASTER_ABOVE, _col, _note, new_figure, rectangles
from ..data import n


# ----------------------------------------------------------------------------- page 5: timeline

def _runs(t: np.ndarray, flag: np.ndarray, dt: float) -> List[Tuple[float, float]]:
    """(start, width) of the runs of True in ``flag`` sampled at times ``t``."""
    if not flag.any():
        return []
    f = np.concatenate([[False], flag, [False]]).astype(np.int8)
    starts, ends = np.flatnonzero(np.diff(f) == 1), np.flatnonzero(np.diff(f) == -1) - 1
    return [(t[s], max(t[e] - t[s], 0.0) + dt) for s, e in zip(starts, ends)]


def timeline_figure(vehicles: Table, truth: Table, looks: Table, *,
                    max_vehicles: int = 40) -> Figure:
    """Per vehicle over time: every look by outcome (why it was missed), stops and tunnels;
    on the right the outcome counts."""
    fig = new_figure()
    gs = fig.add_gridspec(1, 2, width_ratios=[4, 1.1], left=0.12, right=0.98, top=0.88,
                          bottom=0.14, wspace=0.05)
    ax, bx = fig.add_subplot(gs[0]), fig.add_subplot(gs[1])
    ids = np.asarray(vehicles["vehicle_id"]) if n(vehicles) else (
        np.unique(truth["vehicle_id"]) if n(truth) else np.zeros(0, np.int64))
    shown = ids[:max_vehicles]
    names = dict(zip(np.asarray(vehicles["vehicle_id"]), np.asarray(vehicles["name"]))) if (
        n(vehicles) and "name" in vehicles) else {}
    row = {int(v): i for i, v in enumerate(shown)}
    if not len(shown):
        _note(ax, "no vehicles")
        return fig
    if n(truth):
        sel = np.flatnonzero(np.isin(_col(truth, "vehicle_id"), shown))   # one pass over truth
        vid_all = _col(truth, "vehicle_id")[sel]
        order = sel[np.lexsort((_col(truth, "time_s")[sel], vid_all))]
        t, vid = _col(truth, "time_s")[order], _col(truth, "vehicle_id")[order]
        u = np.unique(t)
        dt = float(np.median(np.diff(u))) if len(u) > 1 else 1.0
        bounds = np.flatnonzero(np.r_[True, vid[1:] != vid[:-1], True])
        stops, tunnels, spans = [], [], []
        mode = _col(truth, "mode")[order] if "mode" in truth else None
        inv = _col(truth, "invisible")[order].astype(bool) if "invisible" in truth else None
        for a, b in zip(bounds[:-1], bounds[1:]):       # per shown vehicle (≤ max_vehicles)
            r = row[int(vid[a])]
            tt = t[a:b]
            spans.append([(tt[0], r), (tt[-1], r)])
            if mode is not None:
                stops += [(s, w, r) for s, w in _runs(tt, mode[a:b] == 2, dt)]
            if inv is not None:
                tunnels += [(s, w, r) for s, w in _runs(tt, inv[a:b], dt)]
        ax.add_collection(LineCollection(spans, colors="0.85", lw=6, capstyle="butt", zorder=0))
        for runs, style in ((stops, dict(facecolor="#fee08b", edgecolor="#d8b365")),
                            (tunnels, dict(facecolor="none", edgecolor="#543005", hatch="xxx",
                                           lw=0.5))):
            if runs:
                s, w, r = (np.asarray(c, float) for c in zip(*runs))
                ax.add_collection(PolyCollection(rectangles(s, s + w, r - 0.38, r + 0.38),
                                                 zorder=1, **style))
    codes = list(OUTCOME_STYLE)
    # Several sensors: each vehicle row is split into one lane per sensor (sensor 0 on top),
    # for its looks and its outcome counts; one sensor keeps the full row.
    sensors = (np.unique(_col(looks, "sensor_id")) if n(looks) and "sensor_id" in looks
               else np.zeros(1, np.int64))
    lane_h = 0.7 / len(sensors)
    counts = np.zeros((len(sensors), len(shown), len(codes)))
    if n(looks):
        lv, lo, lt = _col(looks, "vehicle_id"), _col(looks, "outcome"), _col(looks, "time_s")
        ls = _col(looks, "sensor_id") if len(sensors) > 1 else None
        row_of = np.full(int(max(lv.max(), shown.max())) + 1, -1)
        row_of[shown] = np.arange(len(shown))
        for k, sid in enumerate(sensors):
            sel = np.isin(lv, shown) if ls is None else np.isin(lv, shown) & (ls == sid)
            rows = row_of[lv[sel]]
            lane = -0.35 + lane_h * (k + 0.5)
            for j, code in enumerate(codes):
                m = lo[sel] == code
                colour, label, size = OUTCOME_STYLE[code]
                if m.any():
                    ax.scatter(lt[sel][m], rows[m] + lane if len(sensors) > 1 else rows[m], s=size,
                               color=colour, marker="|" if code == Outcome.OUTSIDE_FOV else "o",
                               lw=1 if code == Outcome.OUTSIDE_FOV else 0, zorder=3,
                               rasterized=m.sum() > RASTER_ABOVE)
                    counts[k, :, j] = np.bincount(rows[m], minlength=len(shown))
    # Stacked horizontal bars as one collection (barh makes a patch per bar and vehicle).
    right = np.cumsum(counts, axis=2)
    left = right - counts
    r = np.broadcast_to(np.arange(len(shown))[:, None], counts.shape[1:]).ravel()
    lanes = [(r - 0.35, r + 0.35)] if len(sensors) == 1 else [
        (r - 0.35 + lane_h * k, r - 0.35 + lane_h * (k + 1)) for k in range(len(sensors))]
    bars = np.concatenate([rectangles(left[k], right[k], y0, y1)
                           for k, (y0, y1) in enumerate(lanes)])
    colours = np.broadcast_to(np.array([OUTCOME_STYLE[c][0] for c in codes]), counts.shape[1:])
    bx.add_collection(PolyCollection(bars, lw=0, facecolors=np.tile(colours.ravel(),
                                                                     len(sensors))))
    bx.set_xlim(0, max(float(right[:, :, -1].max()) if right.size else 0.0, 1.0) * 1.05)
    labels = [f"{names.get(v, v)} (#{v})" for v in shown]
    ax.set_yticks(np.arange(len(shown)))
    ax.set_yticklabels(labels, fontsize=max(5, min(9, int(300 / max(len(shown), 1)))))
    ax.set_ylim(len(shown) - 0.5, -0.5)
    bx.set_ylim(len(shown) - 0.5, -0.5)
    bx.set_yticks([])
    bx.set_xlabel("looks")
    bx.set_title("outcome counts" if len(sensors) < 2 else "outcome counts per sensor\n(lanes top "
                 "to bottom: sensor " + ", ".join(str(int(v)) for v in sensors) + ")", fontsize=9)
    ax.set_xlabel("time (s)")
    ax.grid(axis="x", alpha=0.3)
    handles = [Line2D([], [], ls="", marker="o", color=OUTCOME_STYLE[c][0], label=OUTCOME_STYLE[c][1])
               for c in codes]
    handles += [Patch(facecolor="#fee08b", edgecolor="#d8b365", label="stopped (truth)"),
                Patch(facecolor="none", edgecolor="#543005", hatch="xxx", label="on invisible road")]
    fig.legend(handles=handles, loc="lower center", ncol=5, fontsize=8, frameon=False)
    more = f" — first {len(shown)} of {len(ids)} vehicles" if len(ids) > len(shown) else ""
    fig.suptitle(f"Per-vehicle timeline: detected, missed and why{more}", fontsize=14,
                 weight="bold", x=0.05, ha="left")
    return fig
