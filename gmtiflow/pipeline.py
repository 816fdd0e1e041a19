"""The staged runner: orders the stages, times and logs them, and writes the run file.

Every stage is a plain function of its config subtree, its inputs and the root seed (from which
it derives its own named random streams, :mod:`gmtiflow.rng`); it reads no files or global state
of its own accord.  :func:`run` is what the CLI calls after Hydra composed and validated the
config; tests call it directly with a composed config and a temporary directory.

Order (DESIGN §1): roads -> terrain (roads draped on it) -> truth -> platform -> sensor (with
merging, false alarms and ambiguities as the scene requires) -> tracker -> metrics -> run file.
"""
from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import Any, Callable, Dict

import numpy as np

from gmtiflow import config as config_mod
from gmtiflow.config import AppConfig
from gmtiflow.evaluate import evaluate, track
from gmtiflow.errors import GmtiflowError
from gmtiflow.export import export_run
from gmtiflow.report import build_run_report
from gmtiflow.scene.platform import Platform
from gmtiflow.scene.roadmap import RoadMap, load_roadmap
from gmtiflow.scene.terrain import Terrain, build_terrain
from gmtiflow.scene.vehicles import build_fleet
from gmtiflow.sensor.effects import build_effects
from gmtiflow.sensor.model import simulate
from gmtiflow.sensor.outcome import Outcome
from gmtiflow.sensor.rcs import RcsModels
from gmtiflow.store import RunWriter
from gmtiflow.tables import Table

log = logging.getLogger(__name__)

RUN_FILE = "run.h5"


class Runner:
    """Runs named stages in order, logging what each did and how long it took."""

    def __init__(self) -> None:
        self.seconds: Dict[str, float] = {}

    def stage(self, name: str, fn: Callable[..., Any], *args, **kwargs) -> Any:
        start = time.perf_counter()
        result = fn(*args, **kwargs)
        self.seconds[name] = time.perf_counter() - start
        log.info("stage %-14s %8.3f s", name, self.seconds[name])
        return result


def sample_times(duration_s: float, dt_s: float) -> np.ndarray:
    """Sample instants 0, dt, 2 dt, ... up to and including ``duration_s`` when it falls on the grid."""
    n = int(np.floor(duration_s / dt_s + 1e-9)) + 1
    return np.arange(n, dtype=np.float64) * dt_s


def drape_roads(roadmap: RoadMap, terrain: Terrain) -> RoadMap:
    """Road nodes on the terrain surface (DESIGN §5: road z from the DEM); flat: unchanged."""
    if terrain.flat:
        return roadmap
    x, y = roadmap.nodes["x_m"], roadmap.nodes["y_m"]
    terrain.check_covers(float(x.min()), float(x.max()), float(y.min()), float(y.max()))
    return roadmap.draped(terrain.drape)


def detection_ancestors(detections: Table, looks: Table) -> Table:
    """/detection_ancestors: (det_id, truth_id) of every vehicle folded into a merged report.

    The looks of a merged report's ancestors point at it (outcome detected for the strongest,
    merged for the others), so the table is read off the looks.
    """
    det_id = np.asarray(looks["det_id"], np.int64)
    has = det_id >= 0
    merged = np.zeros(det_id.shape, bool)
    merged[has] = np.asarray(detections["merged"], bool)[det_id[has]]
    rows = np.flatnonzero(merged)
    order = np.lexsort((looks["vehicle_id"][rows], det_id[rows]))
    return {"det_id": det_id[rows][order],
            "truth_id": np.asarray(looks["vehicle_id"], np.int64)[rows][order]}


def run(cfg: AppConfig, out_dir) -> Path:
    """Simulate the scene of ``cfg`` and write ``<out_dir>/run.h5``; returns its path."""
    config_mod.validate(cfg)
    out_dir = Path(out_dir)
    runner = Runner()
    scene, fidelity = cfg.scene, cfg.fidelity
    rcs_models = RcsModels.from_config(cfg.sensor.rcs)   # reads RCS tables: fail before work
    roadmap = runner.stage("roads", load_roadmap, cfg.roadmap)
    log.info("road map: %d nodes, %d road segments", len(roadmap.nodes["node_id"]),
             len(roadmap.edges["edge_id"]))
    terrain = runner.stage("terrain", build_terrain, cfg.terrain, roadmap.origin)
    roadmap = runner.stage("drape", drape_roads, roadmap, terrain)
    fleet = runner.stage("truth", build_fleet, cfg.vehicles, roadmap, seed=cfg.seed,
                         duration_s=scene.duration_s, dt_s=fidelity.time_step_s)
    platform = runner.stage("platform", Platform, cfg.platform, roadmap.origin)
    times = sample_times(scene.duration_s, fidelity.truth_output_dt_s)
    truth = runner.stage("truth_table", fleet.truth_table, times)
    platform_table = runner.stage("platform_table", platform.state_at, times)
    log.info("truth: %d vehicles, %d samples", len(fleet.vehicles["vehicle_id"]),
             len(truth["time_s"]))

    effects = build_effects(cfg.sensor, cfg.clutter, cfg.seed, fidelity.merge_iterate)
    log.info("sensor effects: %s", ", ".join(type(e).__name__ for e in effects) or "none")
    sensed = runner.stage("sensor", simulate, cfg.sensor, fleet, platform, terrain, cfg.seed,
                          scene.duration_s, roadmap.origin, effects=effects,
                          dwell_mode=fidelity.dwell_mode, los_step_m=fidelity.terrain_step_m,
                          rcs_models=rcs_models, progress=cfg.progress)
    dwells, detections, looks = sensed["dwells"], sensed["detections"], sensed["looks"]
    ancestors = detection_ancestors(detections, looks)
    n_fa = int(np.sum(detections["truth_id"] < 0))
    log.info("sensor: %d dwells, %d detections (%d false alarms, %d merged), %d looks "
             "(%d detected)", len(dwells["dwell_id"]), len(detections["det_id"]), n_fa,
             int(np.sum(detections["merged"])), len(looks["dwell_id"]),
             int(np.sum(looks["outcome"] == Outcome.DETECTED)))
    tracks = runner.stage("track", track, cfg.tracker, detections, dwells, cfg.seed,
                          origin=roadmap.origin)
    metrics = runner.stage("evaluate", evaluate, cfg.metrics, truth, tracks, looks,
                           fleet.vehicles, platform_table, origin=roadmap.origin)

    attrs = {
        "origin_lat_deg": roadmap.origin.lat_deg, "origin_lon_deg": roadmap.origin.lon_deg,
        "origin_height_m": roadmap.origin.height_m, "scene_epoch_utc": scene.epoch_utc,
        "scene_duration_s": scene.duration_s, "attribution": roadmap.attribution,
    }
    path = out_dir / RUN_FILE
    with RunWriter(path, seed=cfg.seed, attrs=attrs) as writer:
        writer.write_text("config", config_mod.to_yaml(cfg))
        writer.write_table("roads/nodes", roadmap.nodes)
        writer.write_table("roads/edges", roadmap.edges)
        writer.write_table("vehicles", fleet.vehicles)
        writer.write_table("truth", truth)
        writer.write_table("platform", platform_table)
        writer.write_table("dwells", dwells)
        writer.write_table("detections", detections)
        writer.write_table("detection_ancestors", ancestors)
        writer.write_table("looks", looks)
        writer.write_table("tracks", tracks)
        for name, table in metrics.items():
            writer.write_table(name, table)
        runner.stage("store", writer.commit)
    log.info("wrote %s", path)
    runner.stage("export", export_run, cfg.export, path, out_dir)
    if cfg.report.enabled:
        try:
            runner.stage("report", build_run_report, cfg.report, path,
                         out_dir / cfg.report.filename)
        except GmtiflowError as exc:   # the run file is complete and valid; say so and go on
            log.error("report not written: %s", exc)
    return path
