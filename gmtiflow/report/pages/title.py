"""Page 1: the title page (scene summary, key numbers)."""
from __future__ import annotations

import math
from typing import Dict, Tuple

from matplotlib.figure import Figure

from gmtiflow.frames import Origin

from ..common import new_figure
from ..data import n


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
        ("Tracker", _tracker_text(c) if c("tracker.enabled", False) else "off"),
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


def _tracker_text(c) -> str:
    """What tracked: the baseline, a named tracker config, or an external track file."""
    name = c("tracker.name", "nn_kalman")
    if name == "external":
        return f"external tracks: {c('tracker.tracks_file', '?')}"
    return "baseline NN-Kalman" if name == "nn_kalman" else str(name)
