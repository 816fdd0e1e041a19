"""The staged runner: orders the stages, times and logs them, and writes the run file.

Every stage is a plain function of its config subtree, its inputs and the root seed (from which
it derives its own named random streams, :mod:`gmtiflow.rng`); it reads no files or global state
of its own accord.  :func:`run` is what the CLI calls after Hydra composed and validated the
config; tests call it directly with a composed config and a temporary directory.
"""
from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import Any, Callable, Dict

import numpy as np

from gmtiflow import config as config_mod
from gmtiflow.config import AppConfig
from gmtiflow.scene.platform import Platform
from gmtiflow.scene.roadmap import load_roadmap
from gmtiflow.scene.vehicles import build_fleet
from gmtiflow.store import RunWriter

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


def run(cfg: AppConfig, out_dir) -> Path:
    """Simulate the scene of ``cfg`` and write ``<out_dir>/run.h5``; returns its path."""
    config_mod.validate(cfg)
    out_dir = Path(out_dir)
    runner = Runner()
    scene = cfg.scene
    roadmap = runner.stage("roads", load_roadmap, cfg.roadmap)
    log.info("road map: %d nodes, %d road segments", len(roadmap.nodes["node_id"]),
             len(roadmap.edges["edge_id"]))
    fleet = runner.stage("truth", build_fleet, cfg.vehicles, roadmap, seed=cfg.seed,
                         duration_s=scene.duration_s, dt_s=cfg.fidelity.time_step_s)
    platform = runner.stage("platform", Platform, cfg.platform, roadmap.origin)
    times = sample_times(scene.duration_s, cfg.fidelity.truth_output_dt_s)
    truth = runner.stage("truth_table", fleet.truth_table, times)
    platform_table = runner.stage("platform_table", platform.state_at, times)
    log.info("truth: %d vehicles, %d samples", len(fleet.vehicles["vehicle_id"]),
             len(truth["time_s"]))

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
        runner.stage("store", writer.commit)
    log.info("wrote %s", path)
    return path
