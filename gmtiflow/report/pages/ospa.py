"""Page 7: OSPA/GOSPA over time and identity events."""
from __future__ import annotations

import math

import numpy as np
from matplotlib.collections import PolyCollection
from matplotlib.figure import Figure

from gmtiflow.tables import Table

from ..common import RASTER_ABOVE, _col, _note, new_figure
from ..data import n


# Event spans in light, distinct fills; the outcome markers drawn over them are saturated
# (green same id, orange new id, red lost, black identity switch) so the two never share a hue.
EVENT_COLOUR = {"stop": "#bdbdbd", "doppler_blind": "#9ecae1", "terrain": "#c2a5cf",
                "invisible_road": "#dfc27d"}


def event_bars(start_s, width_s, row, *, facecolor, label, height=0.7) -> PolyCollection:
    """One PolyCollection of rectangles [start, start + width] × [row ± height/2]: a single
    artist per event kind (one ``broken_barh`` per event re-ran autoscaling each time and was
    quadratic in the number of events)."""
    s, w, r = (np.asarray(a, float) for a in (start_s, width_s, row))
    h = height / 2
    verts = np.stack([np.c_[s, r - h], np.c_[s + w, r - h], np.c_[s + w, r + h], np.c_[s, r + h]], 1)
    return PolyCollection(verts, facecolors=facecolor, edgecolors="none", alpha=0.9, label=label,
                          rasterized=len(s) > RASTER_ABOVE)


def ospa_figure(ospa: Table, switches: Table, events: Table, *, cutoff_m: float = float("nan"),
                tracker_enabled: bool = True) -> Figure:
    """OSPA/GOSPA over time, cardinalities, and identity events per vehicle."""
    fig = new_figure()
    axes = fig.subplots(3, 1, sharex=True, gridspec_kw=dict(left=0.08, right=0.84, top=0.88,
                                                             bottom=0.08, hspace=0.12,
                                                             height_ratios=[1.2, 0.8, 1.2]))
    a0, a1, a2 = axes
    if n(ospa):
        t = _col(ospa, "time_s")
        a0.plot(t, _col(ospa, "ospa_m"), color="#2166ac", lw=1.2,
                label=f"OSPA (c = {cutoff_m:g} m)" if math.isfinite(cutoff_m) else "OSPA")
        a0.plot(t, _col(ospa, "gospa_m"), color="#b2182b", lw=1.2, label="GOSPA (α = 2)")
        a0.set_ylabel("metric (m)")
        a0.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.005, 1.0), frameon=False)
        for col, label, c in (("n_truth", "vehicles", "k"), ("n_tracks", "tracks", "#2166ac"),
                              ("n_assigned", "assigned pairs (< c)", "#1a9850")):
            if col in ospa:
                a1.step(t, _col(ospa, col), where="post", color=c, lw=1.1, label=label)
        a1.set_ylabel("count")
        a1.yaxis.get_major_locator().set_params(integer=True)
        a1.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.005, 1.0), frameon=False)
    else:
        _note(a0, "no OSPA/GOSPA series (metrics off or no truth)" if tracker_enabled
              else "tracker off: OSPA counts every vehicle as missed" )
    have = False
    if n(events):
        vid, kind = _col(events, "vehicle_id"), _col(events, "kind").astype(str)
        start, dur = _col(events, "start_s").astype(float), _col(events, "duration_s").astype(float)
        for k, c in EVENT_COLOUR.items():
            m = kind == k
            if m.any():
                have = True
                a2.add_collection(event_bars(start[m], np.maximum(dur[m], 0.5), vid[m], facecolor=c,
                                             label=f"{k.replace('_', ' ')} ({int(m.sum())})"))
        if have:
            a2.autoscale_view()
        if "reacquired" in events:
            re = np.asarray(events["reacquired"], bool)
            kept = np.asarray(events["id_kept"], bool) if "id_kept" in events else np.zeros(len(re), bool)
            end = _col(events, "end_s")
            held = _col(events, "track_before") >= 0 if "track_before" in events else np.ones(len(re), bool)
            dly = np.nan_to_num(_col(events, "reacq_delay_s")) if "reacq_delay_s" in events else 0
            for m, mk, c, lab in ((held & kept, "o", "#1a9850", "re-acquired, same id"),
                                  (held & re & ~kept, "s", "#ff7f00", "re-acquired, new id"),
                                  (held & ~re, "X", "#e31a1c", "lost (held before)")):
                if m.any():
                    a2.scatter((end + dly)[m], vid[m], marker=mk, color=c, s=22, zorder=4,
                               edgecolor="k", lw=0.3, label=f"{lab} ({int(m.sum())})",
                               rasterized=m.sum() > RASTER_ABOVE)
    if n(switches):
        have = True
        a2.scatter(_col(switches, "time_s"), _col(switches, "vehicle_id"), marker="|", color="k",
                   s=60, lw=1.2, zorder=5, label=f"identity switch ({n(switches)})",
                   rasterized=n(switches) > RASTER_ABOVE)
    if have:
        a2.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.005, 1.0), frameon=False)
        a2.invert_yaxis()
        a2.yaxis.get_major_locator().set_params(integer=True)
    else:
        _note(a2, "no identity events")
    a2.set_ylabel("vehicle id")
    a2.set_xlabel("time (s)")
    for a in axes:
        a.grid(alpha=0.3)
    fig.suptitle("Tracker: OSPA / GOSPA over time and identity events", fontsize=14,
                 weight="bold", x=0.05, ha="left")
    return fig
