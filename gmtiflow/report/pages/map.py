"""Page 2: the map (orbit and footprints overview, scene map)."""
from __future__ import annotations

import math
from typing import List, Sequence

import matplotlib.cm as cm
import numpy as np
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Circle, Patch, Polygon, Wedge

from gmtiflow.frames import Origin, geodetic_to_enu, wrap_pi
from gmtiflow.tables import Table

from ..common import DET_STYLE, RASTER_ABOVE, _col, _scatter, _sub_note, detection_classes, even_subsample, new_figure
from ..data import n
from ..relief import hillshade_rgba, relief_grid


# ----------------------------------------------------------------------------- page 2: map

TRUTH_COLOUR = "#35978f"
TRACK_COLOUR = "#762a83"
MANY_LINES = 30   # above this many truth trajectories or tracks, lines are drawn thin and faint
EARTH_RADIUS_M = 6371008.8


def truth_polyline(truth: Table, max_points: int):
    """One NaN-separated polyline of every vehicle's trajectory in time order, keeping every
    ``step``-th sample per vehicle (plus its last) so that at most about ``max_points`` remain.

    Returns (x_m, y_m, vehicles, step).
    """
    vid = _col(truth, "vehicle_id")
    order = np.lexsort((_col(truth, "time_s"), vid))
    vs = vid[order]
    step = max(1, int(math.ceil(len(vs) / max(max_points, 1))))
    start = np.r_[True, vs[1:] != vs[:-1]]
    last = np.r_[vs[1:] != vs[:-1], True]
    n_vehicles = int(np.count_nonzero(start)) if len(vs) else 0    # rows sorted by vehicle
    k = np.arange(len(vs)) - np.maximum.accumulate(np.where(start, np.arange(len(vs)), 0))
    keep = (k % step == 0) | last
    order, vs, start = order[keep], vs[keep], start[keep]
    x, y = _col(truth, "x_m")[order], _col(truth, "y_m")[order]
    brk = np.flatnonzero(start[1:]) + 1
    return np.insert(x, brk, np.nan), np.insert(y, brk, np.nan), n_vehicles, step


def add_latlon_axes(ax, origin: Origin, scale: float) -> None:
    """Longitude ticks on top, latitude ticks on the right of a local east/north map in units
    of ``scale`` metres (local tangent-plane approximation about the origin: metres per degree
    of latitude R·π/180, of longitude R·cos φ0·π/180; the error is below 0.1 % of the offset
    for scenes within ~50 km)."""
    m_per_deg_lat = EARTH_RADIUS_M * math.pi / 180.0
    m_per_deg_lon = m_per_deg_lat * max(math.cos(math.radians(origin.lat_deg)), 1e-6)
    lon0, lat0 = origin.lon_deg, origin.lat_deg
    top = ax.secondary_xaxis("top", functions=(lambda x: lon0 + x * scale / m_per_deg_lon,
                                               lambda lon: (lon - lon0) * m_per_deg_lon / scale))
    right = ax.secondary_yaxis("right", functions=(lambda y: lat0 + y * scale / m_per_deg_lat,
                                                   lambda lat: (lat - lat0) * m_per_deg_lat / scale))
    for sec in (top, right):
        sec.tick_params(labelsize=7, colors="0.35")
    top.xaxis.set_major_formatter(_deg_formatter("E", "W"))
    right.yaxis.set_major_formatter(_deg_formatter("N", "S"))
    top.xaxis.get_major_locator().set_params(nbins=5)


def _deg_formatter(pos: str, neg: str):
    from matplotlib.ticker import FuncFormatter
    return FuncFormatter(lambda v, _: f"{abs(v):.3f}°{pos if v >= 0 else neg}")


def revisit_footprints(dwells: Table, origin: Origin, max_footprints: int) -> List[dict]:
    """Ground footprint (annular sector) of every drawn revisit: the union of its dwells' beams.

    A dwell covers beam azimuth ± ``angle_half_extent_rad`` and slant ranges within
    ``range_half_extent_m`` of the slant range to its area centre; the slant window is turned
    into ground range with the platform height above the area centre.
    """
    if not n(dwells):
        return []
    rev = _col(dwells, "revisit_id") if "revisit_id" in dwells else _col(dwells, "dwell_id")
    if "sensor_id" in dwells:       # several sensors: a revisit is one sensor's, never a mix
        rev = _col(dwells, "sensor_id").astype(np.int64) * (int(rev.max()) + 1) + rev
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
    return sorted(out, key=lambda fp: fp["time_s"])     # colour = time, across sensors


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
    """(x, y) arrays of the longest tracks, at most ``max_lines`` (longest first, ties by id),
    each track's rows in file order.

    One stable sort groups the rows by track and each line is a slice of it (a mask over all
    rows per track was 200 passes over the 1,000-vehicle run's 190,000 track rows)."""
    if not n(tracks):
        return []
    keep = np.ones(n(tracks), bool)
    if confirmed_only and "confirmed" in tracks:
        keep = np.asarray(tracks["confirmed"], bool)
    tid = _col(tracks, "track_id")[keep]
    x, y = _col(tracks, "x_m")[keep], _col(tracks, "y_m")[keep]
    ids, counts = np.unique(tid, return_counts=True)
    rows = np.argsort(tid, kind="stable")       # grouped by id, ascending as ``ids``
    ends = np.cumsum(counts)
    return [(x[rows[ends[k] - counts[k]:ends[k]]], y[rows[ends[k] - counts[k]:ends[k]]])
            for k in np.argsort(-counts, kind="stable")[:max_lines]]


def map_figure(nodes: Table, edges: Table, truth: Table, platform: Table, dwells: Table,
               detections: Table, tracks: Table, clutter_regions: Sequence[dict], origin: Origin,
               attribution: str = "", *, max_points: int = 20000, max_footprints: int = 12,
               max_track_lines: int = 200, terrain=None, terrain_name: str = "",
               terrain_note: str = "") -> Figure:
    """Overview (orbit, footprints) and scene map (roads, truth, clutter, detections, tracks).

    ``terrain`` (a :class:`gmtiflow.scene.terrain.Terrain`, e.g. from
    :func:`gmtiflow.report.relief.run_terrain`) is drawn as hill-shaded relief under the scene
    map; ``terrain_note`` says why there is none when the run had a DEM that cannot be read.

    The detection layers are the scatter collections labelled ``true detection``, ``merged
    report`` and ``false alarm`` on the scene axes (``fig.axes[1]``).
    """
    fig = new_figure()
    gs = fig.add_gridspec(1, 2, width_ratios=[1, 2.1], left=0.06, right=0.93, top=0.86,
                          bottom=0.16, wspace=0.12)
    over, ax = fig.add_subplot(gs[0]), fig.add_subplot(gs[1])
    km = 1e3
    fps = revisit_footprints(dwells, origin, max_footprints)
    colours = cm.viridis(np.linspace(0, 1, max(len(fps), 1)))

    # Overview: platform orbit, footprints, scene box.
    if n(platform):       # one line per aircraft (several sensors: rows by sensor_id)
        sid = _col(platform, "sensor_id") if "sensor_id" in platform else np.zeros(n(platform))
        for i, s_id in enumerate(np.unique(sid)):
            rows = np.flatnonzero(sid == s_id)
            over.plot(_col(platform, "x_m", rows) / km, _col(platform, "y_m", rows) / km,
                      color="k", lw=1.2, label="platform track" if i == 0 else None)
            over.plot(_col(platform, "x_m", rows[:1]) / km, _col(platform, "y_m", rows[:1]) / km,
                      "ko", ms=5, label="platform at t = 0" if i == 0 else None)
    for fp, col in zip(fps, colours):
        over.add_patch(_footprint_patch(fp, km, facecolor=col, alpha=0.25, edgecolor=col, lw=0.8))
        over.plot([fp["x"] / km], [fp["y"] / km], "o", color=col, ms=3)
    _draw_roads(over, nodes, edges, km)
    over.set_aspect("equal", adjustable="datalim")
    over.set_xlabel("east (km)")
    over.set_ylabel("north (km)")
    over.set_title(f"Orbit and beam footprints\n({len(fps)} revisits, colour = time)", fontsize=10)
    over.grid(alpha=0.3)

    # Scene map.
    _draw_roads(ax, nodes, edges, km)
    for p in _clutter_patches(clutter_regions, km):
        ax.add_patch(p)
    for fp, col in zip(fps, colours):
        ax.add_patch(_footprint_patch(fp, km, facecolor="none", edgecolor=col, lw=0.6, alpha=0.6))
    n_vehicles = 0
    if n(truth):
        xs, ys, n_vehicles, step = truth_polyline(truth, max_points)
        many = n_vehicles > MANY_LINES
        ax.plot(xs / km, ys / km, color=TRUTH_COLOUR, lw=0.7 if many else 2.2,
                alpha=0.45 if many else 0.6, zorder=3, rasterized=len(xs) > RASTER_ABOVE)
        if step > 1:
            dropped_truth = f"truth every {step}th sample"
        else:
            dropped_truth = ""
    else:
        dropped_truth = ""
    classes = detection_classes(detections)
    dropped = []
    for key, mask in classes.items():
        colour, marker, label = DET_STYLE[key]
        if not mask.any():
            continue
        dense = mask.sum() > 500     # dense layers: small, faint markers so truth shows through
        kw = dict(s=(12 if marker != "x" else 18) * (0.3 if dense else 1.0), marker=marker,
                  color=colour, lw=(0.8 if marker == "x" else 0) * (0.6 if dense else 1.0),
                  alpha=0.45 if dense else 0.8, zorder=5, label=label)
        _, kept = _scatter(ax, _col(detections, "x_m")[mask] / km, _col(detections, "y_m")[mask] / km,
                           max_points=max_points, **kw)
        if kept < mask.sum():
            dropped.append(f"{label}s{_sub_note(int(mask.sum()), kept)}")
    lines = _track_lines(tracks, max_track_lines)
    many_tracks = len(lines) > MANY_LINES
    track_style = dict(color=TRACK_COLOUR, lw=0.5 if many_tracks else 1.0,
                       alpha=0.4 if many_tracks else 0.9)
    if lines:
        ax.add_collection(LineCollection([np.c_[tx, ty] / km for tx, ty in lines], zorder=6,
                                         rasterized=sum(len(tx) for tx, _ in lines) > RASTER_ABOVE,
                                         **track_style))
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
    relief = None
    if terrain is not None:
        relief = relief_grid(terrain, np.asarray(ax.get_xlim()) * km,
                             np.asarray(ax.get_ylim()) * km, source=terrain_name)
    if relief is not None:
        xlim, ylim = ax.get_xlim(), ax.get_ylim()
        ax.imshow(hillshade_rgba(relief), extent=np.asarray(relief.extent_m) / km,
                  origin="lower", interpolation="bilinear", zorder=0)
        ax.set_xlim(xlim)
        ax.set_ylim(ylim)
    if terrain_note:
        dropped.append(terrain_note)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("east (km)")
    ax.set_ylabel("north (km)")
    ax.grid(alpha=0.3)
    title = (f"Scene: roads, truth, detections ({n(detections)}), confirmed tracks "
             f"({len(lines)})")
    if dropped_truth:
        dropped.append(dropped_truth)
    if dropped:
        title += "\n" + "; ".join(dropped)
    ax.set_title(title, fontsize=10)
    handles = [Line2D([], [], color="0.55", lw=1.2, label="road"),
               Line2D([], [], color="#8c510a", lw=2.0, ls=(0, (2, 1.5)), label="tunnel (invisible)"),
               Line2D([], [], color=TRUTH_COLOUR, lw=2.2, alpha=0.6,
                      label=f"truth trajectory ({n_vehicles})"),
               Line2D([], [], lw=1.5, color=TRACK_COLOUR,
                      label=f"confirmed track ({len(lines)}" + (", thin: many)" if many_tracks else ")")),
               Patch(facecolor="none", edgecolor=colours[-1] if fps else "0.5", label="beam footprint")]
    handles += [Line2D([], [], ls="", marker=m, color=c, label=lab)
                for key, (c, m, lab) in DET_STYLE.items() if classes[key].any()]
    handles += [p for p in ax.patches if str(p.get_label()).startswith("clutter")]
    if relief is not None:
        z = relief.height_m[np.isfinite(relief.height_m)]
        handles.append(Patch(facecolor="#c9b99a", edgecolor="none",
                             label=f"terrain ({relief.source or 'DEM'}, {z.min():.0f}–"
                                   f"{z.max():.0f} m)"))

    if n(platform):
        handles += [Line2D([], [], color="k", lw=1.2, label="platform track (left)"),
                    Line2D([], [], ls="", marker="o", color="k", ms=5, label="platform at t = 0"),
                    Patch(fill=False, edgecolor="r", label="scene map extent (left)")]
    # Below both axes, inside the figure: never over the data, never off the page.
    fig.legend(handles=handles, loc="lower center", bbox_to_anchor=(0.5, 0.005),
               ncol=min(6, max(1, len(handles))), fontsize=7, frameon=False)
    if math.isfinite(origin.lat_deg) and (origin.lat_deg or origin.lon_deg):
        add_latlon_axes(ax, origin, km)
    if attribution:
        ax.text(0.995, 0.005, attribution if "©" in attribution else f"© {attribution}",
                transform=ax.transAxes, ha="right", va="bottom", fontsize=7,
                bbox=dict(facecolor="white", alpha=0.8, lw=0))
    fig.suptitle("Map", fontsize=14, weight="bold", x=0.05, ha="left")
    return fig
