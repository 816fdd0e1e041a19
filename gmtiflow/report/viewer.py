"""The scene viewer: one self-contained, offline HTML file per run (``viewer.html``).

``gmtiflow-view RUN_DIR`` (or ``report.viewer=true`` on a run) reads the finished ``run.h5`` and
writes a plotly figure with its JavaScript embedded (no CDN, no server): the road map (tunnels
dashed), the platform and the beam footprint of the current revisit, truth vehicles with ids and
short trails, that revisit's detections coloured by kind (target / false alarm / merged /
folded-or-wrapped), confirmed tracks with ids and 2σ covariance ellipses, and on hover each
vehicle's look outcome in that revisit (detected, or why it was missed).  A time slider and
play/pause step through the revisits; a readout shows the cursor's latitude/longitude.

Responsiveness on big runs (docs/reports.md, "Scene viewer"): at most ``viewer_max_frames``
frames, evenly spread over the revisits; coordinates rounded to 1 m and shipped as typed
arrays; trails, text labels and covariance ellipses only while a frame holds at most
``viewer_max_labels`` vehicles/tracks (hover still names every one).  The browser holds every
frame in memory and redraws only the moving traces.

``viewer.html#frame=N`` opens at frame N (used by the browser test; also a way to share a
moment of a run).  Coordinates: east/north km about the run's origin; lat/lon by the local
tangent-plane approximation used for the readout only.
"""
from __future__ import annotations

import json
import logging
import math
from pathlib import Path
from typing import Dict, List, Optional

import numpy as np

from gmtiflow.formats import atomic_path
from gmtiflow.sensor.outcome import Outcome

from .data import RunData, load_run, n

log = logging.getLogger(__name__)

KM = 1e3
EARTH_RADIUS_M = 6371008.8
TABLES = ("roads/nodes", "roads/edges", "vehicles", "truth", "platform", "dwells", "detections",
          "looks", "tracks")
DET_KINDS = {  # kind -> (colour, marker symbol, legend label)
    "target": ("#2166ac", "circle", "detection: target"),
    "false": ("#d6604d", "x", "detection: false alarm"),
    "merged": ("#984ea3", "diamond", "detection: merged"),
    "folded": ("#ff7f00", "triangle-up", "detection: range-folded / Doppler-wrapped"),
}
OUTCOME_TEXT = {int(Outcome.DETECTED): "detected", int(Outcome.MERGED): "merged into another report",
                int(Outcome.PD_MISS): "missed: P_D draw", int(Outcome.DOPPLER_BLIND): "missed: Doppler notch",
                int(Outcome.TERRAIN): "missed: terrain (no line of sight)",
                int(Outcome.INVISIBLE_ROAD): "missed: tunnel", int(Outcome.OUTSIDE_FOV): "outside the beam"}


def detection_kinds(det) -> Dict[str, np.ndarray]:
    """Row masks: folded (range-folded or Doppler-wrapped: drawn where the radar put them),
    then false alarm, merged, and target (the rest).  Every detection is in exactly one."""
    if not n(det):
        return {k: np.zeros(0, bool) for k in DET_KINDS}
    folded = np.zeros(n(det), bool)
    for flag in ("range_folded", "doppler_wrapped"):
        if flag in det:
            folded |= np.asarray(det[flag], bool)
    false = (np.asarray(det["truth_id"]) < 0) & ~folded
    merged = np.asarray(det["merged"], bool) & ~folded & ~false
    return {"target": ~(folded | false | merged), "false": false, "merged": merged, "folded": folded}


def covariance_ellipses(x, y, cxx, cxy, cyy, n_sigma: float = 2.0, points: int = 24):
    """NaN-separated polylines of the ``n_sigma`` ellipses of 2×2 covariances (vectorised)."""
    x, y, a, b, c = (np.asarray(v, float) for v in (x, y, cxx, cxy, cyy))
    if not len(x):
        return np.zeros(0), np.zeros(0)
    tr, det = a + c, a * c - b * b
    disc = np.sqrt(np.maximum(tr * tr / 4 - det, 0.0))
    l1, l2 = np.maximum(tr / 2 + disc, 0.0), np.maximum(tr / 2 - disc, 0.0)
    theta = 0.5 * np.arctan2(2 * b, a - c)          # major-axis angle from +x
    t = np.linspace(0, 2 * np.pi, points)
    u = n_sigma * np.sqrt(l1)[:, None] * np.cos(t)
    v = n_sigma * np.sqrt(l2)[:, None] * np.sin(t)
    ex = x[:, None] + u * np.cos(theta)[:, None] - v * np.sin(theta)[:, None]
    ey = y[:, None] + u * np.sin(theta)[:, None] + v * np.cos(theta)[:, None]
    nan = np.full((len(x), 1), np.nan)
    return np.hstack([ex, nan]).ravel(), np.hstack([ey, nan]).ravel()


def _road_lines(nodes, edges, invisible: bool):
    if not (n(nodes) and n(edges)):
        return np.zeros(0), np.zeros(0)
    x = np.full(int(np.max(nodes["node_id"])) + 1, np.nan)
    y = x.copy()
    x[nodes["node_id"]], y[nodes["node_id"]] = nodes["x_m"], nodes["y_m"]
    inv = np.asarray(edges["invisible"], bool) if "invisible" in edges else np.zeros(n(edges), bool)
    m = inv if invisible else ~inv
    a, b = np.asarray(edges["from_node"])[m], np.asarray(edges["to_node"])[m]
    nan = np.full(m.sum(), np.nan)
    return (np.stack([x[a], x[b], nan], 1).ravel() / KM, np.stack([y[a], y[b], nan], 1).ravel() / KM)


def _footprint(dwells, rows, origin) -> tuple:
    """Ground outline (km) of the union of a revisit's dwell beams: azimuth ± half extent,
    slant range window turned into ground range at the area centre's height."""
    from gmtiflow.frames import geodetic_to_enu, wrap_pi
    mid = rows[len(rows) // 2]
    px, py, pz = (float(dwells[k][mid]) for k in ("platform_x_m", "platform_y_m", "platform_z_m"))
    ax_, ay_, az_ = geodetic_to_enu(origin, float(dwells["area_lat_deg"][mid]),
                                    float(dwells["area_lon_deg"][mid]), origin.height_m)
    slant = math.sqrt((float(ax_) - px) ** 2 + (float(ay_) - py) ** 2 + (float(az_) - pz) ** 2)
    half = float(dwells["range_half_extent_m"][mid])
    h = pz - float(az_)
    g0, g1 = (math.sqrt(max(s * s - h * h, 0.0)) for s in (max(slant - half, abs(h)), slant + half))
    beam = np.asarray(dwells["beam_az_rad"])[rows]
    beam = beam[0] + wrap_pi(beam - beam[0])
    width = np.asarray(dwells["angle_half_extent_rad"])[rows]
    az = np.linspace(float(np.min(beam - width)), float(np.max(beam + width)), 16)
    xs = np.r_[px + g0 * np.sin(az), px + g1 * np.sin(az[::-1]), px + g0 * np.sin(az[0])]
    ys = np.r_[py + g0 * np.cos(az), py + g1 * np.cos(az[::-1]), py + g0 * np.cos(az[0])]
    return xs / KM, ys / KM, px / KM, py / KM


def frame_of_dwells(dwells) -> np.ndarray:
    """The viewer frame of each dwell: frame k holds the k-th revisit of the first sensor and
    every other sensor's dwells since the previous one ended (one sensor: frame = revisit)."""
    if not n(dwells):
        return np.zeros(0, np.int64)
    rev = np.asarray(dwells["revisit_id"] if "revisit_id" in dwells else dwells["dwell_id"])
    sensor = np.asarray(dwells["sensor_id"]) if "sensor_id" in dwells else np.zeros(len(rev), int)
    time_s = np.asarray(dwells["time_s"], float)
    clock = sensor == sensor.min()
    revs, inverse = np.unique(rev[clock], return_inverse=True)
    ends = np.full(len(revs), -np.inf)
    np.maximum.at(ends, inverse, time_s[clock])
    ends = np.maximum.accumulate(ends)
    frame = np.searchsorted(ends, time_s, side="left")      # first revisit end at or after
    out = np.minimum(frame, len(revs) - 1)
    out[clock] = inverse
    return out.astype(np.int64)


def sensor_names(run: RunData) -> Dict[int, str]:
    """sensor_id -> name: ``sensor_name`` then the ``sensors`` entries in order (the run's
    sensor ids follow that order), else "sensor N"."""
    names = [str(run.cfg("sensor_name", "main"))] + [str(k) for k in (run.cfg("sensors", {}) or {})]
    ids = np.unique(np.asarray(run.table("dwells").get("sensor_id", np.zeros(1, int))))
    return {int(i): names[int(i)] if int(i) < len(names) else f"sensor {int(i)}" for i in ids}


SENSOR_COLOURS = ("#fdae61", "#74add1", "#a6d96a", "#f46d43", "#c2a5cf", "#fee090")
"""Beam footprint (and platform outline) colour of sensor 0, 1, ... (cycled)."""


def _r(a, digits=3):
    """Km rounded to 1 m as float32 (plotly ships typed arrays: 4 bytes a value instead of 8;
    float32 keeps 1 m up to ~8,000 km); NaN stays NaN (a line break for plotly)."""
    return np.round(np.asarray(a, float), digits).astype(np.float32)


class _Frames:
    """Per-frame selections over time-sorted tables (searchsorted slices, no full scans)."""

    def __init__(self, run: RunData):
        t = run.table
        self.truth = self._sorted(t("truth"), "time_s")
        self.tracks = self._sorted(t("tracks"), "time_s")
        det, dwells, looks = t("detections"), t("dwells"), t("looks")
        self.dwells = dwells
        rev = frame_of_dwells(dwells)
        self.revisits = np.unique(rev) if n(dwells) else np.zeros(0, np.int64)
        self.dwell_rev = rev
        self.sensor_of_dwell = np.asarray(dwells["sensor_id"]) if "sensor_id" in dwells else \
            np.zeros(n(dwells), np.int64)
        did = np.asarray(dwells["dwell_id"]) if n(dwells) else np.zeros(0, np.int64)
        order = np.argsort(did)
        self._did_sorted, self._rev_sorted = did[order], rev[order] if n(dwells) else rev

        def rev_col(table):
            if not n(table):
                return np.zeros(0, np.int64)
            pos = np.clip(np.searchsorted(self._did_sorted, np.asarray(table["dwell_id"])), 0,
                          max(len(self._did_sorted) - 1, 0))
            return self._rev_sorted[pos]
        self.det = self._sorted(dict(det, _rev=rev_col(det)), "_rev") if n(det) else {}
        self.det_kind = detection_kinds(self.det)
        self.looks = self._sorted(dict(looks, _rev=rev_col(looks)), "_rev") if n(looks) else {}
        self.names = {}
        veh = t("vehicles")
        if n(veh) and "name" in veh:
            self.names = dict(zip(np.asarray(veh["vehicle_id"]).tolist(),
                                  [str(s) for s in veh["name"]]))

    @staticmethod
    def _sorted(table, key):
        if not n(table):
            return {}
        order = np.argsort(np.asarray(table[key]), kind="stable")
        return {k: np.asarray(v)[order] for k, v in table.items()}

    @staticmethod
    def window(table, key, lo, hi):
        """Row slice of ``table`` (sorted by ``key``) with lo < key <= hi."""
        if not n(table):
            return slice(0, 0)
        col = table[key]
        return slice(int(np.searchsorted(col, lo, "right")), int(np.searchsorted(col, hi, "right")))


def build_viewer(run_path, out_html, *, max_frames: int = 150, max_labels: int = 60,
                 trail_s: float = 30.0) -> Path:
    """Write the scene viewer of the finished run file ``run_path`` to ``out_html``; returns it."""
    import plotly.graph_objects as go

    run = load_run(run_path, TABLES)
    out_html = Path(out_html)
    t = run.table
    fr = _Frames(run)
    origin = run.origin
    revisit_s = float(run.cfg("sensor.revisit_s", 5.0) or 5.0)
    # The frames: evenly spread revisits, each shown at the end time of its last dwell.
    revs = fr.revisits
    if len(revs) > max_frames:
        revs = revs[np.unique(np.linspace(0, len(revs) - 1, max_frames).round().astype(int))]
    dw_t = np.asarray(fr.dwells["time_s"]) if n(fr.dwells) else np.zeros(0)
    truth_times = np.unique(fr.truth["time_s"]) if n(fr.truth) else np.zeros(0)

    static: List = []
    rx, ry = _road_lines(t("roads/nodes"), t("roads/edges"), invisible=False)
    static.append(go.Scattergl(x=_r(rx), y=_r(ry), mode="lines", line=dict(color="#9e9e9e", width=1.5),
                               name="road", hoverinfo="skip"))
    tx_, ty_ = _road_lines(t("roads/nodes"), t("roads/edges"), invisible=True)
    static.append(go.Scatter(x=_r(tx_), y=_r(ty_), mode="lines", name="tunnel (invisible road)",
                             line=dict(color="#8c510a", width=2.5, dash="dash"), hoverinfo="skip"))
    plat = t("platform")
    names = sensor_names(run)
    several = len(names) > 1
    plat_sid = np.asarray(plat["sensor_id"]) if "sensor_id" in plat else np.zeros(n(plat), int)
    plat_by_sensor = {}
    for sid in names:
        m = plat_sid == sid
        if not m.any():
            continue
        order = np.argsort(np.asarray(plat["time_s"])[m], kind="stable")
        ps = {c: np.asarray(plat[c])[m][order] for c in ("time_s", "x_m", "y_m")}
        plat_by_sensor[sid] = ps
        k = max(1, len(ps["time_s"]) // 2000)
        static.append(go.Scatter(x=_r(ps["x_m"][::k] / KM), y=_r(ps["y_m"][::k] / KM),
                                 mode="lines", line=dict(color="#636363", width=1),
                                 name=f"platform track: {names[sid]}" if several else
                                 "platform track", hoverinfo="skip"))

    def frame_traces(rev) -> List:
        rows_all = np.flatnonzero(fr.dwell_rev == rev)
        te = float(dw_t[rows_all].max()) if len(rows_all) else 0.0
        out = []
        for j, (sid, name) in enumerate(names.items()):
            rows = rows_all[fr.sensor_of_dwell[rows_all] == sid]
            fx, fy, _, _ = _footprint(fr.dwells, rows, origin) if len(rows) else ([], [], 0, 0)
            ps = plat_by_sensor.get(sid)
            if ps is not None and len(ps["time_s"]):     # where that aircraft is at te
                i = int(np.clip(np.searchsorted(ps["time_s"], te, "right") - 1, 0,
                                len(ps["time_s"]) - 1))
                px, py = [float(ps["x_m"][i]) / KM], [float(ps["y_m"][i]) / KM]
            else:
                px = py = []
            colour = SENSOR_COLOURS[j % len(SENSOR_COLOURS)]
            rgb = tuple(int(colour[k:k + 2], 16) for k in (1, 3, 5))
            label = f": {name}" if several else ""
            out.append(go.Scatter(x=_r(fx), y=_r(fy), mode="lines", fill="toself",
                                  name=f"beam footprint{label}", line=dict(color=colour, width=1),
                                  fillcolor="rgba(%d,%d,%d,0.18)" % rgb, hoverinfo="skip"))
            out.append(go.Scatter(x=px, y=py, mode="markers", name=f"platform{label}",
                                  marker=dict(symbol="triangle-up", size=12, color="black",
                                              line=dict(color=colour, width=2)),
                                  hovertemplate=f"platform{label} at t = {te:.1f} s<extra></extra>"))
        # truth at the last sample not after te, with the look outcome of this revisit
        tx = ty = np.zeros(0)
        hover: List[str] = []
        ids = np.zeros(0, np.int64)
        trail_x = trail_y = np.zeros(0)
        if len(truth_times):
            i = int(np.searchsorted(truth_times, te, "right")) - 1
            if i >= 0:
                tnow = truth_times[i]
                s = _Frames.window(fr.truth, "time_s", np.nextafter(tnow, -np.inf), tnow)
                ids = fr.truth["vehicle_id"][s]
                labels_on = len(ids) <= max_labels
                tx, ty = fr.truth["x_m"][s] / KM, fr.truth["y_m"][s] / KM
                spd = fr.truth["speed_mps"][s] if "speed_mps" in fr.truth else np.full(len(ids), np.nan)
                looks_of: Dict[int, List[str]] = {}     # vehicle -> its looks this frame
                if n(fr.looks):
                    ls = _Frames.window(fr.looks, "_rev", rev - 0.5, rev + 0.5)
                    lsid = fr.looks["sensor_id"][ls].tolist() if "sensor_id" in fr.looks \
                        else [0] * (ls.stop - ls.start)
                    for v, o, sd in zip(fr.looks["vehicle_id"][ls].tolist(),
                                        fr.looks["outcome"][ls].tolist(), lsid):
                        who = f" ({names.get(sd, sd)})" if several else ""
                        looks_of.setdefault(v, []).append(f"look{who}: {OUTCOME_TEXT.get(o, o)}")
                hover = [f"vehicle {v} {fr.names.get(v, '') if labels_on else ''}<br>{sp:.1f} m/s"
                         "<br>" + ("<br>".join(looks_of[v]) if v in looks_of
                                   else "look: none this revisit")
                         for v, sp in zip(ids.tolist(), spd.tolist())]
                if len(ids) <= max_labels and trail_s > 0:
                    w = _Frames.window(fr.truth, "time_s", tnow - trail_s, tnow)
                    vv = fr.truth["vehicle_id"][w]
                    o = np.lexsort((fr.truth["time_s"][w], vv))
                    xs, ys, vv = fr.truth["x_m"][w][o] / KM, fr.truth["y_m"][w][o] / KM, vv[o]
                    brk = np.flatnonzero(np.diff(vv)) + 1
                    trail_x, trail_y = np.insert(xs, brk, np.nan), np.insert(ys, brk, np.nan)
        labels = len(ids) <= max_labels
        out.append(go.Scatter(x=_r(trail_x), y=_r(trail_y), mode="lines", name="truth trail",
                              line=dict(color="#35978f", width=2), opacity=0.5, hoverinfo="skip"))
        out.append(go.Scatter(x=_r(tx), y=_r(ty), mode="markers+text" if labels else "markers",
                              text=[str(v) for v in ids.tolist()] if labels else None,
                              textposition="top right", textfont=dict(size=9, color="#01665e"),
                              name="truth vehicle", hovertext=hover, hoverinfo="text",
                              marker=dict(size=9, color="#35978f", line=dict(color="white", width=1))))
        # this revisit's detections by kind
        ds = _Frames.window(fr.det, "_rev", rev - 0.5, rev + 0.5) if n(fr.det) else slice(0, 0)
        for kind, (colour, symbol, label) in DET_KINDS.items():
            m = fr.det_kind[kind][ds] if n(fr.det) else np.zeros(0, bool)
            dx = fr.det["x_m"][ds][m] / KM if n(fr.det) else np.zeros(0)
            dy = fr.det["y_m"][ds][m] / KM if n(fr.det) else np.zeros(0)
            sids = fr.det["sensor_id"][ds][m].tolist() if n(fr.det) and "sensor_id" in fr.det \
                else [0] * int(m.sum())
            txt = [f"{label}<br>det {d}, truth {tid}" + (f"<br>sensor {names.get(sd, sd)}"
                                                         if several else "")
                   for d, tid, sd in zip(fr.det["det_id"][ds][m].tolist(),
                                         fr.det["truth_id"][ds][m].tolist(), sids)] \
                if n(fr.det) else []
            out.append(go.Scatter(x=_r(dx), y=_r(dy), mode="markers", name=label, hovertext=txt,
                                  hoverinfo="text", marker=dict(symbol=symbol, size=8, color=colour,
                                                               line=dict(width=1, color=colour))))
        # confirmed tracks updated within the last revisit period: position, id, 2σ ellipse
        kx = ky = ex = ey = np.zeros(0)
        kid = np.zeros(0, np.int64)
        if n(fr.tracks):
            w = _Frames.window(fr.tracks, "time_s", te - revisit_s, te)
            conf = fr.tracks["confirmed"][w].astype(bool) if "confirmed" in fr.tracks else \
                np.ones(w.stop - w.start, bool)
            tid = fr.tracks["track_id"][w][conf]
            order = np.lexsort((fr.tracks["time_s"][w][conf], tid))
            tid_o = tid[order]
            keep = order[np.r_[tid_o[1:] != tid_o[:-1], True]] if len(tid_o) else order
            sel = {k: v[w][conf][keep] for k, v in fr.tracks.items()}
            kid, kx, ky = sel["track_id"], sel["x_m"] / KM, sel["y_m"] / KM
            if "cov_xx_m2" in sel and len(kid) <= max_labels:
                ex, ey = covariance_ellipses(sel["x_m"], sel["y_m"], sel["cov_xx_m2"],
                                             sel["cov_xy_m2"], sel["cov_yy_m2"])
                ex, ey = ex / KM, ey / KM
        out.append(go.Scatter(x=_r(ex), y=_r(ey), mode="lines", name="track 2σ ellipse",
                              line=dict(color="#762a83", width=1), hoverinfo="skip"))
        tlabels = len(kid) <= max_labels
        out.append(go.Scatter(x=_r(kx), y=_r(ky), mode="markers+text" if tlabels else "markers",
                              text=[f"T{v}" for v in kid.tolist()] if tlabels else None,
                              textposition="bottom left", textfont=dict(size=9, color="#762a83"),
                              name="track (confirmed)", hovertext=[f"track {v}" for v in kid.tolist()],
                              hoverinfo="text", marker=dict(symbol="square-open", size=10,
                                                            color="#762a83", line=dict(width=2))))
        return out, te

    # initial view: the scene (roads and truth), not the far-away orbit; terrain under it
    pts_x = [a for a in (rx, fr.truth.get("x_m", np.zeros(0)) / KM) if len(a)]
    pts_y = [a for a in (ry, fr.truth.get("y_m", np.zeros(0)) / KM) if len(a)]
    view = _initial_view(pts_x, pts_y)
    relief_trace, relief_note = _relief_trace(run, view)
    if relief_trace is not None:
        static.insert(0, relief_trace)
    first, _ = frame_traces(revs[0]) if len(revs) else ([], 0.0)
    n_static = len(static)
    dyn_idx = list(range(n_static, n_static + len(first)))
    frames, steps = [], []
    for k, rev in enumerate(revs):
        traces, te = frame_traces(rev) if k else (first, float(dw_t[fr.dwell_rev == rev].max()))
        frames.append(go.Frame(data=traces, traces=dyn_idx, name=str(k)))
        steps.append(dict(method="animate", label=f"{te:.0f}",
                          args=[[str(k)], dict(mode="immediate", frame=dict(duration=0, redraw=False),
                                               transition=dict(duration=0))]))
    fig = go.Figure(data=static + first, frames=frames)
    layout = dict(
        title=dict(text=f"gmtiflow scene viewer — {run.path}", font=dict(size=14)),
        xaxis=dict(title="east (km)", scaleanchor="y", scaleratio=1, zeroline=False),
        yaxis=dict(title="north (km)", zeroline=False),
        hovermode="closest", template="plotly_white", height=820,
        legend=dict(orientation="v", x=1.01, y=1, font=dict(size=11)),
        margin=dict(l=60, r=20, t=60, b=40),
        updatemenus=[dict(type="buttons", direction="left", x=0.0, y=-0.06, xanchor="left",
                          yanchor="top", showactive=False, buttons=[
                              dict(label="▶ play", method="animate",
                                   args=[None, dict(frame=dict(duration=400, redraw=False),
                                                    transition=dict(duration=0), fromcurrent=True)]),
                              dict(label="❚❚ pause", method="animate",
                                   args=[[None], dict(mode="immediate", frame=dict(duration=0),
                                                      transition=dict(duration=0))])])],
        sliders=[dict(active=0, steps=steps, x=0.12, y=-0.04, len=0.88, xanchor="left",
                      yanchor="top", currentvalue=dict(prefix="t = ", suffix=" s"),
                      pad=dict(t=0))] if steps else [],
    )
    if view is not None:
        layout["xaxis"]["range"], layout["yaxis"]["range"] = view
    if relief_note:
        layout["annotations"] = [dict(text=relief_note, xref="paper", yref="paper", x=0, y=1,
                                      xanchor="left", yanchor="bottom", showarrow=False,
                                      font=dict(size=10, color="#8c510a"))]
    attribution = str(run.attrs.get("attribution", "") or "")
    if attribution:
        layout.setdefault("annotations", []).append(dict(
                                      text=attribution if "©" in attribution else f"© {attribution}",
                                      xref="paper", yref="paper", x=1, y=0, xanchor="right",
                                      yanchor="bottom", showarrow=False, font=dict(size=10)))
    fig.update_layout(**layout)
    html = _page(fig, origin, len(frames))
    with atomic_path(out_html, suffix=".partial.html") as tmp:
        Path(tmp).write_text(html, encoding="utf-8")
    log.info("viewer %s: %d frames, %.1f MB", out_html, len(frames), out_html.stat().st_size / 1e6)
    return out_html


def _initial_view(pts_x, pts_y):
    """([x0, x1], [y0, y1]) km around the roads and truth (8 % margin), or None."""
    if not pts_x:
        return None
    allx, ally = np.concatenate(pts_x), np.concatenate(pts_y)
    allx, ally = allx[np.isfinite(allx)], ally[np.isfinite(ally)]
    if not len(allx):
        return None
    pad = 0.08 * max(np.ptp(allx), np.ptp(ally), 0.5)
    return ([float(allx.min() - pad), float(allx.max() + pad)],
            [float(ally.min() - pad), float(ally.max() + pad)])


def _relief_trace(run: RunData, view):
    """(trace, note): the run's terrain (gmtiflow.report.relief) over the initial view as a
    heatmap of its hill shading — transparent where level or lit, brown where a slope faces
    away from the light (north-west) — with the ground height on hover; (None, "") for flat
    ground, (None, why) when the run's DEM cannot be read."""
    import plotly.graph_objects as go

    from .relief import relief_grid, run_terrain, shadow, terrain_source
    terrain, note = run_terrain(run.config, run.origin)
    if terrain is None or view is None:
        return None, note
    relief = relief_grid(terrain, np.asarray(view[0]) * KM, np.asarray(view[1]) * KM,
                         cells=200, source=terrain_source(run.config))
    if relief is None:
        return None, note
    z = np.where(np.isfinite(relief.height_m), shadow(relief), np.nan)
    return go.Heatmap(x=_r(relief.x_m / KM), y=_r(relief.y_m / KM), z=np.round(z, 3),
                      customdata=np.round(relief.height_m).astype(np.float32), zmin=0, zmax=1,
                      showscale=False, zsmooth="best", showlegend=True,
                      colorscale=[[0, "rgba(255,255,255,0)"], [1, "rgb(140,105,70)"]],
                      name=f"terrain ({relief.source})",
                      hovertemplate="ground %{customdata:.0f} m<extra></extra>"), note


_HEAD = """<!DOCTYPE html>
<html><head><meta charset="utf-8"><title>gmtiflow scene viewer</title>
<script>window.gmtiflowErrors = [];
window.addEventListener("error", function (e) { window.gmtiflowErrors.push(String(e.message)); });
</script>
<style>body{font-family:sans-serif;margin:8px} #readout{font:13px monospace;color:#333;
position:fixed;right:12px;bottom:8px;background:#fff;padding:2px 6px;border:1px solid #ccc}</style>
</head><body>
"""


def _page(fig, origin, n_frames: int) -> str:
    """The HTML: plotly.js inlined, the figure, the lat/lon readout and ``#frame=N``."""
    m_per_deg_lat = EARTH_RADIUS_M * math.pi / 180.0
    m_per_deg_lon = m_per_deg_lat * max(math.cos(math.radians(origin.lat_deg)), 1e-6)
    geo = json.dumps({"lat0": origin.lat_deg, "lon0": origin.lon_deg,
                      "km_per_deg_lat": m_per_deg_lat / KM, "km_per_deg_lon": m_per_deg_lon / KM})
    post = """
var gd = document.getElementById('{plot_id}');
var geo = %s;
var readout = document.getElementById('readout');
gd.addEventListener('mousemove', function (evt) {
  var L = gd._fullLayout; if (!L || !L.xaxis) return;
  var r = gd.getBoundingClientRect();
  var x = L.xaxis.p2d(evt.clientX - r.left - L.xaxis._offset);
  var y = L.yaxis.p2d(evt.clientY - r.top - L.yaxis._offset);
  if (!isFinite(x) || !isFinite(y)) return;
  var lat = geo.lat0 + y / geo.km_per_deg_lat, lon = geo.lon0 + x / geo.km_per_deg_lon;
  readout.textContent = 'east ' + x.toFixed(3) + ' km, north ' + y.toFixed(3) + ' km | ' +
    Math.abs(lat).toFixed(5) + (lat >= 0 ? '\\u00b0N ' : '\\u00b0S ') +
    Math.abs(lon).toFixed(5) + (lon >= 0 ? '\\u00b0E' : '\\u00b0W');
});
var m = /frame=(\\d+)/.exec(window.location.hash);
var shown = (m && +m[1] < %d) ? m[1] : '0';
function done() { document.body.setAttribute('data-frame-shown', shown);
  document.body.setAttribute('data-errors', JSON.stringify(window.gmtiflowErrors)); }
if (m && +m[1] < %d) {
  Plotly.animate(gd, [m[1]], {mode: 'immediate', frame: {duration: 0, redraw: true},
                              transition: {duration: 0}}).then(done, function (e) {
    window.gmtiflowErrors.push(String(e)); done(); });
} else { done(); }
""" % (geo, n_frames, n_frames)
    body = fig.to_html(full_html=False, include_plotlyjs=True, post_script=post,
                       config={"scrollZoom": True, "displaylogo": False, "responsive": True})
    return (_HEAD + body + '\n<div id="readout">move the pointer over the map for lat/lon</div>\n'
            "</body></html>\n")


def main(argv: Optional[List[str]] = None) -> int:
    """``gmtiflow-view RUN_DIR|run.h5 [-o viewer.html]``."""
    import argparse
    import sys

    from gmtiflow.errors import GmtiflowError
    ap = argparse.ArgumentParser(prog="gmtiflow-view", description="Write the interactive scene "
                                 "viewer (one offline HTML file) of a finished run.")
    ap.add_argument("run", help="a run directory (holding run.h5) or a run.h5 file")
    ap.add_argument("-o", "--output", help="output HTML (default: RUN_DIR/viewer.html)")
    ap.add_argument("--max-frames", type=int, default=150, help="most frames (revisits), evenly spread")
    ap.add_argument("--max-labels", type=int, default=60,
                    help="id labels, trails and ellipses only while a frame has at most this many")
    args = ap.parse_args(argv)
    src = Path(args.run)
    run_h5 = src / "run.h5" if src.is_dir() else src
    out = Path(args.output) if args.output else run_h5.parent / "viewer.html"
    if args.max_frames < 1 or args.max_labels < 0:
        ap.error("--max-frames must be >= 1 and --max-labels >= 0")
    from gmtiflow.paths import refuse_same_file
    try:
        refuse_same_file(out, [run_h5])           # never write the page over its run file
        if out.is_dir():
            raise GmtiflowError(f"{out}: is a directory; give the output HTML file")
        print(build_viewer(run_h5, out, max_frames=args.max_frames, max_labels=args.max_labels))
    except GmtiflowError as exc:
        print(f"gmtiflow-view: error: {exc}", file=sys.stderr)
        return 1
    except OSError as exc:                        # the output cannot be written
        print(f"gmtiflow-view: error: {out}: cannot write the viewer "
              f"({exc.strerror or exc})", file=sys.stderr)
        return 1
    return 0


def entry() -> None:
    """Console script ``gmtiflow-view``."""
    import sys
    sys.exit(main())
