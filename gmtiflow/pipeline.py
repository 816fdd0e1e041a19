"""The staged runner: orders the stages, times and logs them, and writes the run file.

Every stage is a plain function of its config subtree, its inputs and the root seed (from which
it derives its own named random streams, :mod:`gmtiflow.rng`); it reads no files or global state
of its own accord.  :func:`run` is what the CLI calls after Hydra composed and validated the
config; tests call it directly with a composed config and a temporary directory.

Order (DESIGN §1): roads -> terrain (roads draped on it) -> truth -> platform -> sensor (with
merging, false alarms and ambiguities as the scene requires) -> tracker -> metrics -> run file.

Caching (``cache.*``, :mod:`gmtiflow.cache`): the scene (roads + terrain + drape), the truth
(the :class:`~gmtiflow.scene.vehicles.Fleet`), the platform and the sensor output are each
looked up by a key over their config subtrees, their upstream keys, the seed and the code, so
a sweep over sensor settings computes the truth once.  Cached and uncached runs write
bit-identical datasets.

Streaming (docs/scale.md): the run file is written while the stages run.  ``/truth`` is built
and appended ``chunk_s`` seconds of scene time at a time, the sensor's dwells, detections and
looks are appended per chunk of revisits (:func:`~gmtiflow.sensor.model.simulate_chunks`), so
memory stays bounded by the Fleet's profiles plus one chunk.  Only the tracker and the metrics
need whole tables; they are kept in memory only when ``tracker.enabled`` or
``metrics.enabled`` (big scenes: ``tracker=none metrics.enabled=false``).
"""
from __future__ import annotations

import glob
import json
import logging
import os
import time
from pathlib import Path
from typing import Any, Callable, Dict, List, Optional

import numpy as np
from tqdm import tqdm

from gmtiflow.formats import write_atomic
from gmtiflow import config as config_mod
from gmtiflow.cache import StageCache, stage_key
from gmtiflow.config import AppConfig
from gmtiflow.errors import GmtiflowError
from gmtiflow.evaluate import evaluate, track
from gmtiflow.export import export_run, open_live_export, planned_files
from gmtiflow.report import build_run_report
from gmtiflow.scene.platform import Platform
from gmtiflow.scene.roadmap import RoadMap, load_roadmap
from gmtiflow.scene.terrain import Terrain, build_terrain
from gmtiflow.scene.vehicles import build_fleet
from gmtiflow.sensor.effects import build_effects
from gmtiflow.sensor.model import (DETECTION_COLUMNS, DWELL_COLUMNS, LOOK_COLUMNS, empty_table,
                                   simulate_chunks)
from gmtiflow.sensor.outcome import Outcome
from gmtiflow.sensor.rcs import RcsModels
from gmtiflow.store import RunWriter
from gmtiflow.tables import Table, n_rows

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
    merged for the others), so the table is read off the looks.  ``detections`` may be one
    chunk of a run (consecutive ``det_id`` values from any offset) with the looks of that chunk.
    """
    det_id = np.asarray(looks["det_id"], np.int64)
    has = det_id >= 0
    merged = np.zeros(det_id.shape, bool)
    ids = np.asarray(detections["det_id"], np.int64)
    first = int(ids[0]) if ids.size else 0
    merged[has] = np.asarray(detections["merged"], bool)[det_id[has] - first]
    rows = np.flatnonzero(merged)
    order = np.lexsort((looks["vehicle_id"][rows], det_id[rows]))
    return {"det_id": det_id[rows][order],
            "truth_id": np.asarray(looks["vehicle_id"], np.int64)[rows][order]}


class TableSink:
    """Appends the chunks of one run-file table, in blocks of whole HDF5 chunks.

    Rows are buffered until about ``block_rows`` are pending, so appends stay aligned with the
    dataset's chunks; ``keep=True`` also keeps every row for the stages that need the whole
    table (tracker, metrics).  :meth:`close` flushes and creates the table even if empty.
    """

    def __init__(self, writer: RunWriter, name: str, columns: Optional[Dict[str, type]] = None,
                 *, keep: bool = False, block_rows: int = 4 * 65536):
        self.writer, self.name, self.columns = writer, name, columns
        self.keep, self.block_rows = keep, block_rows
        self._pending: List[Table] = []
        self._n_pending = 0
        self._kept: List[Table] = []
        self._first: Optional[Table] = None
        self._created = False
        self.n_rows = 0

    def append(self, table: Table) -> None:
        if self.columns is not None:
            table = {c: np.asarray(table[c]).astype(t, copy=False)
                     for c, t in self.columns.items()}
        if self._first is None:
            self._first = {c: v[:0] for c, v in table.items()}
        rows = n_rows(table)
        self.n_rows += rows
        if self.keep:
            self._kept.append(table)
        if rows:
            self._pending.append(table)
            self._n_pending += rows
            if self._n_pending >= self.block_rows:
                self._flush()

    def _flush(self) -> None:
        if not self._pending:
            return
        block = (self._pending[0] if len(self._pending) == 1 else
                 {c: np.concatenate([p[c] for p in self._pending]) for c in self._pending[0]})
        self._pending, self._n_pending = [], 0
        self.writer.append_table(self.name, block)
        self._created = True

    def close(self) -> None:
        self._flush()
        if not self._created:
            empty = self._first
            if empty is None:
                empty = empty_table(self.columns) if self.columns is not None else {}
            self.writer.write_table(self.name, empty)
            self._created = True

    def table(self) -> Table:
        """All rows appended so far (only with ``keep=True``)."""
        if not self.keep:
            raise RuntimeError(f"/{self.name} was streamed, not kept")
        if not self._kept:
            if self.columns is not None:
                return empty_table(self.columns)
            return dict(self._first) if self._first is not None else {}
        if len(self._kept) == 1:
            return self._kept[0]
        return {c: np.concatenate([k[c] for k in self._kept]) for c in self._kept[0]}


def time_chunks(times: np.ndarray, chunk_s: float) -> List[np.ndarray]:
    """Split sorted sample times into consecutive blocks spanning ``chunk_s`` seconds each."""
    if times.size == 0:
        return []
    edges = np.floor((times - times[0]) / chunk_s + 1e-9).astype(np.int64)
    cut = np.flatnonzero(np.diff(edges)) + 1
    return np.split(times, cut)


def _scene(cfg: AppConfig, runner: Runner):
    roadmap = runner.stage("roads", load_roadmap, cfg.roadmap)
    terrain = runner.stage("terrain", build_terrain, cfg.terrain, roadmap.origin)
    roadmap = runner.stage("drape", drape_roads, roadmap, terrain)
    return roadmap, terrain


def stage_keys(cfg: AppConfig) -> Dict[str, str]:
    """Cache keys of the cached stages (:mod:`gmtiflow.cache`): which settings each depends on.

    scene    roadmap, terrain (and their input files)
    truth    scene + vehicles, scene.duration_s, fidelity.time_step_s, seed
    platform scene (the origin) + platform
    sensor   truth + platform + sensor, clutter, scene.duration_s, fidelity.dwell_mode,
             fidelity.terrain_step_m, fidelity.merge_iterate, seed
    """
    fid, scene = cfg.fidelity, cfg.scene
    k_scene = stage_key("scene", seed=None, roadmap=cfg.roadmap, terrain=cfg.terrain)
    k_truth = stage_key("truth", seed=cfg.seed, upstream=[k_scene], vehicles=cfg.vehicles,
                        duration_s=scene.duration_s, time_step_s=fid.time_step_s)
    k_platform = stage_key("platform", seed=None, upstream=[k_scene], platform=cfg.platform)
    k_sensor = stage_key("sensor", seed=cfg.seed, upstream=[k_truth, k_platform],
                         sensor=cfg.sensor, clutter=cfg.clutter, duration_s=scene.duration_s,
                         dwell_mode=fid.dwell_mode, terrain_step_m=fid.terrain_step_m,
                         merge_iterate=fid.merge_iterate)
    return {"scene": k_scene, "truth": k_truth, "platform": k_platform, "sensor": k_sensor}


MANIFEST = "outputs.json"
"""Written first (``complete: false``, the files the run may write) and last (``complete: true``,
the files it wrote, with sizes); docs/reliability.md, "Re-runs"."""


def planned_names(cfg: AppConfig) -> List[str]:
    """The file names this run will write (or overwrite) in its directory."""
    names = [RUN_FILE, *(name for _, name in planned_files(cfg.export))]
    if cfg.report.enabled:
        names.append(cfg.report.filename)
        if cfg.report.animation:
            names.append(str(Path(cfg.report.filename).with_suffix(".gif")))
    return list(dict.fromkeys(names))


def _temporaries(out_dir: Path, name: str) -> List[Path]:
    """Temporaries a killed writer of ``name`` leaves: RunWriter/report, formats' writers."""
    return sorted(out_dir.glob(f".{glob.escape(name)}.*.partial*")) + \
        sorted(out_dir.glob(f"{glob.escape(name)}.*.part"))


def _read_manifest(out_dir: Path) -> List[str]:
    """File names an earlier run's manifest claims (plain names inside ``out_dir`` only)."""
    path = out_dir / MANIFEST
    if not path.is_file():
        return []
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
        names = list(doc.get("planned", [])) + [f.get("name") for f in doc.get("files", [])]
    except (ValueError, AttributeError, TypeError, OSError) as exc:
        log.warning("%s: unreadable manifest of an earlier run (%s); ignored", path, exc)
        return []
    return [n for n in names if isinstance(n, str) and n and Path(n).name == n
            and n not in (".", "..")]


def _write_manifest(out_dir: Path, doc: dict) -> None:
    write_atomic(out_dir / MANIFEST, (json.dumps(doc, indent=1) + "\n").encode())


def remove_stale_outputs(cfg: AppConfig, out_dir: Path) -> List[Path]:
    """Delete what an earlier run left in ``out_dir``, so nothing there mixes two runs.

    Hydra rewrites ``.hydra/config.yaml`` at the start of every run into a directory; an old
    ``run.h5`` or old exports kept beside it would look like the output of the new config
    (a re-run with ``export=none``, or one that fails or is killed before it commits).  Removed:
    ``run.h5``, the files the earlier run's manifest lists, and writers' temporaries.  Files of
    other names, and files no gmtiflow manifest claims (a first run into a user's folder), stay.
    """
    claimed = _read_manifest(out_dir)
    paths = [out_dir / n for n in dict.fromkeys([RUN_FILE, *claimed])]
    for name in dict.fromkeys([*planned_names(cfg), *claimed]):
        paths += _temporaries(out_dir, name)
    paths.append(out_dir / MANIFEST)
    removed = []
    for path in dict.fromkeys(paths):
        if path.is_file() or path.is_symlink():
            path.unlink()
            removed.append(path)
    if len(removed) > 1 or (removed and removed[0].name != MANIFEST):
        log.info("removed %d output(s) of an earlier run in %s: %s", len(removed), out_dir,
                 ", ".join(p.name for p in removed))
    return removed


def run(cfg: AppConfig, out_dir) -> Path:
    """Simulate the scene of ``cfg`` and write ``<out_dir>/run.h5``; returns its path.

    Outputs an earlier run left in ``out_dir`` are removed first (:func:`remove_stale_outputs`).
    """
    config_mod.validate(cfg)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    remove_stale_outputs(cfg, out_dir)
    planned = planned_names(cfg)
    _write_manifest(out_dir, {"complete": False, "seed": cfg.seed, "planned": planned,
                              "files": []})
    log.info("run pid=%d seed=%d -> %s", os.getpid(), cfg.seed, out_dir)
    runner = Runner()
    scene, fidelity = cfg.scene, cfg.fidelity
    cache = StageCache.from_config(cfg.cache)
    keys = stage_keys(cfg) if cache.enabled else {k: "" for k in
                                                  ("scene", "truth", "platform", "sensor")}
    rcs_models = RcsModels.from_config(cfg.sensor.rcs)   # reads RCS tables: fail before work
    roadmap, terrain = cache.get_or_compute("scene", keys["scene"],
                                            lambda: _scene(cfg, runner))
    log.info("road map: %d nodes, %d road segments", len(roadmap.nodes["node_id"]),
             len(roadmap.edges["edge_id"]))
    fleet = cache.get_or_compute(
        "truth", keys["truth"],
        lambda: runner.stage("truth", build_fleet, cfg.vehicles, roadmap, seed=cfg.seed,
                             duration_s=scene.duration_s, dt_s=fidelity.time_step_s,
                             progress=cfg.progress))
    platform = cache.get_or_compute(
        "platform", keys["platform"],
        lambda: runner.stage("platform", Platform, cfg.platform, roadmap.origin))
    times = sample_times(scene.duration_s, fidelity.truth_output_dt_s)
    keep = bool(cfg.tracker.enabled or cfg.metrics.enabled)

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

        truth_sink = TableSink(writer, "truth", keep=keep)
        start = time.perf_counter()
        for tt in tqdm(time_chunks(times, cfg.chunk_s), desc="truth table", unit="chunk",
                       leave=False, disable=None if cfg.progress else True):
            truth_sink.append(fleet.truth_table(tt))
        if not len(times):
            truth_sink.append(fleet.truth_table(times))
        truth_sink.close()
        runner.seconds["truth_table"] = time.perf_counter() - start
        log.info("stage %-14s %8.3f s", "truth_table", runner.seconds["truth_table"])
        platform_table = runner.stage("platform_table", platform.state_at, times)
        writer.write_table("platform", platform_table)
        log.info("truth: %d vehicles, %d samples", len(fleet.vehicles["vehicle_id"]),
                 truth_sink.n_rows)

        effects = build_effects(cfg.sensor, cfg.clutter, cfg.seed, fidelity.merge_iterate)
        log.info("sensor effects: %s", ", ".join(type(e).__name__ for e in effects) or "none")
        sinks = {"dwells": TableSink(writer, "dwells", DWELL_COLUMNS, keep=keep),
                 "detections": TableSink(writer, "detections", DETECTION_COLUMNS, keep=keep),
                 "detection_ancestors": TableSink(writer, "detection_ancestors", {
                     "det_id": np.int64, "truth_id": np.int64}),
                 "looks": TableSink(writer, "looks", LOOK_COLUMNS, keep=keep)}
        counts = {"fa": 0, "merged": 0, "detected": 0}

        def produce():
            return simulate_chunks(cfg.sensor, fleet, platform, terrain, cfg.seed,
                                   scene.duration_s, roadmap.origin, effects=effects,
                                   dwell_mode=fidelity.dwell_mode,
                                   los_step_m=fidelity.terrain_step_m, rcs_models=rcs_models,
                                   workers=cfg.sensor_workers)

        start = time.perf_counter()
        chunks = cache.stream("sensor", keys["sensor"], produce)
        # export.stream: the 4607 packets of every chunk go out live (gmtiflow.live)
        live_sink = open_live_export(cfg.export, roadmap.origin, scene.epoch_utc,
                                     {"sensor": {"revisit_s": cfg.sensor.revisit_s},
                                      "clutter": {"fov_density_per_km2":
                                                  cfg.clutter.fov_density_per_km2}})
        for dw, det, look in tqdm(chunks, desc="sensor", unit="chunk", leave=False,
                                  disable=None if cfg.progress else True):
            if live_sink is not None:
                live_sink.append(dw, det)
            sinks["dwells"].append(dw)
            sinks["detections"].append(det)
            sinks["detection_ancestors"].append(detection_ancestors(det, look))
            sinks["looks"].append(look)
            counts["fa"] += int(np.sum(det["truth_id"] < 0))
            counts["merged"] += int(np.sum(det["merged"]))
            counts["detected"] += int(np.sum(look["outcome"] == Outcome.DETECTED))
        for sink in sinks.values():
            sink.close()
        if live_sink is not None:
            live_sink.close()
        runner.seconds["sensor"] = time.perf_counter() - start
        log.info("stage %-14s %8.3f s", "sensor", runner.seconds["sensor"])
        log.info("sensor: %d dwells, %d detections (%d false alarms, %d merged), %d looks "
                 "(%d detected)", sinks["dwells"].n_rows, sinks["detections"].n_rows,
                 counts["fa"], counts["merged"], sinks["looks"].n_rows, counts["detected"])

        if keep:
            detections, dwells = sinks["detections"].table(), sinks["dwells"].table()
            looks, truth = sinks["looks"].table(), truth_sink.table()
        else:  # streamed only: the tracker and the metrics are off
            detections, dwells = empty_table(DETECTION_COLUMNS), empty_table(DWELL_COLUMNS)
            looks, truth = empty_table(LOOK_COLUMNS), None
        tracks = runner.stage("track", track, cfg.tracker, detections, dwells, cfg.seed,
                              origin=roadmap.origin)
        writer.write_table("tracks", tracks)
        if cfg.metrics.enabled:
            metrics = runner.stage("evaluate", evaluate, cfg.metrics, truth, tracks, looks,
                                   fleet.vehicles, platform_table, origin=roadmap.origin)
            for name, table in metrics.items():
                writer.write_table(name, table)
        runner.stage("store", writer.commit)
    if cache.enabled:
        log.info("cache: hits %s, misses %s", ",".join(cache.hits) or "-",
                 ",".join(cache.misses) or "-")
    log.info("wrote %s", path)
    runner.stage("export", export_run, cfg.export, path, out_dir)
    if cfg.report.enabled:
        try:
            runner.stage("report", build_run_report, cfg.report, path,
                         out_dir / cfg.report.filename)
        except GmtiflowError as exc:   # the run file is complete and valid; say so and go on
            log.error("report not written: %s", exc)
    written = [n for n in planned if (out_dir / n).is_file()]
    _write_manifest(out_dir, {"complete": True, "seed": cfg.seed, "planned": planned,
                              "files": [{"name": n, "bytes": (out_dir / n).stat().st_size}
                                        for n in written]})
    return path
