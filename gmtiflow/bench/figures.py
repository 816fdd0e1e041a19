"""A picture of one benchmark scenario's run: roads, truth, plots and where the challenge is.

Drawn from a run file's tables (ENU km): roads (tunnels dashed), each vehicle's truth path with
its name at the start, the radar's plots (true, merged, false alarms), the vehicles' true
positions at looks lost to the Doppler notch, the terrain or a tunnel, and an arrow towards the
radar at mid-scene.  ``benchmarks/benchmark_suite.py --figures`` makes the PNGs of
docs/benchmark.md with it.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from gmtiflow.report.figures import new_figure
from gmtiflow.sensor.outcome import Outcome

from .challenges import RunTables, check
from .scenarios import CHALLENGE_TEXT

LOST = {Outcome.DOPPLER_BLIND: ("#fc8d59", "lost: Doppler notch"),
        Outcome.TERRAIN: ("#8c510a", "lost: terrain shadow"),
        Outcome.INVISIBLE_ROAD: ("#543005", "lost: tunnel")}
VEHICLE_COLOURS = ["#2166ac", "#1b7837", "#762a83", "#b35806", "#01665e", "#c51b7d"]


def scene_figure(run_file, scenario: str):
    t = RunTables(Path(run_file))
    fig = new_figure((8.0, 6.6))
    ax = fig.add_axes([0.09, 0.08, 0.88, 0.78])
    nodes, edges = t["roads/nodes"], t["roads/edges"]
    idx = {int(i): k for k, i in enumerate(nodes["node_id"])}
    for a, b, inv in zip(edges["from_node"], edges["to_node"], edges["invisible"]):
        i, j = idx[int(a)], idx[int(b)]
        ax.plot(np.array([nodes["x_m"][i], nodes["x_m"][j]]) / 1e3,
                np.array([nodes["y_m"][i], nodes["y_m"][j]]) / 1e3,
                color="#543005" if inv else "#bbbbbb", lw=4 if not inv else 2.5,
                ls="--" if inv else "-", zorder=1, solid_capstyle="round")
    det = t["detections"]
    fa = np.asarray(det["truth_id"]) < 0
    merged = np.asarray(det["merged"], bool)
    x, y = np.asarray(det["x_m"]) / 1e3, np.asarray(det["y_m"]) / 1e3
    step = max(1, int(fa.sum() // 1500))
    ax.plot(x[fa][::step], y[fa][::step], "x", color="#d6604d", ms=3, alpha=0.5, zorder=2,
            label=f"false alarm{' (every %d-th)' % step if step > 1 else ''}")
    ax.plot(x[~fa & ~merged], y[~fa & ~merged], ".", color="#4d4d4d", ms=3, zorder=3,
            label="plot")
    ax.plot(x[merged], y[merged], "D", color="#984ea3", ms=5, zorder=5, label="merged plot")
    veh = t["vehicles"]
    for k, (vid, name) in enumerate(zip(veh["vehicle_id"], veh["name"])):
        tr = t.truth_of(int(vid))
        if not tr["time_s"].size:
            continue
        colour = VEHICLE_COLOURS[k % len(VEHICLE_COLOURS)]
        ax.plot(tr["x_m"] / 1e3, tr["y_m"] / 1e3, color=colour, lw=1.3, zorder=4)
        ax.annotate(str(name), (tr["x_m"][0] / 1e3, tr["y_m"][0] / 1e3), fontsize=7,
                    color=colour, xytext=(3, -9), textcoords="offset points")
    for outcome, (colour, label) in LOST.items():
        px, py = [], []
        for vid in veh["vehicle_id"]:
            times = t.looks_of(int(vid), outcome)
            if times.size:
                tr = t.truth_of(int(vid))
                px.append(np.interp(times, tr["time_s"], tr["x_m"]))
                py.append(np.interp(times, tr["time_s"], tr["y_m"]))
        if px:
            ax.plot(np.concatenate(px) / 1e3, np.concatenate(py) / 1e3, "o", mfc="none",
                    mec=colour, ms=7, mew=1.4, zorder=6, label=label)
    # the view: roads and truth with a margin (false alarms fill the whole footprint)
    px = np.concatenate([np.asarray(nodes["x_m"], float), np.asarray(t["truth"]["x_m"], float)])
    py = np.concatenate([np.asarray(nodes["y_m"], float), np.asarray(t["truth"]["y_m"], float)])
    pad = 0.25 * max(np.ptp(px), np.ptp(py), 500.0)
    ax.set_xlim((px.min() - pad) / 1e3, (px.max() + pad) / 1e3)
    ax.set_ylim((py.min() - pad) / 1e3, (py.max() + pad) / 1e3)
    plat = t["platform"]
    sensor = np.asarray(plat["sensor_id"]) if "sensor_id" in plat else np.zeros(len(plat["time_s"]))
    xlim, ylim = ax.get_xlim(), ax.get_ylim()
    cx, cy = np.mean(xlim), np.mean(ylim)
    span = 0.12 * max(xlim[1] - xlim[0], ylim[1] - ylim[0])
    for k, s_id in enumerate(np.unique(sensor)):     # an arrow towards each radar at mid-scene
        rows = np.flatnonzero(sensor == s_id)
        mid = rows[len(rows) // 2]
        d = np.array([plat["x_m"][mid] / 1e3 - cx, plat["y_m"][mid] / 1e3 - cy])
        d /= np.linalg.norm(d)
        base = (xlim[0] + (0.1 + 0.25 * k) * (xlim[1] - xlim[0]),
                ylim[0] + 0.88 * (ylim[1] - ylim[0]))
        who = f"radar {int(s_id)}" if len(np.unique(sensor)) > 1 else "radar"
        ax.annotate("to %s\n(t = %.0f s)" % (who, plat["time_s"][mid]),
                    xy=(base[0] + d[0] * span, base[1] + d[1] * span), xytext=base,
                    arrowprops={"arrowstyle": "->", "lw": 1.5}, fontsize=7, ha="center",
                    va="bottom")
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("east (km)")
    ax.set_ylabel("north (km)")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper right", fontsize=7, framealpha=0.85)
    result = check(scenario, run_file)
    fig.text(0.5, 0.965, f"{scenario}: {CHALLENGE_TEXT.get(scenario, '')}", ha="center",
             fontsize=10, weight="bold")
    fig.text(0.5, 0.925, f"seed {int(np.asarray(_seed(run_file)))}: {result.summary}",
             ha="center", fontsize=8)
    return fig


def _seed(run_file) -> int:
    from gmtiflow import store
    with store.open_run(run_file) as f:
        return int(f.attrs.get("seed", -1))


def save_scene_png(run_file, scenario: str, png, dpi: int = 80) -> Path:
    png = Path(png)
    png.parent.mkdir(parents=True, exist_ok=True)
    scene_figure(run_file, scenario).savefig(png, dpi=dpi)
    return png
