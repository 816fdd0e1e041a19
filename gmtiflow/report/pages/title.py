"""Page 1: the title page (scene summary, key numbers)."""
from __future__ import annotations

import math
import textwrap
from typing import Dict, List, Optional, Sequence, Tuple

from matplotlib.figure import Figure

from ..common import new_figure

HOW_TO_READ = [
    "Map: truth (teal) under detections (blue: true, purple: merged, red ×: false alarm) and",
    "   confirmed tracks (purple); footprints coloured by time; terrain shading with a DEM.",
    "Physics sanity: red dots should sit on the black Swerling I curve, histograms on N(0, 1).",
    "Range rate vs azimuth: misses in the clutter notch lie between the MDV lines.",
    "Timeline: one row per vehicle; why each look was missed; stops and tunnels as bars.",
    "Track errors: median and percentile bands over time; the worst tracks by id.",
    "OSPA / identity: lower is better (0 = perfect, c = everything missed or false);",
    "   blind gaps (stops, notch, terrain, tunnels) and what the tracker did after each.",
]
SCENE_VALUE_CHARS = 52
"""Characters per line of a scene value (two lines at most) before the Results column."""
UNITS = ("Units: distances m (map in km), angles °, speeds and range rates m/s, SNR dB, times s "
         "from the scene epoch (UTC); P_D and P_FA are probabilities; RMSE = root mean square "
         "error over associated track rows.")


def _shorten(text: str, width: int) -> str:
    """``text`` cut in the middle to ``width`` characters (paths keep both ends)."""
    text = str(text)
    return text if len(text) <= width else text[:width // 2 - 1] + "…" + text[-(width // 2):]


def _table(fig, title, rows, x0, y0, key_w, ref_dx, width, header=None) -> None:
    """Rows of (name, value, reference) from (x0, y0) down; values wrap at ``width`` characters
    and references at 32 (three lines at most), so nothing runs off the page.  One text per
    column (lines padded so rows line up): a PDF text costs ~3 ms to write, 70 of them were a
    tenth of the report on a big run."""
    fig.text(x0, y0, title, fontsize=12, weight="bold")
    y = y0 - 0.012
    if header:
        fig.text(x0 + key_w, y - 0.012, header[1], fontsize=7.5, color="0.4")
        fig.text(x0 + ref_dx, y - 0.012, header[2], fontsize=7.5, color="0.4")
        y -= 0.014
    names: List[str] = []
    values: List[str] = []
    refs: List[str] = []
    for name, value, ref in rows:
        v = textwrap.wrap(str(value), width)[:3] or [""]
        r = textwrap.wrap(ref, 32)[:3] if ref else []
        h = max(len(v), len(r), 1)
        names += [name] + [""] * (h - 1)
        values += v + [""] * (h - len(v))
        refs += r + [""] * (h - len(r))
    style = dict(fontsize=8.5, va="top", linespacing=1.55)
    y -= 0.012
    fig.text(x0 + 0.005, y, "\n".join(names), weight="bold", **style)
    fig.text(x0 + key_w, y, "\n".join(values), **style)
    if any(refs):
        fig.text(x0 + ref_dx, y, "\n".join(refs), color="0.35", **style)


def reference_values(config: dict, numbers: Dict[str, float],
                     detections, expected_false_alarms: Optional[float]) -> Dict[str, str]:
    """What each result on the title page is to be compared with, by its label: the model's
    mean P_D, the detector's expected false alarms, the sensor's median measurement σ for
    the track errors, the OSPA/GOSPA cut-off, the ideal values of the identity metrics."""
    import numpy as np
    pd_model = numbers.get("pd_model_mean", float("nan"))
    out = {"P_D achieved": (f"the looks' mean model P_D, {pd_model:.3g} (equal when the "
                            f"detector is right)" if math.isfinite(pd_model) else
                            "the looks' mean model P_D"),
           "Identity switches": "0 (ideal)", "Fragmentations": "0 (ideal)",
           "Coverage (mean)": "1 (every vehicle tracked all the time)",
           "Track purity (mean)": "1 (every track on one vehicle)"}
    if expected_false_alarms is not None:
        e = float(expected_false_alarms)
        out["Detections"] = f"noise false alarms expected {e:.4g} ± {math.sqrt(max(e, 0)):.2g}"
    cutoff = (config.get("metrics") or {}).get("cutoff_m") if isinstance(config, dict) else None
    if cutoff is not None:
        for k in ("OSPA mean", "GOSPA mean"):
            out[k] = f"0 = perfect; c = {float(cutoff):g} m: all missed or false"
    if detections is not None and len(detections.get("range_m", ())) and \
            "sigma_range_m" in detections:
        true = np.asarray(detections["truth_id"]) >= 0
        if true.any():
            sr = float(np.nanmedian(np.asarray(detections["sigma_range_m"])[true]))
            sx = float(np.nanmedian((np.asarray(detections["range_m"])
                                     * np.asarray(detections["sigma_azimuth_rad"]))[true]))
            out["Position RMSE"] = f"one report's σ: range {sr:.3g} m, cross-range {sx:.3g} m"
            if "sigma_range_rate_mps" in detections:
                srr = float(np.nanmedian(np.asarray(detections["sigma_range_rate_mps"])[true]))
                out["Range-rate RMSE"] = f"one report's σ: {srr:.3g} m/s"
    return out


# ----------------------------------------------------------------------------- page 1

def title_figure(attrs: dict, config: dict, numbers: Dict[str, float],
                 metrics: Dict[str, Tuple[float, str]], run_name: str,
                 overrides: Optional[Sequence[str]] = None,
                 references: Optional[Dict[str, str]] = None) -> Figure:
    """The run's command line (``overrides``; None when not recorded), the scene, the results
    with what to compare each to (``references``, by result label, e.g. from
    :func:`reference_values`), units, and how to read the pages that follow."""
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
        ("P_D achieved", f"{fmt(numbers.get('pd_achieved'))} over "
                         f"{fmt(numbers.get('looks_drawn'))} looks on visible targets"),
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

    refs = references or {}
    rows = [(k, v, refs.get(k, "")) for k, v in results]

    fig.text(0.04, 0.945, "gmtiflow run report", fontsize=20, weight="bold")
    fig.text(0.04, 0.91, _shorten(run_name, 130), fontsize=9, color="0.3", family="monospace")
    command = ("gmtiflow " + " ".join(overrides)) if overrides else (
        "gmtiflow (no overrides: the packaged defaults)" if overrides is not None
        else "not recorded (no .hydra/overrides.yaml beside the run file: a run made from Python)")
    lines = textwrap.wrap(command, 130, break_on_hyphens=False)[:3]
    fig.text(0.04, 0.885, "Command line:", fontsize=9, weight="bold", va="top")
    fig.text(0.14, 0.885, "\n".join(lines), fontsize=8.5, family="monospace", va="top",
             linespacing=1.3)
    top = 0.885 - 0.025 * len(lines) - 0.02
    tracker = dict(scene).get("Tracker", "")
    if len(tracker) > SCENE_VALUE_CHARS:   # an external track file's path: full width, unbroken
        fig.text(0.04, top + 0.01, "Tracks:", fontsize=9, weight="bold", va="top")
        fig.text(0.14, top + 0.01, _shorten(tracker, 130), fontsize=8.5, family="monospace",
                 va="top")
        scene = [(k, "the track file named above" if k == "Tracker" else v) for k, v in scene]
        top -= 0.05
    _table(fig, "Scene", [(k, v, "") for k, v in scene], 0.04, top, 0.12, 0.0, SCENE_VALUE_CHARS)
    _table(fig, "Results", rows, 0.48, top, 0.13, 0.31, 32, header=("", "value", "reference"))
    fig.text(0.04, 0.215, "How to read this report", fontsize=11, weight="bold")
    half = (len(HOW_TO_READ) + 1) // 2
    for col, chunk in enumerate((HOW_TO_READ[:half], HOW_TO_READ[half:])):
        fig.text(0.05 + 0.47 * col, 0.195, "\n".join(chunk), fontsize=7.5, va="top",
                 linespacing=1.45)
    fig.text(0.04, 0.045, UNITS, fontsize=7.5, color="0.25")
    if attrs.get("attribution"):
        fig.text(0.04, 0.02, f"Map data: {attrs['attribution']}", fontsize=8, color="0.3")
    return fig


def _tracker_text(c) -> str:
    """What tracked: the baseline, a named tracker config, or an external track file."""
    name = c("tracker.name", "nn_kalman")
    if name == "external":
        return f"external tracks: {c('tracker.tracks_file', '?')}"
    return "baseline NN-Kalman" if name == "nn_kalman" else str(name)
