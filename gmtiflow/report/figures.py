"""The run report's figures: one function per page, each taking tables and returning a Figure.

Figures are built with :class:`matplotlib.figure.Figure` and an Agg canvas, never through
``pyplot``, so building a report touches no global state and works in any thread or worker.
Every figure copes with empty tables (no detections, no tracks, tracker off) by saying so on the
page.  Dense layers are subsampled evenly to ``max_points`` (the title says "every k-th") and
rasterised in the PDF above a few thousand points, so big runs stay fast and small.

Units on the pages: km for map coordinates, degrees for angles, m/s for speeds, dB for SNR.
"""
from __future__ import annotations

import math
from typing import Dict, List, Optional, Sequence, Tuple

import matplotlib.cm as cm
import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Circle, Patch, Polygon, Wedge

from gmtiflow.frames import Origin, geodetic_to_enu, wrap_pi
from gmtiflow.sensor.outcome import Outcome
from gmtiflow.tables import Table

from .data import DETECTED, DRAWN, n

A4_LANDSCAPE = (11.69, 8.27)
SNR_FLOOR_DB = -10.0  # the P_D-vs-SNR plot starts here (lower bins hold notch-suppressed looks)
RASTER_ABOVE = 3000  # points per layer above which a layer is rasterised in the PDF

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


# ----------------------------------------------------------------------------- page 1

def title_figure(attrs: dict, config: dict, numbers: Dict[str, float],
                 metrics: Dict[str, Tuple[float, str]], run_name: str) -> Figure:
    """Scene summary and key numbers as text."""
    fig = new_figure()

    def c(dotted, default="—"):
        node = config
        for part in dotted.split("."):
            if not isinstance(node, dict) or part not in node:
                return default
            node = node[part]
        return default if node is None else node

    vehicles = c("vehicles.vehicles", []) or []
    n_convoy = sum(int((v.get("convoy") or {}).get("count", 1) or 1) for v in vehicles)
    n_random = int(c("vehicles.random.count", 0) or 0)
    regions = [r.get("name") or r.get("shape") for r in (c("clutter.regions", []) or [])]
    sensor_bits = (f"{float(c('sensor.freq_hz', float('nan'))) / 1e9:.2f} GHz, "
                   f"az {c('sensor.az_min_deg')}…{c('sensor.az_max_deg')}°, "
                   f"range {float(c('sensor.range_min_m', float('nan'))) / 1e3:.0f}–"
                   f"{float(c('sensor.range_max_m', float('nan'))) / 1e3:.0f} km, "
                   f"revisit {c('sensor.revisit_s')} s, P_FA {c('sensor.pfa')}, "
                   f"STAP {'on, MDV ' + str(c('sensor.mdv_mps')) + ' m/s' if c('sensor.stap', False) else 'off'}")
    wps = c("platform.waypoints_m", []) or []
    alt = f"{wps[0][2] / 1e3:.1f} km" if wps and len(wps[0]) > 2 else "—"
    roadmap = c("roadmap.kind")
    if c("roadmap.path", None):
        roadmap = f"{roadmap}: {c('roadmap.path')}"
    scene = [
        ("Road map", f"{roadmap}"),
        ("Vehicles", f"{numbers.get('vehicles', 0):.0f} ({len(vehicles)} configured entries "
                     f"→ {n_convoy} incl. convoys, {n_random} random)"),
        ("Platform", f"{len(wps)} waypoints, {c('platform.speed_mps')} m/s, altitude {alt}"),
        ("Sensor", sensor_bits),
        ("Clutter", f"{c('clutter.fov_density_per_km2', 0)} /km²/dwell over the FoV; regions: "
                    f"{', '.join(map(str, regions)) or 'none'}"),
        ("Terrain", f"{c('terrain.kind')}"),
        ("Fidelity", f"{c('fidelity.name')} ({c('fidelity.dwell_mode')}, "
                     f"truth every {c('fidelity.truth_output_dt_s')} s)"),
        ("Tracker", "baseline NN-Kalman" if c("tracker.enabled", False) else "off"),
        ("Duration / epoch", f"{c('scene.duration_s')} s from {attrs.get('scene_epoch_utc', '—')}"),
        ("Seed / version", f"{attrs.get('seed', '—')} / gmtiflow {attrs.get('gmtiflow_version', '—')}"),
        ("Origin", f"{attrs.get('origin_lat_deg', float('nan')):.5f}° N, "
                   f"{attrs.get('origin_lon_deg', float('nan')):.5f}° E, "
                   f"{attrs.get('origin_height_m', float('nan')):.0f} m"),
    ]

    def fmt(v, unit="", digits=3):
        if v is None or (isinstance(v, float) and not math.isfinite(v)):
            return "n/a"
        if float(v).is_integer() and abs(v) < 1e9 and unit == "":
            return f"{v:.0f}"
        return f"{v:.{digits}g} {unit}".strip()

    results = [
        ("Dwells / looks", f"{fmt(numbers.get('dwells'))} / {fmt(numbers.get('looks'))}"),
        ("Detections", f"{fmt(numbers.get('detections'))} "
                       f"({fmt(numbers.get('false_alarms'))} false alarms, "
                       f"{fmt(numbers.get('merged'))} merged)"),
        ("P_D achieved", f"{fmt(numbers.get('pd_achieved'))} over {fmt(numbers.get('looks_drawn'))} "
                         f"looks on visible targets (model mean {fmt(numbers.get('pd_model_mean'))})"),
        ("Tracks", f"{fmt(numbers.get('tracks'))} ({fmt(numbers.get('confirmed_tracks'))} confirmed)"),
    ]
    for name, label in (("ospa_mean_m", "OSPA mean"), ("gospa_mean_m", "GOSPA mean"),
                        ("position_rmse_m", "Position RMSE"), ("speed_rmse_mps", "Speed RMSE"),
                        ("range_rate_rmse_mps", "Range-rate RMSE"),
                        ("identity_switches", "Identity switches"),
                        ("fragmentations", "Fragmentations"), ("coverage_mean", "Coverage (mean)"),
                        ("track_purity_mean", "Track purity (mean)")):
        if name in metrics:
            v, u = metrics[name]
            results.append((label, fmt(v, u)))
    if not metrics:
        results.append(("Tracker metrics", "none in this run"))

    fig.text(0.05, 0.93, "gmtiflow run report", fontsize=22, weight="bold")
    fig.text(0.05, 0.885, run_name, fontsize=10, color="0.3", family="monospace")
    tracker_rows = results[4:]
    for title, rows, x0, y0, w in (("Scene", scene, 0.05, 0.82, 0.17),
                                   ("Sensor results", results[:4], 0.05, 0.37, 0.17),
                                   ("Tracker results", tracker_rows, 0.62, 0.37, 0.17)):
        fig.text(x0, y0, title, fontsize=14, weight="bold")
        for i, (k, v) in enumerate(rows):
            y = y0 - 0.034 * (i + 1)
            fig.text(x0 + 0.02, y, k, fontsize=10, weight="bold")
            fig.text(x0 + 0.02 + w, y, v, fontsize=10)
    if attrs.get("attribution"):
        fig.text(0.05, 0.02, f"Map data: {attrs['attribution']}", fontsize=9, color="0.3")
    return fig


# ----------------------------------------------------------------------------- page 2: map

def revisit_footprints(dwells: Table, origin: Origin, max_footprints: int) -> List[dict]:
    """Ground footprint (annular sector) of every drawn revisit: the union of its dwells' beams.

    A dwell covers beam azimuth ± ``angle_half_extent_rad`` and slant ranges within
    ``range_half_extent_m`` of the slant range to its area centre; the slant window is turned
    into ground range with the platform height above the area centre.
    """
    if not n(dwells):
        return []
    rev = _col(dwells, "revisit_id") if "revisit_id" in dwells else _col(dwells, "dwell_id")
    revisits = np.unique(rev)
    chosen = revisits[even_subsample(len(revisits), max_footprints)]
    ax_, ay_, az_ = geodetic_to_enu(origin, _col(dwells, "area_lat_deg"),
                                    _col(dwells, "area_lon_deg"), np.full(n(dwells), origin.height_m))
    out = []
    for r in chosen:
        rows = np.flatnonzero(rev == r)
        mid = rows[len(rows) // 2]
        px, py, pz = (float(dwells[k][mid]) for k in ("platform_x_m", "platform_y_m", "platform_z_m"))
        slant_c = math.sqrt((ax_[mid] - px) ** 2 + (ay_[mid] - py) ** 2 + (az_[mid] - pz) ** 2)
        half = float(dwells["range_half_extent_m"][mid])
        h = pz - az_[mid]
        g = [math.sqrt(max(s * s - h * h, 0.0)) for s in (max(slant_c - half, abs(h)), slant_c + half)]
        beam = _col(dwells, "beam_az_rad", rows)
        beam = beam[0] + wrap_pi(beam - beam[0])
        width = _col(dwells, "angle_half_extent_rad", rows)
        lo, hi = float(np.min(beam - width)), float(np.max(beam + width))
        out.append({"revisit": int(r), "time_s": float(dwells["time_s"][mid]), "x": px, "y": py,
                    "ground_min_m": g[0], "ground_max_m": g[1], "az_lo": lo, "az_hi": hi})
    return out


def _footprint_patch(fp: dict, scale: float, **kw) -> Wedge:
    # Azimuth clockwise from north -> matplotlib angle counter-clockwise from east.
    t1, t2 = 90.0 - math.degrees(fp["az_hi"]), 90.0 - math.degrees(fp["az_lo"])
    return Wedge((fp["x"] / scale, fp["y"] / scale), fp["ground_max_m"] / scale, t1, t2,
                 width=(fp["ground_max_m"] - fp["ground_min_m"]) / scale, **kw)


def _clutter_patches(regions: Sequence[dict], scale: float) -> List:
    patches = []
    for reg in regions or []:
        shape = reg.get("shape")
        style = dict(facecolor="#6baed6", alpha=0.25, edgecolor="#08519c", hatch="//", lw=1.0)
        try:
            if shape == "polygon":
                v = np.asarray(reg["vertices_m"], float) / scale
                p = Polygon(v, closed=True, **style)
            elif shape == "circle":
                p = Circle(np.asarray(reg["centre_m"], float) / scale, reg["radius_m"] / scale, **style)
            elif shape == "ring":
                p = Wedge(np.asarray(reg["centre_m"], float) / scale, reg["outer_radius_m"] / scale,
                          0, 360, width=(reg["outer_radius_m"] - reg["inner_radius_m"]) / scale, **style)
            else:
                continue
        except (KeyError, TypeError, ValueError):
            continue
        p.set_label(f"clutter: {reg.get('name') or shape}")
        patches.append(p)
    return patches


def _draw_roads(ax, nodes: Table, edges: Table, scale: float) -> None:
    if not (n(nodes) and n(edges)):
        return
    x = np.full(int(np.max(nodes["node_id"])) + 1, np.nan)
    y = x.copy()
    x[nodes["node_id"]], y[nodes["node_id"]] = nodes["x_m"], nodes["y_m"]
    a, b = _col(edges, "from_node"), _col(edges, "to_node")
    inv = _col(edges, "invisible").astype(bool) if "invisible" in edges else np.zeros(len(a), bool)
    for mask, style in ((~inv, dict(color="0.55", lw=1.2, zorder=1)),
                        (inv, dict(color="#8c510a", lw=2.0, ls=(0, (2, 1.5)), zorder=2))):
        if mask.any():
            xs = np.stack([x[a[mask]], x[b[mask]], np.full(mask.sum(), np.nan)], 1).ravel() / scale
            ys = np.stack([y[a[mask]], y[b[mask]], np.full(mask.sum(), np.nan)], 1).ravel() / scale
            ax.plot(xs, ys, **style)


def _track_lines(tracks: Table, max_lines: int, confirmed_only=True):
    """(x, y) arrays of the longest tracks, at most ``max_lines``."""
    if not n(tracks):
        return []
    keep = np.ones(n(tracks), bool)
    if confirmed_only and "confirmed" in tracks:
        keep = np.asarray(tracks["confirmed"], bool)
    tid = _col(tracks, "track_id")[keep]
    x, y = _col(tracks, "x_m")[keep], _col(tracks, "y_m")[keep]
    ids, counts = np.unique(tid, return_counts=True)
    ids = ids[np.argsort(-counts, kind="stable")[:max_lines]]
    return [(x[tid == i], y[tid == i]) for i in ids]


def map_figure(nodes: Table, edges: Table, truth: Table, platform: Table, dwells: Table,
               detections: Table, tracks: Table, clutter_regions: Sequence[dict], origin: Origin,
               attribution: str = "", *, max_points: int = 20000, max_footprints: int = 12,
               max_track_lines: int = 200) -> Figure:
    """Overview (orbit, footprints) and scene map (roads, truth, clutter, detections, tracks).

    The detection layers are the scatter collections labelled ``true detection``, ``merged
    report`` and ``false alarm`` on the scene axes (``fig.axes[1]``).
    """
    fig = new_figure()
    gs = fig.add_gridspec(1, 2, width_ratios=[1, 2.1], left=0.05, right=0.99, top=0.9,
                          bottom=0.07, wspace=0.1)
    over, ax = fig.add_subplot(gs[0]), fig.add_subplot(gs[1])
    km = 1e3
    fps = revisit_footprints(dwells, origin, max_footprints)
    colours = cm.viridis(np.linspace(0, 1, max(len(fps), 1)))

    # Overview: platform orbit, footprints, scene box.
    if n(platform):
        over.plot(_col(platform, "x_m") / km, _col(platform, "y_m") / km, color="k", lw=1.2,
                  label="platform track")
        over.plot(platform["x_m"][0] / km, platform["y_m"][0] / km, "ko", ms=5, label="platform at t = 0")
    for fp, col in zip(fps, colours):
        over.add_patch(_footprint_patch(fp, km, facecolor=col, alpha=0.25, edgecolor=col, lw=0.8))
        over.plot([fp["x"] / km], [fp["y"] / km], "o", color=col, ms=3)
    _draw_roads(over, nodes, edges, km)
    over.set_aspect("equal", adjustable="datalim")
    over.set_xlabel("east (km)")
    over.set_ylabel("north (km)")
    over.set_title(f"Orbit and beam footprints\n({len(fps)} revisits, colour = time)", fontsize=10)
    over.grid(alpha=0.3)
    if n(platform):
        over.legend(loc="upper left", fontsize=7)

    # Scene map.
    _draw_roads(ax, nodes, edges, km)
    for p in _clutter_patches(clutter_regions, km):
        ax.add_patch(p)
    for fp, col in zip(fps, colours):
        ax.add_patch(_footprint_patch(fp, km, facecolor="none", edgecolor=col, lw=0.6, alpha=0.6))
    if n(truth):
        vid = _col(truth, "vehicle_id")
        order = np.lexsort((_col(truth, "time_s"), vid))
        vs, x, y = vid[order], _col(truth, "x_m")[order] / km, _col(truth, "y_m")[order] / km
        brk = np.flatnonzero(np.diff(vs)) + 1
        xs = np.insert(x, brk, np.nan)
        ys = np.insert(y, brk, np.nan)
        ax.plot(xs, ys, color="#35978f", lw=2.2, alpha=0.6, zorder=3)
    classes = detection_classes(detections)
    dropped = []
    for key, mask in classes.items():
        colour, marker, label = DET_STYLE[key]
        if not mask.any():
            continue
        kw = dict(s=12 if marker != "x" else 18, marker=marker, color=colour, lw=0.8 if marker == "x" else 0,
                  alpha=0.8, zorder=5, label=label)
        _, kept = _scatter(ax, _col(detections, "x_m")[mask] / km, _col(detections, "y_m")[mask] / km,
                           max_points=max_points, **kw)
        if kept < mask.sum():
            dropped.append(f"{label}s{_sub_note(int(mask.sum()), kept)}")
    lines = _track_lines(tracks, max_track_lines)
    for tx, ty in lines:
        ax.plot(tx / km, ty / km, color="k", lw=0.9, zorder=6)
    # Zoom on the scene: roads, truth and true detections (false alarms may lie far out).
    xs_, ys_ = [], []
    for t, cx, cy in ((nodes, "x_m", "y_m"), (truth, "x_m", "y_m")):
        if n(t):
            xs_.append(_col(t, cx))
            ys_.append(_col(t, cy))
    for p in ax.patches:  # clutter regions (the footprints are far larger: left out)
        if str(p.get_label()).startswith("clutter"):
            v = p.get_path().transformed(p.get_patch_transform()).vertices * km
            xs_.append(v[:, 0])
            ys_.append(v[:, 1])
    if xs_:
        allx, ally = np.concatenate(xs_) / km, np.concatenate(ys_) / km
        pad = 0.08 * max(np.ptp(allx), np.ptp(ally), 0.5)
        ax.set_xlim(allx.min() - pad, allx.max() + pad)
        ax.set_ylim(ally.min() - pad, ally.max() + pad)
        over.add_patch(Polygon([[allx.min() - pad, ally.min() - pad], [allx.max() + pad, ally.min() - pad],
                                [allx.max() + pad, ally.max() + pad], [allx.min() - pad, ally.max() + pad]],
                               closed=True, fill=False, edgecolor="r", lw=1.0, label="scene map"))
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("east (km)")
    ax.set_ylabel("north (km)")
    ax.grid(alpha=0.3)
    title = (f"Scene: roads, truth, detections ({n(detections)}), confirmed tracks "
             f"({len(lines)})")
    if dropped:
        title += "\n" + "; ".join(dropped)
    ax.set_title(title, fontsize=10)
    handles = [Line2D([], [], color="0.55", lw=1.2, label="road"),
               Line2D([], [], color="#8c510a", lw=2.0, ls=(0, (2, 1.5)), label="tunnel (invisible)"),
               Line2D([], [], color="#35978f", lw=2.2, alpha=0.6, label="truth trajectory"),
               Line2D([], [], color="k", lw=0.9, label="track (confirmed)"),
               Patch(facecolor="none", edgecolor=colours[-1] if fps else "0.5", label="beam footprint")]
    handles += [Line2D([], [], ls="", marker=m, color=c, label=lab)
                for key, (c, m, lab) in DET_STYLE.items() if classes[key].any()]
    handles += [p for p in ax.patches if str(p.get_label()).startswith("clutter")]
    ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.09), ncol=5,
              fontsize=7, frameon=False)
    if attribution:
        ax.text(0.995, 0.005, attribution if "©" in attribution else f"© {attribution}",
                transform=ax.transAxes, ha="right", va="bottom", fontsize=7,
                bbox=dict(facecolor="white", alpha=0.8, lw=0))
    fig.suptitle("Map", fontsize=14, weight="bold", x=0.05, ha="left")
    return fig


# ----------------------------------------------------------------------------- page 3: sensor

def swerling1_pd(pfa: float, snr_linear) -> np.ndarray:
    """P_D = P_FA^{1/(1+SNR)} (DESIGN eq. 11), in log space."""
    return np.exp(math.log(pfa) / (1.0 + np.asarray(snr_linear, float)))


def pd_vs_snr(looks: Table, bin_db: float):
    """Binned empirical P_D of the looks where the draw happened: (centres, pd, count, model)."""
    if not n(looks):
        return (np.zeros(0),) * 4
    outcome = _col(looks, "outcome")
    snr = _col(looks, "snr_db").astype(float)
    keep = np.isin(outcome, DRAWN) & np.isfinite(snr)
    if not keep.any():
        return (np.zeros(0),) * 4
    snr, det, pd = snr[keep], np.isin(outcome[keep], DETECTED), _col(looks, "pd")[keep]
    edges = np.arange(math.floor(snr.min() / bin_db) * bin_db, snr.max() + bin_db, bin_db)
    if len(edges) < 2:
        edges = np.array([snr.min() - bin_db / 2, snr.min() + bin_db / 2])
    which = np.clip(np.digitize(snr, edges) - 1, 0, len(edges) - 2)
    count = np.bincount(which, minlength=len(edges) - 1)
    hits = np.bincount(which, weights=det, minlength=len(edges) - 1)
    model = np.bincount(which, weights=pd, minlength=len(edges) - 1)
    ok = count > 0
    centres = 0.5 * (edges[:-1] + edges[1:])
    return centres[ok], hits[ok] / count[ok], count[ok], model[ok] / count[ok]


def normalised_errors(det: Table) -> Dict[str, np.ndarray]:
    """(measured − true)/σ of unmerged true detections without range folding/Doppler wrapping."""
    if not n(det):
        return {"range": np.zeros(0), "azimuth": np.zeros(0), "range rate": np.zeros(0)}
    ok = (np.asarray(det["truth_id"]) >= 0) & ~np.asarray(det["merged"], bool)
    for flag in ("range_folded", "doppler_wrapped"):
        if flag in det:
            ok &= ~np.asarray(det[flag], bool)
    with np.errstate(invalid="ignore", divide="ignore"):
        out = {
            "range": (_col(det, "range_m") - _col(det, "true_range_m")) / _col(det, "sigma_range_m"),
            "azimuth": wrap_pi(_col(det, "azimuth_rad") - _col(det, "true_azimuth_rad"))
            / _col(det, "sigma_azimuth_rad"),
            "range rate": (_col(det, "range_rate_mps") - _col(det, "true_range_rate_mps"))
            / _col(det, "sigma_range_rate_mps"),
        }
    return {k: v[ok & np.isfinite(v)] for k, v in out.items()}


def sensor_figure(looks: Table, detections: Table, pfa: float, *, snr_bin_db: float = 1.0,
                  expected_false_alarms: Optional[float] = None) -> Figure:
    """Empirical P_D vs model SNR against Swerling I; normalised measurement errors vs N(0, 1);
    with ``expected_false_alarms`` (the detector's P_FA × cells × dwells) the run's false-alarm
    count against it."""
    fig = new_figure()
    if expected_false_alarms is not None:
        n_fa = int(np.sum(_col(detections, "truth_id") < 0)) if n(detections) else 0
        e = float(expected_false_alarms)
        fig.text(0.05, 0.93, f"False alarms: {n_fa} in the run; the detector's expectation "
                 f"P_FA × range × Doppler cells × dwells = {e:.4g} ± {math.sqrt(max(e, 0.0)):.2g} "
                 "(Poisson; fewer where the horizon or terrain masks cells, more with clutter "
                 "regions)", fontsize=9, color="0.2")
    gs = fig.add_gridspec(2, 3, height_ratios=[1.25, 1], left=0.07, right=0.93, top=0.88,
                          bottom=0.08, hspace=0.42, wspace=0.28)
    ax = fig.add_subplot(gs[0, :])
    centres, pd_emp, count, model = pd_vs_snr(looks, snr_bin_db)
    low = centres < SNR_FLOOR_DB
    n_low = int(count[low].sum())
    low_hits = float(np.sum(pd_emp[low] * count[low]))
    centres, pd_emp, count, model = centres[~low], pd_emp[~low], count[~low], model[~low]
    if n_low:
        ax.text(0.01, 0.97, f"{n_low} looks below {SNR_FLOOR_DB:g} dB not shown (deep in the "
                f"clutter notch or beam edge; {low_hits:.0f} detected)", transform=ax.transAxes,
                va="top", fontsize=8, color="0.3")
    if len(centres):
        grid = np.linspace(min(centres.min(), 0) - 2, max(centres.max(), 20) + 2, 400)
        ax.plot(grid, swerling1_pd(pfa, 10 ** (grid / 10)), "k-", lw=1.5,
                label=f"Swerling I: $P_D = P_{{FA}}^{{1/(1+SNR)}}$, $P_{{FA}}$ = {pfa:g}")
        ax.plot(centres, model, "s", mfc="none", color="0.4", ms=5, label="mean model $P_D$ of the bin")
        err = np.sqrt(np.clip(pd_emp * (1 - pd_emp), 0.25 / count, None) / count)
        ax.errorbar(centres, pd_emp, yerr=err, fmt="o", color="#d73027", ms=5, capsize=2,
                    label=f"empirical: detected / looks ({int(count.sum())} looks, ±1σ binomial)")
        ax2 = ax.twinx()
        ax2.bar(centres, count, width=0.9 * snr_bin_db, color="0.85", zorder=0)
        ax2.set_ylabel("looks per bin", color="0.5")
        ax2.tick_params(axis="y", colors="0.5")
        ax.set_zorder(ax2.get_zorder() + 1)
        ax.patch.set_visible(False)
        ax.legend(loc="center left", fontsize=8)
        ax.set_ylim(-0.03, 1.03)
    else:
        _note(ax, "no looks above the SNR floor: nothing to compare" if n_low
              else "no looks on visible targets: nothing to compare")
    ax.set_xlabel(f"model SNR of the look (dB, bins of {snr_bin_db:g} dB; incl. beam and STAP losses)")
    ax.set_ylabel("$P_D$")
    ax.set_title("Detection probability vs SNR (looks with a detection draw: detected, "
                 "merged, notch, $P_D$ miss)", fontsize=10)
    ax.grid(alpha=0.3)

    errs = normalised_errors(detections)
    x = np.linspace(-4.5, 4.5, 200)
    for i, (name, v) in enumerate(errs.items()):
        a = fig.add_subplot(gs[1, i])
        if len(v):
            a.hist(np.clip(v, -5, 5), bins=np.linspace(-5, 5, 41), density=True, color="#4393c3",
                   alpha=0.8, label=f"n={len(v)}\nmean {v.mean():+.2f}\nstd {v.std():.2f}")
            a.plot(x, np.exp(-x * x / 2) / math.sqrt(2 * math.pi), "k-", lw=1.3, label="N(0, 1)")
            a.legend(fontsize=7, loc="upper right")
        else:
            _note(a, "no unmerged true detections")
        a.set_xlabel(f"({name} measured − true) / σ")
        a.set_ylabel("density")
        a.set_title(f"{name.capitalize()} error / σ", fontsize=10)
        a.grid(alpha=0.3)
    fig.suptitle("Physics sanity: detection and measurement errors", fontsize=14, weight="bold",
                 x=0.05, ha="left")
    return fig


def _dwell_lookup(dwells: Table, dwell_id: np.ndarray, col: str) -> np.ndarray:
    pos = np.searchsorted(_col(dwells, "dwell_id"), dwell_id)
    pos = np.clip(pos, 0, n(dwells) - 1)
    return _col(dwells, col)[pos]


def clutter_range_rate(dwells: Table, dwell_id, azimuth_rad, range_m) -> np.ndarray:
    """ṙ_MLC = −v_p·ℓ of the ground at (azimuth, slant range) seen from the dwell's platform
    (flat ground at the origin's height: depression sin δ = platform height / slant range)."""
    vx, vy, vz = (_dwell_lookup(dwells, dwell_id, f"platform_v{c}_mps") for c in "xyz")
    h = _dwell_lookup(dwells, dwell_id, "platform_z_m")
    sin_d = np.clip(h / np.maximum(range_m, 1.0), -1, 1)
    cos_d = np.sqrt(1 - sin_d ** 2)
    lx, ly, lz = np.sin(azimuth_rad) * cos_d, np.cos(azimuth_rad) * cos_d, -sin_d
    return -(vx * lx + vy * ly + vz * lz)


def _finite_median(values, default: float) -> float:
    """Median of the finite values, or ``default`` when there are none (no NaN warning)."""
    if values is None:
        return default
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    return float(np.median(v)) if v.size else default


def range_rate_figure(looks: Table, detections: Table, dwells: Table, *,
                      max_points: int = 20000) -> Figure:
    """Range rate vs azimuth off the platform track, with the clutter notch and blind speeds.

    Left: every look on a visible target (true range rate), by outcome; the notch is
    ṙ_MLC ± MDV with ṙ_MLC = −|v_p| cos(Δaz) cos δ for the median speed and depression, and the
    blind speeds are the notch shifted by ± λ·PRF/2.  Right: the reports (measured range rate,
    wrapped into ± λ·PRF/4 where the radar is Doppler-ambiguous).
    """
    fig = new_figure()
    axl, axr = fig.subplots(1, 2, sharex=True, gridspec_kw=dict(left=0.07, right=0.98, top=0.86,
                                                                 bottom=0.1, wspace=0.15))
    if not n(dwells):
        _note(axl, "no dwells")
        return fig
    speed = np.hypot(_col(dwells, "platform_vx_mps"), _col(dwells, "platform_vy_mps"))
    v_p = float(np.median(speed))
    mdv = _finite_median(dwells.get("mdv_mps"), 0.0)
    wrap = _finite_median(dwells.get("wrap_velocity_mps"), float("nan"))   # NaN: no PRF
    # depression of a typical look: platform height over the looks' median slant range
    slant = _finite_median(looks.get("range_m") if n(looks) else None, float("nan"))
    height = _finite_median(dwells.get("platform_z_m"), 0.0)
    cos_d = math.sqrt(max(0.0, 1.0 - (height / slant) ** 2)) if slant > 0 else 1.0

    def rel_az(table, az_col="azimuth_rad"):
        hd = _dwell_lookup(dwells, _col(table, "dwell_id"), "platform_heading_rad")
        return np.degrees(wrap_pi(_col(table, az_col) - hd))

    xs, ys = [], []
    drawn = np.zeros(0, bool)
    if n(looks):
        outcome = _col(looks, "outcome")
        drawn = np.isin(outcome, DRAWN)
        rel = rel_az(looks)
        if n(looks) and "range_m" in looks:
            r = _col(looks, "range_m")
            cos_d = float(np.nanmedian(np.sqrt(np.clip(1 - (_dwell_lookup(
                dwells, _col(looks, "dwell_id"), "platform_z_m") / np.maximum(r, 1)) ** 2, 0, 1)))) \
                if drawn.any() else cos_d
        for code in (Outcome.DETECTED, Outcome.MERGED, Outcome.PD_MISS, Outcome.DOPPLER_BLIND):
            m = outcome == code
            if m.any():
                colour, label, _ = OUTCOME_STYLE[code]
                blind_code = code == Outcome.DOPPLER_BLIND
                _scatter(axl, rel[m], _col(looks, "range_rate_mps")[m], max_points=max_points,
                         s=22 if blind_code else 9, marker="^" if blind_code else "o",
                         color=colour, label=f"{label} ({int(m.sum())})", alpha=0.9, lw=0,
                         zorder=4 if blind_code else 3)
                xs.append(rel[m])
                ys.append(_col(looks, "range_rate_mps")[m])
    if n(detections):
        rel_d = rel_az(detections)
        xs.append(rel_d)
        for key, mask in detection_classes(detections).items():
            if mask.any():
                colour, marker, label = DET_STYLE[key]
                _scatter(axr, rel_d[mask], _col(detections, "range_rate_mps")[mask],
                         max_points=max_points, s=14 if marker == "x" else 10, marker=marker,
                         color=colour, lw=0.8 if marker == "x" else 0, alpha=0.8,
                         label=f"{label} ({int(mask.sum())})")
    allx = np.concatenate(xs) if xs else np.array([60.0, 120.0])
    allx = allx[np.isfinite(allx)]
    lo, hi = (allx.min(), allx.max()) if len(allx) else (60.0, 120.0)
    pad = max(2.0, 0.05 * (hi - lo))
    grid = np.linspace(lo - pad, hi + pad, 300)
    notch = -v_p * np.cos(np.radians(grid)) * cos_d
    blind = 2 * wrap if math.isfinite(wrap) else float("nan")
    for a, wrapped in ((axl, False), (axr, True)):
        shifts = [0.0] if (wrapped or not math.isfinite(blind)) else [0.0, -blind, blind]
        for k, s in enumerate(shifts):
            c = notch + s
            if wrapped and math.isfinite(wrap):
                c = np.mod(c + wrap, 2 * wrap) - wrap
                c = np.where(np.abs(np.diff(c, prepend=c[0])) > wrap, np.nan, c)
            label = ("clutter notch $\\dot r_{MLC}$ ± MDV" if k == 0
                     else "blind speeds $\\dot r_{MLC}$ ± λ·PRF/2" if k == 1 else None)
            a.plot(grid, c, color="k" if k == 0 else "0.3", lw=1.0, ls="-" if k == 0 else "--",
                   label=label)
            if mdv > 0:
                a.fill_between(grid, c - mdv, c + mdv, color="0.6" if k == 0 else "0.8", alpha=0.35,
                               lw=0)
        if wrapped and math.isfinite(wrap):
            for w in (-wrap, wrap):
                a.axhline(w, color="#b2182b", lw=0.8, ls=":")
            a.plot([], [], color="#b2182b", lw=0.8, ls=":", label=f"wrap limits ±λ·PRF/4 = ±{wrap:.1f} m/s")
        a.set_xlabel("azimuth relative to platform heading (deg, + = right)")
        a.grid(alpha=0.3)
        a.legend(fontsize=7, loc="upper right")
    if not drawn.any():
        _note(axl, "no looks on visible targets")
    if not n(detections):
        _note(axr, "no detections")
    yv = np.concatenate(ys + [notch]) if ys else notch
    yv = yv[np.isfinite(yv)]
    axl.set_ylim(yv.min() - max(10.0, 3 * mdv), yv.max() + max(10.0, 3 * mdv))
    axl.set_ylabel("range rate (m/s, + = receding)")
    axl.set_title("Looks: true range rate by outcome", fontsize=10)
    axr.set_title("Reports: measured range rate", fontsize=10)
    fig.suptitle(f"Range rate vs azimuth — platform {v_p:.0f} m/s, MDV {mdv:g} m/s"
                 + (f", blind speed {blind:.1f} m/s" if math.isfinite(blind) else ", no PRF set"),
                 fontsize=14, weight="bold", x=0.05, ha="left")
    return fig


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
        t, vid = _col(truth, "time_s"), _col(truth, "vehicle_id")
        dt = float(np.median(np.diff(np.unique(t)))) if len(np.unique(t)) > 1 else 1.0
        for v in shown:
            m = vid == v
            tt = t[m]
            ax.plot([tt.min(), tt.max()] if m.any() else [], [row[int(v)]] * (2 if m.any() else 0),
                    color="0.85", lw=6, solid_capstyle="butt", zorder=0)
            if "mode" in truth:
                ax.broken_barh(_runs(tt, _col(truth, "mode")[m] == 2, dt), (row[int(v)] - 0.38, 0.76),
                               facecolor="#fee08b", edgecolor="#d8b365", zorder=1)
            if "invisible" in truth:
                ax.broken_barh(_runs(tt, _col(truth, "invisible")[m].astype(bool), dt),
                               (row[int(v)] - 0.38, 0.76), facecolor="none", edgecolor="#543005",
                               hatch="xxx", lw=0.5, zorder=1)
    counts = np.zeros((len(shown), len(OUTCOME_STYLE)))
    codes = list(OUTCOME_STYLE)
    if n(looks):
        lv, lo, lt = _col(looks, "vehicle_id"), _col(looks, "outcome"), _col(looks, "time_s")
        sel = np.isin(lv, shown)
        rows = np.array([row.get(int(v), -1) for v in lv[sel]])
        for j, code in enumerate(codes):
            m = lo[sel] == code
            colour, label, size = OUTCOME_STYLE[code]
            if m.any():
                ax.scatter(lt[sel][m], rows[m], s=size, color=colour, marker="|" if code == Outcome.OUTSIDE_FOV else "o",
                           lw=1 if code == Outcome.OUTSIDE_FOV else 0, zorder=3,
                           rasterized=m.sum() > RASTER_ABOVE)
                np.add.at(counts[:, j], rows[m], 1)
    left = np.zeros(len(shown))
    for j, code in enumerate(codes):
        colour, label, _ = OUTCOME_STYLE[code]
        bx.barh(np.arange(len(shown)), counts[:, j], left=left, color=colour, height=0.7)
        left += counts[:, j]
    labels = [f"{names.get(v, v)} (#{v})" for v in shown]
    ax.set_yticks(np.arange(len(shown)))
    ax.set_yticklabels(labels, fontsize=max(5, min(9, int(300 / max(len(shown), 1)))))
    ax.set_ylim(len(shown) - 0.5, -0.5)
    bx.set_ylim(len(shown) - 0.5, -0.5)
    bx.set_yticks([])
    bx.set_xlabel("looks")
    bx.set_title("outcome counts", fontsize=9)
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


# ----------------------------------------------------------------------------- tracker pages

def track_errors_figure(track_errors: Table, *, max_tracks: int = 200,
                        tracker_enabled: bool = True) -> Figure:
    """Paper Fig. 5: position, speed and range-rate errors of the tracks vs truth over time."""
    fig = new_figure()
    axes = fig.subplots(3, 1, sharex=True, gridspec_kw=dict(left=0.08, right=0.97, top=0.88,
                                                             bottom=0.08, hspace=0.12))
    rows = (("position_error_m", "position error (m)"), ("speed_error_mps", "speed error (m/s)"),
            ("range_rate_error_mps", "range-rate error (m/s)"))
    if not n(track_errors):
        for a, (_, label) in zip(axes, rows):
            a.set_ylabel(label)
        _note(axes[1], "no tracks associated with truth" if tracker_enabled
              else "tracker off: no tracks in this run")
    else:
        tid = _col(track_errors, "track_id")
        t = _col(track_errors, "time_s")
        ids, counts = np.unique(tid, return_counts=True)
        ids = ids[np.argsort(-counts, kind="stable")[:max_tracks]]
        colours = cm.tab20(np.arange(len(ids)) % 20)
        for a, (col, label) in zip(axes, rows):
            if col not in track_errors:
                _note(a, f"no {label}")
                continue
            v = _col(track_errors, col)
            for i, c in zip(ids, colours):
                m = tid == i
                a.plot(t[m], v[m], "-", color=c, lw=0.9, marker=".", ms=2.5)
            finite = v[np.isfinite(v)]
            rms = float(np.sqrt(np.mean(finite ** 2))) if len(finite) else float("nan")
            a.text(0.005, 0.95, f"RMS {rms:.3g}", transform=a.transAxes, va="top", fontsize=8,
                   bbox=dict(facecolor="white", alpha=0.8, lw=0))
            if col != "position_error_m":
                a.axhline(0, color="k", lw=0.6)
            a.set_ylabel(label)
            a.grid(alpha=0.3)
        more = f", longest {len(ids)} of {len(np.unique(tid))} tracks" if len(ids) < len(np.unique(tid)) else ""
        axes[0].set_title(f"{len(np.unique(tid))} tracks associated with truth (one colour per "
                          f"track; signed errors track − truth){more}", fontsize=10)
    axes[-1].set_xlabel("time (s)")
    fig.suptitle("Track errors w.r.t. ground truth (paper Fig. 5)", fontsize=14, weight="bold",
                 x=0.05, ha="left")
    return fig


EVENT_COLOUR = {"stop": "#fee08b", "doppler_blind": "#fc8d59", "terrain": "#8c510a",
                "invisible_road": "#543005"}


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
        for k, c in EVENT_COLOUR.items():
            m = kind == k
            if m.any():
                have = True
                for j, (v, s, d) in enumerate(zip(vid[m], _col(events, "start_s")[m],
                                                  _col(events, "duration_s")[m])):
                    a2.broken_barh([(s, max(d, 0.5))], (v - 0.35, 0.7), facecolor=c, edgecolor="none",
                                   alpha=0.8, label=f"{k.replace('_', ' ')} ({int(m.sum())})"
                                   if j == 0 else None)
        if "reacquired" in events:
            re = np.asarray(events["reacquired"], bool)
            kept = np.asarray(events["id_kept"], bool) if "id_kept" in events else np.zeros(len(re), bool)
            end = _col(events, "end_s")
            held = _col(events, "track_before") >= 0 if "track_before" in events else np.ones(len(re), bool)
            dly = np.nan_to_num(_col(events, "reacq_delay_s")) if "reacq_delay_s" in events else 0
            for m, mk, c, lab in ((held & kept, "o", "#1a9850", "re-acquired, same id"),
                                  (held & re & ~kept, "s", "#fdae61", "re-acquired, new id"),
                                  (held & ~re, "X", "#d73027", "lost (held before)")):
                if m.any():
                    a2.scatter((end + dly)[m], vid[m], marker=mk, color=c, s=22, zorder=4, label=lab)
    if n(switches):
        have = True
        a2.scatter(_col(switches, "time_s"), _col(switches, "vehicle_id"), marker="|", color="k",
                   s=60, lw=1.2, zorder=5, label=f"identity switch ({n(switches)})")
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
