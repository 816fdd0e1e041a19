"""The staged runner: the stages of a run, declared as data, and the loop that runs them.

:func:`stages` lists what a run does, in order; each :class:`Stage` names its inputs, its cache
key (the settings it depends on), its seed and the run-file tables it writes.  :func:`run`, what
the CLI calls after Hydra composed and validated the config, is a loop over them.  Every stage
is a plain function of its config subtree, its inputs and a seed (from which it derives its own
named random streams, :mod:`gmtiflow.rng`); it reads no files or global state of its own accord.

Order (docs/architecture.md): scene (roads, terrain, roads draped) -> truth -> /truth ->
platform per sensor -> /sensors + /platform -> sensor per sensor (with merging, false alarms
and ambiguities as the scene requires) -> tracker (all sensors fused in time order) ->
metrics -> run file -> exports -> report.

Sensors (:func:`gmtiflow.config.sensor_slots`): one platform + one radar per slot, sensor_id
0..S-1.  A sensor's stages read only its own slot and draw from its own streams (its
``stream_seed``), so adding a sensor leaves the others' dwells, detections and looks
bit-identical; its rows carry ``sensor_id`` and run-wide ``dwell_id``/``det_id`` values that
continue after the sensors before it (docs/tables.md).

Caching (``cache.*``, :mod:`gmtiflow.cache`): a stage with a ``key`` is looked up by a hash of
its config subtrees, its seed, its cached inputs' keys and the code, so a sweep over one
sensor's settings computes the truth and the other sensors once.  Cached and uncached runs
write bit-identical datasets.

Streaming (docs/scale.md): the run file is written while the stages run.  ``/truth`` is built
and appended ``chunk_s`` seconds of scene time at a time, each sensor's dwells, detections and
looks are appended per chunk of revisits (:func:`~gmtiflow.sensor.model.simulate_chunks`), so
memory stays bounded by the Fleet's profiles plus one chunk.  Only the tracker and the metrics
need whole tables; they are kept in memory only when ``tracker.enabled`` or
``metrics.enabled`` (big scenes: ``tracker=none metrics.enabled=false``).
"""
from __future__ import annotations

import gc
import logging
import os
import time
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any, Callable, Dict, List, Optional, Tuple

from gmtiflow import config as config_mod
from gmtiflow import budget, interrupts, rundir
from gmtiflow.cache import StageCache, stage_key
from gmtiflow.config import AppConfig, SensorSlot, sensor_slots
from gmtiflow.errors import ConfigError
from gmtiflow.export import planned_files, stream_problem
from gmtiflow.scene import trajectory
from gmtiflow.sensor.rcs import RcsModels
from gmtiflow import stages as sf   # the stage functions
from gmtiflow.stages import RunState, build_scene
from gmtiflow.stages import (SENSOR_ID, SENSORS_COLUMNS, TableSink, detection_ancestors,
                             drape_roads, sample_times, time_chunks)
from gmtiflow.store import RunWriter

log = logging.getLogger(__name__)

RUN_FILE = rundir.RUN_FILE

__all__ = ["MANIFEST", "RUN_FILE", "SENSOR_ID", "SENSORS_COLUMNS", "RunState", "Stage", "TableSink",
           "build_scene", "detection_ancestors", "drape_roads", "planned_names", "run",
           "sample_times", "stage_keys", "stages", "time_chunks"]

# ---------------------------------------------------------------------------------------------
# The stages.  Each is declared once (name, inputs, cache key, tables) in :func:`stages`; the
# runner (:func:`run`) is a loop over them.  A stage's ``compute`` returns its value (cached when
# it has a ``key``); ``write`` puts that value into the run file and returns what later stages
# read under the stage's name.  Per-sensor stages are one declaration per sensor slot.
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Stage:
    """One step of a run.

    name     unique within the run (``sensor.east``); later stages read its value by this name
    compute  ``fn(state) -> value`` (a stream of chunks when ``stream``)
    inputs   stages whose values it reads; their cache keys are part of its own
    key      ``fn() -> {part: config subtree}``: the settings it depends on (None: never cached)
    seed     the root (or sensor stream) seed its draws derive from; None: it draws nothing
    write    ``fn(state, value) -> value``: writes its tables, returns what later stages read
    tables   the run-file tables it writes (docs/tables.md)
    """

    name: str
    compute: Callable[["RunState"], Any]
    inputs: Tuple[str, ...] = ()
    key: Optional[Callable[[], Dict[str, Any]]] = None
    seed: Optional[int] = None
    stream: bool = False
    write: Optional[Callable[["RunState", Any], Any]] = None
    tables: Tuple[str, ...] = ()


def stages(cfg: AppConfig, slots: Optional[List[SensorSlot]] = None) -> List[Stage]:
    """The stages of a run of ``cfg``, in order (docs/architecture.md draws them)."""
    slots = sensor_slots(cfg) if slots is None else slots
    fid, scene = cfg.fidelity, cfg.scene
    out = [
        Stage("scene", lambda st: build_scene(st.cfg),
              key=lambda: dict(roadmap=cfg.roadmap, terrain=cfg.terrain),
              write=sf.write_scene, tables=("roads/nodes", "roads/edges")),
        Stage("truth", sf.truth, inputs=("scene",), seed=cfg.seed,
              key=lambda: dict(vehicles=cfg.vehicles, duration_s=scene.duration_s,
                               time_step_s=fid.time_step_s),
              write=sf.write_vehicles, tables=("vehicles",)),
        Stage("truth_table", sf.truth_table, inputs=("truth",), tables=("truth",)),
    ]
    for slot in slots:
        out.append(Stage(f"platform.{slot.name}", partial(sf.platform, slot=slot),
                         inputs=("scene",), key=partial(dict, platform=slot.platform)))
    out.append(Stage("platform_table", sf.platform_table,
                     inputs=tuple(f"platform.{s.name}" for s in slots),
                     tables=("sensors", "platform")))
    for slot in slots:
        out.append(Stage(
            f"sensor.{slot.name}", partial(sf.sensor, slot=slot),
            inputs=("scene", "truth", f"platform.{slot.name}"), seed=slot.stream_seed,
            key=partial(dict, sensor=slot.sensor, clutter=cfg.clutter,
                        duration_s=scene.duration_s, dwell_mode=fid.dwell_mode,
                        terrain_step_m=fid.terrain_step_m, merge_iterate=fid.merge_iterate),
            stream=True, write=partial(sf.write_sensor, slot=slot),
            tables=("dwells", "detections", "detection_ancestors", "looks")))
    out.append(Stage("track", sf.track, inputs=tuple(f"sensor.{s.name}" for s in slots),
                     write=sf.write_tracks, tables=("tracks",)))
    if cfg.metrics.enabled:
        out.append(Stage("evaluate", sf.evaluate, inputs=("truth_table", "track"),
                         write=sf.write_metrics, tables=("metrics",)))
    out += [Stage("store", sf.commit), Stage("export", sf.export, inputs=("store",))]
    if cfg.report.enabled:
        out.append(Stage("report", sf.report, inputs=("store",)))
    return out


def stage_keys(cfg: AppConfig, declared: Optional[List[Stage]] = None) -> Dict[str, str]:
    """Cache keys of the cached stages (:mod:`gmtiflow.cache`) by stage name: each hashes the
    settings its ``key`` names, its seed and the keys of its cached inputs, so a change
    recomputes exactly the stages downstream of it (one sensor's change: that sensor only)."""
    keys: Dict[str, str] = {}
    for st in declared if declared is not None else stages(cfg):
        if st.key is not None:
            keys[st.name] = stage_key(st.name.split(".")[0], seed=st.seed,
                                      upstream=[keys[i] for i in st.inputs if i in keys],
                                      **st.key())
    return keys

MANIFEST = rundir.MANIFEST


def planned_names(cfg: AppConfig) -> List[str]:
    """The file names this run will write (or overwrite) in its directory."""
    names = [RUN_FILE, *(name for _, name in planned_files(cfg.export))]
    if cfg.report.enabled:
        names.append(cfg.report.filename)
        if cfg.report.animation:
            names.append(str(Path(cfg.report.filename).with_suffix(".gif")))
        if cfg.report.viewer:
            names.append(cfg.report.viewer_filename)
    return list(dict.fromkeys(names))


def run(cfg: AppConfig, out_dir, *, on_prepared: Optional[Callable[[], None]] = None) -> Path:
    """Simulate the scene of ``cfg`` and write ``<out_dir>/run.h5``; returns its path.

    The run directory is locked for the run and outputs an earlier run left there are removed
    first (:mod:`gmtiflow.rundir`); ``on_prepared`` is called after that, before any work (the
    CLI writes Hydra's config files there).  Then every stage of :func:`stages` runs in order,
    its value looked up in the stage cache when it has a key, then written.

    Objects alive before the run (the config, the modules) are moved out of the garbage
    collector's generations for its duration (``gc.freeze``, undone on return, finished or
    failed): the run's full collections no longer rescan them (a 1,000-vehicle config: the
    peer benchmark's 1,000-target child 0.69 -> 0.64 s CPU, median of 5 alternated).
    """
    gc.freeze()
    try:
        return _checked_run(cfg, Path(out_dir), on_prepared)
    finally:
        gc.unfreeze()


def _checked_run(cfg: AppConfig, out_dir: Path,
                 on_prepared: Optional[Callable[[], None]]) -> Path:
    config_mod.validate(cfg)
    budget.check(cfg)                  # refuse what cannot fit before touching the directory
    trajectory.check_scene_coverage(cfg)   # an external log must span the whole scene
    problem = stream_problem(cfg.export, len(sensor_slots(cfg)))
    if problem:
        raise ConfigError(problem)
    with rundir.claim(out_dir):
        rundir.prepare(out_dir, planned_names(cfg), cfg.seed)
        if on_prepared is not None:
            on_prepared()
        return _run(cfg, out_dir)


def _run(cfg: AppConfig, out_dir: Path) -> Path:
    planned = planned_names(cfg)
    log.info("run pid=%d seed=%d -> %s", os.getpid(), cfg.seed, out_dir)
    slots = sensor_slots(cfg)
    state = RunState(cfg, slots, rcs={s.name: RcsModels.from_config(s.sensor.rcs)  # fail early
                                      for s in slots})
    declared = stages(cfg, slots)
    cache = StageCache.from_config(cfg.cache)
    keys = stage_keys(cfg, declared) if cache.enabled else {}
    with RunWriter(out_dir / RUN_FILE, seed=cfg.seed) as state.writer:
        state.writer.write_text("config", config_mod.to_yaml(cfg))
        try:
            for st in declared:
                interrupts.check()       # a Ctrl-C swallowed inside an extension stops here
                start = time.perf_counter()
                compute = partial(st.compute, state)
                if st.name not in keys:
                    value = compute()
                elif st.stream:
                    value = cache.stream(st.name, keys[st.name], compute)
                else:
                    value = cache.get_or_compute(st.name, keys[st.name], compute)
                state.values[st.name] = st.write(state, value) if st.write else value
                state.seconds[st.name] = time.perf_counter() - start
                log.info("stage %-14s %8.3f s", st.name, state.seconds[st.name])
            interrupts.check()
        finally:
            if state.live is not None:      # the live stream ends with the sensor stages
                state.live.close()
    if cache.enabled:
        log.info("cache: hits %s, misses %s", ",".join(cache.hits) or "-",
                 ",".join(cache.misses) or "-")
    written = [n for n in planned if (out_dir / n).is_file()]
    rundir.write_manifest(out_dir, {"complete": True, "seed": cfg.seed, "planned": planned,
                                    "files": [{"name": n, "bytes": (out_dir / n).stat().st_size}
                                              for n in written]})
    return state.values["store"]
