"""The sensor stage: dwells, detections and looks of an airborne GMTI radar (DESIGN §5).

:func:`simulate` runs the scan schedule (:mod:`.scan`) over the fleet's truth, vectorised over
(dwell, target) pairs, and returns the ``dwells``, ``detections`` and ``looks`` tables of
docs/tables.md.  Per chunk of whole revisits (:func:`_simulate_chunk`; the pieces share one
:class:`~gmtiflow.sensor.context.SensorRun`):

1. **Poses** (:mod:`.poses`): the platform state and the antenna axes once per dwell; the
   chunk's ``/dwells`` rows.
2. **Pairs** (:mod:`.pairs`): the (dwell, target) pairs to evaluate, in vehicle blocks of
   bounded size, only for the vehicles on the road during the chunk.  ``dwell_resolved``: the
   dwells whose footprint holds the target at each dwell's own time (or the nearest one,
   outcome ``outside_fov``); ``instant_scan``: one pair per vehicle and revisit at the scan's
   middle instant, beam centred on the target.
3. **Visibility, 4. SNR, detection, errors** (:mod:`.looks`): field of view, invisible road,
   terrain line of sight; SNR, the Swerling-I draw, measurement errors and geolocation.
5. **Effects seam.**  Each callable in ``effects`` receives ``(context, detections, looks)`` of
   the chunk (:class:`~gmtiflow.sensor.context.ChunkContext`) and returns the new
   ``(detections, looks)`` (merging, clutter, ambiguities belong there).  Chunk-local ``det_id``
   values must stay consistent between the two tables; the stage renumbers them run-wide
   afterwards.

Random draws are counter-based on (dwell_id, vehicle_id) with keys
``counter_key(seed, "sensor", purpose)`` for purpose in pd, error_range, error_azimuth,
error_range_rate: a vehicle's draws do not depend on any other vehicle.
"""
from __future__ import annotations

from collections import deque
from concurrent.futures import ThreadPoolExecutor
from typing import Dict, Iterable, Iterator, Optional, Tuple

import numpy as np


from gmtiflow import frames
from gmtiflow import bars
from gmtiflow.sensor import scan
from gmtiflow.sensor.columns import DETECTION_COLUMNS, DWELL_COLUMNS, LOOK_COLUMNS
from gmtiflow.sensor.config import SensorConfig
from gmtiflow.sensor.context import ChunkContext, Effect, SensorRun
from gmtiflow.sensor.effects import apply_effects
from gmtiflow.sensor.looks import evaluate_block
from gmtiflow.sensor.poses import chunk_poses, dwell_table
from gmtiflow.sensor.rcs import RcsModels
from gmtiflow.tables import Table

__all__ = ["ChunkContext", "DETECTION_COLUMNS", "DWELL_COLUMNS", "Effect", "LOOK_COLUMNS",
           "SensorRun", "empty_table", "simulate", "simulate_chunks"]


def empty_table(columns: Dict[str, type]) -> Table:
    return {name: np.zeros(0, dtype) for name, dtype in columns.items()}


def _simulate_chunk(run: SensorRun, rev_ids, vehicle_ids, effects, block_vehicles):
    """One chunk of whole revisits; vehicles in blocks of ``block_vehicles`` (bounded working
    memory for big fleets), merged back into (dwell, vehicle) order before the effects, which
    need every detection of a dwell."""
    poses = chunk_poses(run, rev_ids)
    dwells = dwell_table(run, poses)
    vehicle_ids = _on_the_road(run.fleet, vehicle_ids, poses.time_s)
    parts = [evaluate_block(run, poses, vehicle_ids[v0:v0 + block_vehicles])
             for v0 in range(0, len(vehicle_ids), block_vehicles)]
    n_eval = sum(p[2] for p in parts)
    if not parts:     # no vehicles: the dwells still produce false alarms
        detections, looks = empty_table(DETECTION_COLUMNS), empty_table(LOOK_COLUMNS)
    elif len(parts) == 1:
        detections, looks = parts[0][0], parts[0][1]
    else:
        detections, looks = _merge_blocks([p[0] for p in parts], [p[1] for p in parts])
    if effects:
        ctx = ChunkContext(run.cfg, run.seed, run.terrain, run.origin, dwells, poses.b, poses.h,
                           poses.u, run.los_step_m)
        detections, looks = apply_effects(ctx, effects, detections, looks)
    return dwells, detections, looks, n_eval


def _on_the_road(fleet, vehicle_ids, time_s):
    """The vehicles on the road at some instant of the chunk (a fleet with ``start_time_s`` /
    ``end_time_s``; else all): one inactive at every dwell of the chunk has no look row, so
    leaving it out changes nothing and keeps the cost at the traffic, not the fleet size."""
    start = getattr(fleet, "start_time_s", None)
    end = getattr(fleet, "end_time_s", None)
    if start is None or end is None or not len(time_s):
        return vehicle_ids
    t_lo, t_hi = float(np.min(time_s)), float(np.max(time_s))
    pad = 1e-6 * max(1.0, abs(t_hi))       # the fleet's own activity test rounds differently
    on = ((np.asarray(start)[vehicle_ids] <= t_hi + pad)
          & (np.asarray(end)[vehicle_ids] >= t_lo - pad))
    return vehicle_ids if on.all() else vehicle_ids[on]


def _merge_blocks(dets, looks):
    """Concatenate vehicle blocks and restore (dwell, vehicle) order with consecutive ids."""
    offset = 0
    for d, lk in zip(dets, looks):
        lk["det_id"] = np.where(lk["det_id"] >= 0, lk["det_id"] + offset, -1)
        d["det_id"] = d["det_id"] + offset
        offset += len(d["det_id"])
    det = {k: np.concatenate([d[k] for d in dets]) for k in dets[0]}
    lk = {k: np.concatenate([x[k] for x in looks]) for k in looks[0]}
    # blocks are in vehicle order, so a stable sort on the dwell gives (dwell, vehicle)
    order = np.argsort(lk["dwell_id"], kind="stable")
    lk = {k: v[order] for k, v in lk.items()}
    dorder = np.argsort(det["dwell_id"], kind="stable")
    det = {k: v[dorder] for k, v in det.items()}
    new_id = np.empty(offset, np.int64)
    new_id[dorder] = np.arange(offset)
    det["det_id"] = np.arange(offset, dtype=np.int64)
    hit = lk["det_id"] >= 0
    lk["det_id"][hit] = new_id[lk["det_id"][hit]]
    return det, lk


def _renumber(detections: Table, looks: Table, offset: int) -> None:
    old = np.asarray(detections["det_id"], np.int64)
    if old.size and old[0] == 0 and np.all(np.diff(old) == 1):
        # already 0, 1, 2, ... in row order (no effect reordered them): ids + offset
        if offset == 0:       # the first chunk's ids are the run's
            detections["det_id"], looks["det_id"] = old, np.asarray(looks["det_id"], np.int64)
            return
        detections["det_id"] = old + offset
        ld = np.asarray(looks["det_id"], np.int64)
        looks["det_id"] = np.where(ld >= 0, ld + offset, ld)
        return
    order = np.argsort(old, kind="stable")
    new = np.empty_like(old)
    new[order] = np.arange(old.size) + offset
    # the tables keep their row order; ids become offset + rank of the chunk-local id
    detections["det_id"] = new if old.size else old
    ld = np.asarray(looks["det_id"], np.int64)
    has = ld >= 0
    if np.any(has):
        pos = np.searchsorted(old[order], ld[has])
        looks["det_id"] = ld.copy()
        looks["det_id"][has] = new[order][pos]


def simulate_chunks(cfg: SensorConfig, fleet, platform, terrain, seed: int, duration_s: float,
                    origin: frames.Origin, *, effects: Iterable[Effect] = (),
                    dwell_mode="dwell_resolved", los_step_m: float = 30.0,
                    chunk_pairs: int = 300_000, workers: int = 1,
                    stats: Optional[dict] = None, rcs_models: Optional[RcsModels] = None
                    ) -> Iterator[Tuple[Table, Table, Table]]:
    """Yield ``(dwells, detections, looks)`` per chunk of revisits, in time order, with run-wide
    ``det_id`` values: the streaming form of :func:`simulate` (bounded memory for big scenes).

    ``workers`` > 1 computes that many chunks at once in threads (numpy releases the GIL); the
    output is identical to ``workers=1`` because every draw is counter-based.  The fleet,
    platform, terrain and effects must then be safe to call from several threads (read-only).
    """
    cfg = cfg.normalised()
    sched = scan.build_schedule(cfg, duration_s, dwell_mode)
    if rcs_models is None:
        rcs_models = RcsModels.from_config(cfg.rcs)
    vehicles = fleet.vehicles
    vehicle_ids = np.asarray(vehicles["vehicle_id"], np.int64)
    types = vehicles["vehicle_type"]
    if not (isinstance(types, np.ndarray) and types.dtype.kind == "U"):
        types = list(types)      # a unicode array goes as it is: list() of it costs ~0.2 µs a row
    codes = rcs_models.type_codes(types)
    type_codes = np.zeros(int(vehicle_ids.max()) + 1 if vehicle_ids.size else 0, np.int64)
    type_codes[vehicle_ids] = codes
    effects = tuple(effects)
    per_vehicle = 1 if sched.instant else 3    # pairs per vehicle-revisit
    per_rev = max(1, len(vehicle_ids) * per_vehicle)
    if cfg.noise_false_alarms:   # false alarms count like pairs towards the chunk's memory
        per_rev += int(sched.n_dwells * cfg.expected_false_alarms_per_dwell)
    revs_per_chunk = max(1, chunk_pairs // per_rev)
    block_vehicles = max(1, chunk_pairs // per_vehicle)
    if workers > 1:  # enough chunks to keep every worker busy, none too small to pay off
        smallest = max(1, -(-50_000 // per_rev))
        revs_per_chunk = max(smallest, min(revs_per_chunk,
                                           -(-sched.n_revisits // (2 * workers))))
    chunks = [np.arange(r0, min(sched.n_revisits, r0 + revs_per_chunk))
              for r0 in range(0, sched.n_revisits, revs_per_chunk)]

    ctx = SensorRun(cfg, sched, fleet, platform, terrain, seed, origin, rcs_models, type_codes,
                    los_step_m)

    def run(rev_ids):
        return _simulate_chunk(ctx, rev_ids, vehicle_ids, effects, block_vehicles)

    n_det = 0
    evaluated = 0
    if stats is not None:
        stats.update(pairs_evaluated=0, n_revisits=sched.n_revisits, n_dwells=sched.n_total)
    if workers > 1 and len(chunks) > 1:
        pool = ThreadPoolExecutor(max_workers=workers)
        pending = deque()
        results = _ordered_results(pool, pending, run, chunks, workers)
    else:
        pool = None
        results = map(run, chunks)
    try:
        for dw, det, look, n_eval in results:
            _renumber(det, look, n_det)
            n_det += len(det["det_id"])
            evaluated += n_eval
            if stats is not None:
                stats["pairs_evaluated"] = evaluated
            yield dw, det, look
    finally:
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)


def _ordered_results(pool, pending, fn, items, depth):
    """Results of ``fn`` over ``items`` in order, at most ``depth`` computed ahead."""
    it = iter(items)
    for item in it:
        pending.append(pool.submit(fn, item))
        if len(pending) >= depth:
            break
    for item in it:
        yield pending.popleft().result()
        pending.append(pool.submit(fn, item))
    while pending:
        yield pending.popleft().result()


def simulate(cfg: SensorConfig, fleet, platform, terrain, seed: int, duration_s: float,
             origin: frames.Origin, *, effects: Iterable[Effect] = (),
             dwell_mode="dwell_resolved", los_step_m: float = 30.0,
             chunk_pairs: int = 300_000, workers: int = 1,
             stats: Optional[dict] = None, rcs_models: Optional[RcsModels] = None,
             progress: bool = False) -> Dict[str, Table]:
    """Dwells, detections and looks of a run (docs/tables.md).

    Parameters
    ----------
    cfg : SensorConfig
    fleet, platform, terrain : objects with the interfaces of docs/architecture.md
    seed : root seed (draws use ``counter_key(seed, "sensor", purpose)``)
    duration_s : scene duration; revisits whose last dwell falls after it are not run
    origin : the scene's geodetic origin (for lat/lon columns)
    effects : post-processors per chunk of dwells (merge, clutter, ambiguity), see module doc
    dwell_mode : ``dwell_resolved`` or ``instant_scan`` (an Enum by its value); the fidelity
        preset chooses it (``FidelityConfig.dwell_mode``)
    los_step_m : terrain line-of-sight ray step (``FidelityConfig.terrain_step_m``); unused on
        flat terrain
    chunk_pairs : about how many (dwell, target) pairs a chunk holds (bounds working memory)
    workers : chunks computed concurrently in threads (same output for any value)
    stats : if a dict is given, ``pairs_evaluated``, ``n_revisits`` and ``n_dwells`` go in it
    rcs_models : the RCS models, loaded beforehand (``RcsModels.from_config(cfg.rcs)``, which
        reads the table files); loaded here when None
    progress : show a tqdm bar over the chunks (on a terminal only)
    """
    out_d, out_det, out_look = [], [], []
    chunks = simulate_chunks(cfg, fleet, platform, terrain, seed, duration_s, origin,
                             effects=effects, dwell_mode=dwell_mode, los_step_m=los_step_m,
                             chunk_pairs=chunk_pairs, workers=workers, stats=stats,
                             rcs_models=rcs_models)
    for dw, det, look in bars.stage_progress(chunks, progress, desc="sensor", unit="chunk",
                                             leave=False):
        out_d.append(dw)
        out_det.append(det)
        out_look.append(look)
    return {
        "dwells": _concat(out_d, DWELL_COLUMNS),
        "detections": _concat(out_det, DETECTION_COLUMNS),
        "looks": _concat(out_look, LOOK_COLUMNS),
    }


def _concat(tables, columns) -> Table:
    if not tables:
        return empty_table(columns)
    if len(tables) == 1:
        return {name: np.asarray(tables[0][name]).astype(dtype, copy=False)
                for name, dtype in columns.items()}
    return {name: np.concatenate([np.asarray(t[name]) for t in tables]).astype(dtype, copy=False)
            for name, dtype in columns.items()}
