"""The stage functions of a run and what they share (:class:`RunState`, :class:`TableSink`).

:mod:`gmtiflow.pipeline` declares the stages (name, inputs, cache key, tables) and runs them;
the work of each is here: ``compute`` functions take the :class:`RunState` and return the
stage's value, ``_write_*`` functions put it into the run file and return what later stages
read.  Order and data flow: docs/architecture.md.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional, Tuple

import numpy as np

from gmtiflow import bars, rundir
from gmtiflow.coverage import sensors_table
from gmtiflow.config import AppConfig, SensorSlot
from gmtiflow.errors import GmtiflowError
from gmtiflow.export import export_run, open_live_export
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
from gmtiflow.tables import Table, empty_like, n_rows

log = logging.getLogger(__name__)

RUN_FILE = rundir.RUN_FILE


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
            self._first = empty_like(table)   # not views: they would keep the rows alive
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
        block = self._pending          # joined column by column as the writer compresses
        self._pending, self._n_pending = [], 0
        self.writer.append_table(self.name, block)
        self._created = True

    def close(self) -> None:
        if not self._created and self._pending:
            # every row arrived before the first block was due: one dataset of exactly these
            # rows (chunks of its own size; no padding to a full streaming chunk)
            block = self._pending
            self._pending, self._n_pending = [], 0
            self.writer.write_table(self.name, block)
            self._created = True
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


@dataclass
class RunState:
    """What the stages of one run share: the config, its sensors, the run file and the values."""

    cfg: AppConfig
    slots: List[SensorSlot]
    writer: Optional[RunWriter] = None
    values: Dict[str, Any] = field(default_factory=dict)
    seconds: Dict[str, float] = field(default_factory=dict)
    sinks: Dict[str, "TableSink"] = field(default_factory=dict)
    rcs: Dict[str, RcsModels] = field(default_factory=dict)
    live: Any = None
    """``export.stream``: the live 4607 sink every sensor chunk is sent to (gmtiflow.live)."""

    @property
    def keep(self) -> bool:
        """Whole tables are kept in memory only for the tracker and the metrics."""
        return bool(self.cfg.tracker.enabled or self.cfg.metrics.enabled)

    def sink(self, name: str, columns: Optional[Dict[str, type]] = None,
             keep: Optional[bool] = None) -> "TableSink":
        """The streaming sink of run-file table ``name`` (shared by the stages that fill it)."""
        if name not in self.sinks:
            self.sinks[name] = TableSink(self.writer, name, columns,
                                         keep=self.keep if keep is None else keep)
        return self.sinks[name]

    def table(self, name: str, columns: Dict[str, type]) -> Table:
        """Close sink ``name`` and return its rows (empty when the run keeps no tables)."""
        sink = self.sink(name, columns)
        sink.close()
        return sink.table() if sink.keep else empty_table(columns)


SENSOR_ID = {"sensor_id": np.int64}
"""Column added to /dwells, /detections, /looks and /platform: which sensor (0..S-1)."""
SENSORS_COLUMNS = {"sensor_id": np.int64, "name": str, "platform_id": str}


def build_scene(cfg: AppConfig) -> Tuple[RoadMap, Terrain]:
    """Roads, terrain and the roads draped on it (the ``scene`` stage's value)."""
    roadmap = load_roadmap(cfg.roadmap)
    terrain = build_terrain(cfg.terrain, roadmap.origin)
    return drape_roads(roadmap, terrain), terrain


def write_scene(state: RunState, value):
    roadmap, _ = value
    cfg = state.cfg
    state.writer.set_attrs({
        "origin_lat_deg": roadmap.origin.lat_deg, "origin_lon_deg": roadmap.origin.lon_deg,
        "origin_height_m": roadmap.origin.height_m, "scene_epoch_utc": cfg.scene.epoch_utc,
        "scene_duration_s": cfg.scene.duration_s, "attribution": roadmap.attribution})
    state.writer.write_table("roads/nodes", roadmap.nodes)
    state.writer.write_table("roads/edges", roadmap.edges)
    log.info("road map: %d nodes, %d road segments", len(roadmap.nodes["node_id"]),
             len(roadmap.edges["edge_id"]))
    return value


def truth(state: RunState):
    cfg, (roadmap, _) = state.cfg, state.values["scene"]
    return build_fleet(cfg.vehicles, roadmap, seed=cfg.seed, duration_s=cfg.scene.duration_s,
                       dt_s=cfg.fidelity.time_step_s, progress=cfg.progress)


def write_vehicles(state: RunState, fleet):
    state.writer.write_table("vehicles", fleet.vehicles)
    return fleet


def _sample_times(cfg: AppConfig) -> np.ndarray:
    return sample_times(cfg.scene.duration_s, cfg.fidelity.truth_output_dt_s)


def truth_table(state: RunState):
    """/truth, ``chunk_s`` seconds of scene time at a time, appended block by block
    (:meth:`Fleet.truth_blocks`)."""
    cfg, fleet = state.cfg, state.values["truth"]
    times = _sample_times(cfg)
    sink = state.sink("truth")
    for tt in bars.stage_progress(time_chunks(times, cfg.chunk_s), cfg.progress,
                                  desc="truth table", unit="chunk", leave=False):
        for block in fleet.truth_blocks(tt):
            sink.append(block)
    if not sink.n_rows:         # no vehicle active at any sample: the empty table's columns
        sink.append(fleet.truth_table(times[:0]))
    sink.close()
    log.info("truth: %d vehicles, %d samples", len(fleet.vehicles["vehicle_id"]), sink.n_rows)
    return sink.table() if sink.keep else None


def platform(state: RunState, slot: SensorSlot):
    return Platform(slot.platform, state.values["scene"][0].origin)


def platform_table(state: RunState):
    """/sensors (one row per sensor) and /platform (each platform's states, sensor by sensor)."""
    times = _sample_times(state.cfg)
    state.writer.write_table("sensors", {
        "sensor_id": np.array([s.sensor_id for s in state.slots], np.int64),
        "name": np.array([s.name for s in state.slots], dtype=object),
        "platform_id": np.array([s.platform_id for s in state.slots], dtype=object)})
    tables = []
    for slot in state.slots:
        table = dict(state.values[f"platform.{slot.name}"].state_at(times))
        table["sensor_id"] = np.full(len(times), slot.sensor_id, np.int64)
        tables.append(table)
    table = tables[0] if len(tables) == 1 else \
        {c: np.concatenate([t[c] for t in tables]) for c in tables[0]}
    state.writer.write_table("platform", table)
    return table


def sensor(state: RunState, slot: SensorSlot):
    """The chunks (dwells, detections, looks) of one sensor, with sensor-local ids."""
    cfg, (roadmap, terrain) = state.cfg, state.values["scene"]
    fid = cfg.fidelity
    effects = build_effects(slot.sensor, cfg.clutter, slot.stream_seed, fid.merge_iterate)
    log.info("sensor %s effects: %s", slot.name,
             ", ".join(type(e).__name__ for e in effects) or "none")
    return simulate_chunks(slot.sensor, state.values["truth"],
                           state.values[f"platform.{slot.name}"], terrain, slot.stream_seed,
                           cfg.scene.duration_s, roadmap.origin, effects=effects,
                           dwell_mode=fid.dwell_mode, los_step_m=fid.terrain_step_m,
                           rcs_models=state.rcs[slot.name], workers=cfg.sensor_workers)


def write_sensor(state: RunState, chunks, slot: SensorSlot):
    """Append one sensor's chunks: run-wide dwell and det ids (after the sensors before it),
    its ``sensor_id`` on every row."""
    sinks = {"dwells": state.sink("dwells", {**DWELL_COLUMNS, **SENSOR_ID}),
             "detections": state.sink("detections", {**DETECTION_COLUMNS, **SENSOR_ID}),
             "detection_ancestors": state.sink("detection_ancestors", {
                 "det_id": np.int64, "truth_id": np.int64}, keep=False),
             "looks": state.sink("looks", {**LOOK_COLUMNS, **SENSOR_ID})}
    dwell0, det0 = sinks["dwells"].n_rows, sinks["detections"].n_rows
    if state.cfg.export.stream.url and state.live is None:
        state.live = open_live_export(
            state.cfg.export, state.values["scene"][0].origin, state.cfg.scene.epoch_utc,
            {"sensor": {"revisit_s": slot.sensor.revisit_s},
             "clutter": {"fov_density_per_km2": state.cfg.clutter.fov_density_per_km2}})
    counts = dict.fromkeys(("dwells", "detections", "fa", "merged", "looks", "detected"), 0)
    for dw, det, look in bars.stage_progress(chunks, state.cfg.progress,
                                             desc=f"sensor {slot.name}", unit="chunk",
                                             leave=False):
        anc = detection_ancestors(det, look)
        dw, det, look = _as_run_wide(slot.sensor_id, dwell0, det0, dw, det, look)
        if state.live is not None:          # export.stream: out on the network as simulated
            state.live.append(dw, det)
        anc["det_id"] = anc["det_id"] + det0
        for name, table in (("dwells", dw), ("detections", det), ("looks", look),
                            ("detection_ancestors", anc)):
            sinks[name].append(table)
        counts["dwells"] += n_rows(dw)
        counts["detections"] += n_rows(det)
        counts["looks"] += n_rows(look)
        counts["fa"] += int(np.sum(det["truth_id"] < 0))
        counts["merged"] += int(np.sum(det["merged"]))
        counts["detected"] += int(np.sum(look["outcome"] == Outcome.DETECTED))
    log.info("sensor %s: %d dwells, %d detections (%d false alarms, %d merged), %d looks "
             "(%d detected)", slot.name, counts["dwells"], counts["detections"], counts["fa"],
             counts["merged"], counts["looks"], counts["detected"])
    return counts


def _as_run_wide(sensor_id: int, dwell0: int, det0: int, dw: Table, det: Table, look: Table):
    """One sensor's chunk with run-wide ids: dwell ids + ``dwell0``, det ids + ``det0``."""
    def shifted(table, **offsets):
        out = dict(table)
        for column, offset in offsets.items():
            ids = np.asarray(out[column], np.int64)
            out[column] = np.where(ids >= 0, ids + offset, ids) if offset else ids
        out["sensor_id"] = np.full(n_rows(table), sensor_id, np.int64)
        return out
    return (shifted(dw, dwell_id=dwell0), shifted(det, dwell_id=dwell0, det_id=det0),
            shifted(look, dwell_id=dwell0, det_id=det0))


def track(state: RunState):
    cfg = state.cfg
    detections = state.table("detections", {**DETECTION_COLUMNS, **SENSOR_ID})
    dwells = state.table("dwells", {**DWELL_COLUMNS, **SENSOR_ID})
    for name in ("looks", "detection_ancestors"):
        state.sinks[name].close()
    if not cfg.tracker.enabled:        # tracker=none: no tracker module (scipy.optimize)
        from gmtiflow.evaluate.tracks import empty_tracks
        return empty_tracks()
    from gmtiflow.evaluate import track as run_tracker    # imported when run (scipy)
    return run_tracker(cfg.tracker, detections, dwells, cfg.seed,
                 origin=state.values["scene"][0].origin, epoch_utc=cfg.scene.epoch_utc,
                 duration_s=cfg.scene.duration_s)


def write_tracks(state: RunState, tracks):
    state.writer.write_table("tracks", tracks)
    return tracks


def evaluate(state: RunState):
    """The metrics of the fused tracks, and /metrics/sensors: each sensor's and the fused
    detection coverage and blind gaps (:mod:`gmtiflow.coverage`)."""
    cfg = state.cfg
    platform = state.values["platform_table"]
    first = np.asarray(platform["sensor_id"]) == 0
    looks = state.table("looks", {**LOOK_COLUMNS, **SENSOR_ID})
    dwells = state.table("dwells", {**DWELL_COLUMNS, **SENSOR_ID})
    # Scored from the first dwell of any sensor to the last (docs/evaluation.md, "Time base").
    last_dwell_s = float(np.max(dwells["time_s"])) if len(dwells["time_s"]) else None
    first_dwell_s = float(np.min(dwells["time_s"])) if len(dwells["time_s"]) else None
    from gmtiflow.evaluate import evaluate as evaluate_tracks   # scipy: only when scored
    metrics = evaluate_tracks(cfg.metrics, state.values["truth_table"], state.values["track"],
                              looks, state.values["truth"].vehicles,
                              {c: np.asarray(v)[first] for c, v in platform.items()},
                              origin=state.values["scene"][0].origin, until_s=last_dwell_s,
                              since_s=first_dwell_s)
    window_s = 2.0 * max(slot.sensor.revisit_s for slot in state.slots)
    metrics["metrics/sensors"] = sensors_table(
        [slot.name for slot in state.slots], state.values["truth_table"], dwells,
        state.table("detections", {**DETECTION_COLUMNS, **SENSOR_ID}), looks,
        window_s=window_s, end_s=cfg.scene.duration_s)
    return metrics


def write_metrics(state: RunState, metrics):
    for name, table in metrics.items():
        state.writer.write_table(name, table)
    return metrics


def commit(state: RunState):
    for sink in state.sinks.values():
        sink.close()
    path = state.writer.commit()
    log.info("wrote %s", path)
    return path


def export(state: RunState):
    return export_run(state.cfg.export, state.values["store"], state.values["store"].parent)


def report(state: RunState):
    cfg, path = state.cfg, state.values["store"]
    try:
        return build_run_report(cfg.report, path, path.parent / cfg.report.filename)
    except GmtiflowError as exc:   # the run file is complete and valid; say so and go on
        log.error("report not written: %s", exc)
        return None
