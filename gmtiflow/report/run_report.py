"""The run report: one PDF per run, built from a finished ``run.h5`` only.

Pipeline hook (the runner calls it after the run file is committed)::

    from gmtiflow.report import build_run_report
    if cfg.report.enabled:
        build_run_report(cfg.report, path, out_dir / cfg.report.filename)

Pages (``PAGES``): title (scene summary, key numbers), map, physics sanity (P_D vs SNR and
normalised measurement errors), range rate vs azimuth (clutter notch, blind speeds), per-vehicle
timeline, track errors (paper Fig. 5), OSPA/GOSPA and identity events; with several sensors a
"sensors" page (per-sensor and fused coverage) follows the title.  The PDF is written under
a temporary name and renamed when complete, so an interrupted report never looks finished.
"""
from __future__ import annotations

import gc
import logging
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np
from matplotlib.backends.backend_pdf import PdfPages
from matplotlib.figure import Figure

from gmtiflow.formats import atomic_path
from gmtiflow import __version__
from gmtiflow.console import progress

from . import figures as F
from .config import ReportConfig
from .data import RunData, key_numbers, load_run, n, summary
from .pages.title import reference_values
from .relief import run_terrain, terrain_source
from .sensors_page import sensors_figure

log = logging.getLogger(__name__)

PAGES = ("title", "map", "sensor", "range_rate", "timeline", "track_errors", "ospa")
"""The pages of a one-sensor run; a run with several sensors adds "sensors" after the title."""


def run_figures(run: RunData, cfg: ReportConfig) -> List[Tuple[str, Callable[[], Figure]]]:
    """The report's pages in order, as (name, builder) pairs (built lazily, one at a time)."""
    t = run.table
    tracker_on = bool(run.cfg("tracker.enabled", True))
    pages = [
        ("title", lambda: _title(run)),
        ("map", lambda: F.map_figure(t("roads/nodes"), t("roads/edges"), t("truth"), t("platform"),
                                     t("dwells"), t("detections"), t("tracks"),
                                     run.cfg("clutter.regions", []) or [], run.origin,
                                     str(run.attrs.get("attribution", "") or ""),
                                     max_points=cfg.max_points, max_footprints=cfg.max_footprints,
                                     max_track_lines=cfg.max_track_lines,
                                     **_terrain_args(run))),
        ("sensor", lambda: F.sensor_figure(t("looks"), t("detections"),
                                           float(run.cfg("sensor.pfa", 1e-6)),
                                           snr_bin_db=cfg.snr_bin_db,
                                           expected_false_alarms=_expected_false_alarms(run))),
        ("range_rate", lambda: F.range_rate_figure(t("looks"), t("detections"), t("dwells"),
                                                   max_points=cfg.max_points)),
        ("timeline", lambda: F.timeline_figure(t("vehicles"), t("truth"), t("looks"),
                                               max_vehicles=cfg.max_timeline_vehicles)),
        ("track_errors", lambda: F.track_errors_figure(t("metrics/track_errors"),
                                                       max_tracks=cfg.max_track_lines,
                                                       tracker_enabled=tracker_on)),
        ("ospa", lambda: F.ospa_figure(t("metrics/ospa"), t("metrics/identity_switches"),
                                       _fused(t("metrics/events")),
                                       cutoff_m=float(run.cfg("metrics.cutoff_m", float("nan"))),
                                       tracker_enabled=tracker_on)),
    ]
    sensors = t("metrics/sensors")
    if len(sensors.get("name", ())) > 2:    # several sensors (one row each, and the fused row)
        window_s = 2.0 * max(float(run.cfg("sensor.revisit_s", 0.0)), *(
            float(s.get("sensor", {}).get("revisit_s", 0.0))
            for s in (run.cfg("sensors", {}) or {}).values()))
        pages.insert(1, ("sensors", lambda: sensors_figure(sensors, window_s)))
    return pages


def _fused(events):
    """The fused events (``sensor_id`` -1); per-sensor rows would repeat them on the page."""
    if "sensor_id" not in events:
        return events
    keep = np.asarray(events["sensor_id"]) < 0
    return {k: np.asarray(v)[keep] for k, v in events.items()}


def _title(run: RunData) -> Figure:
    numbers = key_numbers(run)
    return F.title_figure(run.attrs, run.config, numbers, summary(run.table("metrics")),
                          str(run.path), overrides=recorded_overrides(run.path),
                          references=reference_values(run.config, numbers,
                                                      run.table("detections"),
                                                      _expected_false_alarms(run)))


def _terrain_args(run: RunData) -> dict:
    """The map page's terrain arguments: the run's DEM rebuilt from its config (gmtiflow.report.relief)."""
    terrain, note = run_terrain(run.config, run.origin)
    return dict(terrain=terrain, terrain_name=terrain_source(run.config), terrain_note=note)


def recorded_overrides(run_path: Path) -> Optional[List[str]]:
    """The command-line overrides of the run (Hydra's ``.hydra/overrides.yaml`` beside the run
    file), or None when the run did not record them (made from Python, or moved)."""
    import yaml
    path = Path(run_path).parent / ".hydra" / "overrides.yaml"
    try:
        items = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, yaml.YAMLError):
        return None
    return [str(x) for x in items] if isinstance(items, list) else None


def _expected_false_alarms(run: RunData) -> Optional[float]:
    """The detector's expected noise false alarms of the run (P_FA × cells per dwell × dwells),
    None when the run's config does not say (an older run) or they were switched off."""
    from gmtiflow.sensor.config import SensorConfig
    sensor = run.cfg("sensor", None)
    if not isinstance(sensor, dict):
        return None
    names = set(SensorConfig.__dataclass_fields__) - {"rcs", "merge"}
    try:
        cfg = SensorConfig(**{k: v for k, v in sensor.items() if k in names})
        if not cfg.noise_false_alarms or "noise_false_alarms" not in sensor:
            return None
        return cfg.expected_false_alarms_per_dwell * n(run.table("dwells"))
    except (TypeError, ValueError):
        return None


def build_run_report(cfg: ReportConfig, run_path, out_pdf,
                     extra_pages: Sequence[Tuple[str, Callable[[], Figure]]] = ()) -> Path:
    """Build the PDF report of the finished run file ``run_path`` at ``out_pdf``; returns it.

    Reads nothing but ``run_path``; ``extra_pages`` ((name, builder) pairs) follow the title
    page (``gmtiflow-report --tracks --baseline`` adds its side-by-side page so).  Raises
    :class:`gmtiflow.errors.StoreError` for a missing or incomplete run file.  With ``cfg.animation`` also writes ``<out_pdf stem>.gif`` beside it.
    """
    with _old_objects_frozen():
        return _build_run_report(cfg, run_path, out_pdf, extra_pages)


@contextmanager
def _old_objects_frozen():
    """Objects alive before the report (the modules: ~150,000 after the report's imports) are
    moved out of the garbage collector's generations while it is built (``gc.freeze``, undone
    on exit), so the full collections that the pages' many artists trigger no longer rescan
    them.  Inside :func:`gmtiflow.pipeline.run`, which froze them already, nothing changes.

    The 1,000-vehicle run's report in a fresh process: collections 0.13-0.21 -> 0.04-0.05 s.
    """
    if gc.get_freeze_count():          # a caller froze them; its unfreeze must stay the only one
        yield
        return
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()


def _build_run_report(cfg: ReportConfig, run_path, out_pdf,
                      extra_pages: Sequence[Tuple[str, Callable[[], Figure]]]) -> Path:
    out_pdf = Path(out_pdf)
    start, cpu_start = time.perf_counter(), time.process_time()
    run = load_run(run_path, lazy=True)   # columns read as the pages ask for them
    seconds: Dict[str, float] = {"load": time.perf_counter() - start}
    cpu_seconds: Dict[str, float] = {"load": time.process_time() - cpu_start}
    with atomic_path(out_pdf) as tmp, PdfPages(
            tmp, metadata={"Title": f"gmtiflow run report: {run.path}",
                           "Creator": f"gmtiflow {__version__}"}) as pdf:
        pages = run_figures(run, cfg)
        pages[1:1] = list(extra_pages)
        for page, builder in progress(pages, "report", "page"):   # on a terminal, after 2 s
            t0, c0 = time.perf_counter(), time.process_time()
            pdf.savefig(builder(), dpi=cfg.dpi)   # the figure is dropped here (no pyplot)
            seconds[page] = time.perf_counter() - t0
            cpu_seconds[page] = time.process_time() - c0
    if cfg.viewer:
        from .viewer import build_viewer
        t0 = time.perf_counter()
        build_viewer(run.path, out_pdf.parent / cfg.viewer_filename,
                     max_frames=cfg.viewer_max_frames, max_labels=cfg.viewer_max_labels)
        seconds["viewer"] = time.perf_counter() - t0
    if cfg.animation:
        t0 = time.perf_counter()
        gif = write_animation(run, out_pdf.with_suffix(".gif"), cfg)
        seconds["animation"] = time.perf_counter() - t0
        if gif is not None:
            log.info("wrote %s", gif)
    log.info("report %s in %.2f s (%s)", out_pdf, time.perf_counter() - start,
             ", ".join(f"{k} {v:.2f}" for k, v in seconds.items()))
    build_run_report.last_seconds = seconds  # wall, for benchmarks/report_time.py
    build_run_report.last_cpu_seconds = cpu_seconds
    return out_pdf


def write_animation(run: RunData, out_gif: Path, cfg: ReportConfig) -> Optional[Path]:
    """An animated GIF, one frame per revisit (at most ``animation_max_frames``): truth positions,
    that revisit's detections, and confirmed tracks.

    Blitted: the roads, axes and legend are drawn once; each frame restores that background,
    draws only the three moving layers and the title, and hands the pixels to pillow (adaptive
    palette per frame).  Matplotlib's FuncAnimation + PillowWriter redrew the whole figure per
    frame (24.5 s for 60 frames of the 1,000-vehicle scene).  Returns None (with a log line)
    when pillow is missing.
    """
    try:
        from PIL import Image
    except ImportError:
        log.warning("animation skipped: pillow is not installed")
        return None
    truth, det, tracks, dwells = (run.table(k) for k in ("truth", "detections", "tracks", "dwells"))
    if not n(dwells):
        log.warning("animation skipped: no dwells")
        return None
    rev = np.asarray(dwells["revisit_id"]) if "revisit_id" in dwells else np.asarray(dwells["dwell_id"])
    revisits = np.unique(rev)
    frames = revisits[F.even_subsample(len(revisits), cfg.animation_max_frames)]
    t_end = {int(r): float(np.max(np.asarray(dwells["time_s"])[rev == r])) for r in frames}
    det_rev = rev[np.searchsorted(np.asarray(dwells["dwell_id"]), np.asarray(det["dwell_id"]))] \
        if n(det) else np.zeros(0)
    km = 1e3
    fig = F.new_figure((8, 7))
    ax = fig.add_subplot(111)
    F._draw_roads(ax, run.table("roads/nodes"), run.table("roads/edges"), km)
    pts = [run.table(k) for k in ("roads/nodes", "truth") if n(run.table(k))]
    if pts:
        x = np.concatenate([np.asarray(p["x_m"]) for p in pts]) / km
        y = np.concatenate([np.asarray(p["y_m"]) for p in pts]) / km
        pad = 0.08 * max(np.ptp(x), np.ptp(y), 0.5)
        ax.set_xlim(x.min() - pad, x.max() + pad)
        ax.set_ylim(y.min() - pad, y.max() + pad)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("east (km)")
    ax.set_ylabel("north (km)")
    truth_sc = ax.scatter([], [], s=25, color="#35978f", label="truth", zorder=3, animated=True)
    det_sc = ax.scatter([], [], s=14, color="#2166ac", label="detections (this revisit)", zorder=4,
                        animated=True)
    trk_sc = ax.scatter([], [], s=30, marker="s", facecolor="none", edgecolor="k",
                        label="confirmed tracks", zorder=5, animated=True)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=3, fontsize=8, frameon=False)
    title = ax.set_title("revisit 0000, t = 00000.0 s", animated=True)
    tt = np.asarray(truth["time_s"]) if n(truth) else np.zeros(0)
    tr_t = np.asarray(tracks["time_s"]) if n(tracks) else np.zeros(0)
    conf = np.asarray(tracks["confirmed"], bool) if n(tracks) and "confirmed" in tracks else np.ones(len(tr_t), bool)

    def draw(r):
        te = t_end[int(r)]
        if len(tt):
            tnear = tt[np.argmin(np.abs(tt - te))]
            m = tt == tnear
            truth_sc.set_offsets(np.c_[np.asarray(truth["x_m"])[m], np.asarray(truth["y_m"])[m]] / km)
        m = det_rev == r
        det_sc.set_offsets(np.c_[np.asarray(det["x_m"])[m], np.asarray(det["y_m"])[m]] / km
                           if m.any() else np.zeros((0, 2)))
        m = conf & (tr_t <= te) & (tr_t > te - float(run.cfg("sensor.revisit_s", 5.0)))
        trk_sc.set_offsets(np.c_[np.asarray(tracks["x_m"])[m], np.asarray(tracks["y_m"])[m]] / km
                           if m.any() else np.zeros((0, 2)))
        title.set_text(f"revisit {int(r)}, t = {te:.1f} s")
        return truth_sc, det_sc, trk_sc, title

    fig.set_dpi(80)
    canvas = fig.canvas
    canvas.draw()                                  # the static layers, once
    background = canvas.copy_from_bbox(fig.bbox)
    images = []
    for r in frames:
        canvas.restore_region(background)
        for artist in draw(r):
            artist.axes.draw_artist(artist) if artist.axes is not None else fig.draw_artist(artist)
        rgb = np.asarray(canvas.buffer_rgba())[..., :3].copy()
        images.append(Image.fromarray(rgb).quantize(colors=64, method=Image.Quantize.MEDIANCUT))
    with atomic_path(out_gif, suffix=".partial.gif") as tmp:
        images[0].save(tmp, format="GIF", save_all=True, append_images=images[1:], loop=0,
                       duration=int(round(1000.0 / cfg.animation_fps)))
    return out_gif
