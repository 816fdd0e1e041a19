"""Bringing truth and tracks to common instants.

Two alignments, both vectorised (one ``searchsorted`` over a combined (object, time) key):

* :func:`interpolate_truth`: truth of given vehicles at given instants, linear in time between
  the vehicle's truth samples (position and velocity; speed and heading follow from the
  interpolated velocity).  Instants outside a vehicle's sampled span are invalid.  Used for the
  per-track errors, which are taken at the track's own row times (paper Fig. 5).
* :func:`tracks_at_grid`: the tracks present at each time of an evaluation grid.  A track takes
  part at grid time ``t`` when it has a row at or before ``t`` no older than
  ``max_extrapolation_s``; its position is that row's, extrapolated to ``t`` at the row's
  velocity (held when the table has no velocity).  A track ends with its last row: it is absent
  before its first row and ``end_hold_s`` or more after its last one (a tracker stops reporting
  a track when it deletes it; without this, a deleted track would linger next to its successor
  and make the association flip between the two).  Used for OSPA/GOSPA and identity.

The evaluation grid defaults to the truth table's own sample times, at which truth is exact.
"""
from __future__ import annotations

from typing import Mapping, Tuple

import numpy as np

from gmtiflow import frames
from gmtiflow.evaluate.order import dense_ids, lexorder, small_key_order
from gmtiflow.tables import Table

_EPS_S = 1e-9


def _keys(ids: np.ndarray, times: np.ndarray) -> Tuple[np.ndarray, np.ndarray, float, float]:
    """Dense object index and a combined sortable float key ``index * span + (t - t0)``, for
    ``ids`` sorted (:func:`~gmtiflow.evaluate.order.dense_ids`: the distinct ids from their
    runs, no np.unique sort)."""
    uniq, dense = dense_ids(ids)
    t0 = float(times.min()) if len(times) else 0.0
    span = (float(times.max()) - t0 if len(times) else 0.0) + 1.0
    return uniq, dense, t0, span


def interpolate_truth(truth: Mapping[str, np.ndarray], vehicle_id, time_s) -> Table:
    """Truth of ``vehicle_id[i]`` at ``time_s[i]``: x_m y_m (z_m if truth has it) vx_mps vy_mps
    speed_mps heading_rad, plus ``valid`` (False where the vehicle has no truth sample on both
    sides)."""
    vid = np.asarray(vehicle_id, np.int64)
    tq = np.asarray(time_s, float)
    n = len(vid)
    names = ("x_m", "y_m", "vx_mps", "vy_mps") + (("z_m",) if "z_m" in truth else ())
    out = {k: np.full(n, np.nan) for k in names}
    valid = np.zeros(n, bool)
    tv = np.asarray(truth["vehicle_id"], np.int64)
    tt = np.asarray(truth["time_s"], float)
    if n and len(tv):
        order = lexorder(tv, tt)
        tv, tt = tv[order], tt[order]
        cols = {k: np.asarray(truth[k], float)[order] for k in out}
        uniq, dense, t0, span = _keys(tv, tt)
        key = dense * span + (tt - t0)
        qpos = np.searchsorted(uniq, vid)
        known = (qpos < len(uniq)) & (uniq[np.minimum(qpos, len(uniq) - 1)] == vid)
        qkey = qpos * span + (tq - t0)
        j = np.searchsorted(key, qkey + _EPS_S, side="right") - 1
        jc = np.clip(j, 0, len(tv) - 1)
        j1 = np.clip(j + 1, 0, len(tv) - 1)
        exact = known & (j >= 0) & (tv[jc] == vid) & (np.abs(tt[jc] - tq) <= _EPS_S)
        between = (known & (j >= 0) & (tv[jc] == vid) & (j + 1 < len(tv)) & (tv[j1] == vid)
                   & (tt[j1] >= tq))
        valid = exact | between
        gap = np.where(between & ~exact, tt[j1] - tt[jc], 1.0)
        w = np.where(between & ~exact, (tq - tt[jc]) / np.where(gap > 0, gap, 1.0), 0.0)
        for k, col in cols.items():
            out[k] = np.where(valid, (1.0 - w) * col[jc] + w * col[j1], np.nan)
    out["speed_mps"] = np.hypot(out["vx_mps"], out["vy_mps"])
    out["heading_rad"] = np.where(valid, frames.heading_rad(np.nan_to_num(out["vx_mps"]),
                                                            np.nan_to_num(out["vy_mps"])), np.nan)
    out["valid"] = valid
    return out


def evaluation_grid(truth: Mapping[str, np.ndarray], eval_dt_s=None, since_s=None,
                    until_s=None) -> np.ndarray:
    """The evaluation instants: the truth sample times, or a regular grid of ``eval_dt_s`` from
    the first of them.

    ``since_s``, ``until_s``: the tracker's window (its first and last dwell).  The grid then
    covers it on its own step, whether or not a vehicle is on the road: /truth has rows only for
    vehicles on the road, so the truth's instants alone leave out the time before the first
    vehicle starts, after the last one leaves and between, where a tracker's false tracks
    would cost nothing.  The truth's step is that of its instants (all on one lattice
    ``t0 + k·dt``); truth instants that do not lie on one lattice (or a single instant) are not
    extended.  The window only adds instants: truth instants outside it stay."""
    times = np.unique(np.asarray(truth["time_s"], float))
    if len(times) == 0:
        return times
    lo = times[0] if since_s is None else min(times[0], float(since_s))
    hi = times[-1] if until_s is None else max(times[-1], float(until_s))
    if eval_dt_s is not None:
        dt = float(eval_dt_s)
        k0 = int(np.ceil((lo - times[0]) / dt - 1e-9))
        n = int(np.floor((hi - times[0]) / dt + 1e-9)) + 1
        return times[0] + np.arange(k0, n) * dt
    dt = _lattice_step(times)
    if dt is None or (lo == times[0] and hi == times[-1] and
                      len(times) == int(round((times[-1] - times[0]) / dt)) + 1):
        return times
    k0 = int(np.ceil((lo - times[0]) / dt - 1e-9))
    k1 = int(np.floor((hi - times[0]) / dt + 1e-9))
    lattice = times[0] + np.arange(k0, k1 + 1) * dt
    # the truth's own instants bit for bit, the lattice's where no vehicle is on the road
    j = np.clip(np.searchsorted(times, lattice), 1, len(times) - 1)
    near = np.minimum(np.abs(times[j] - lattice), np.abs(times[j - 1] - lattice)) < 1e-6 * dt
    return np.union1d(times, lattice[~near])


def _lattice_step(times: np.ndarray):
    """The step dt of sorted distinct instants that all lie on one lattice ``t0 + k·dt``
    (to 1e-6 of a step), else None (fewer than two instants, or irregular ones)."""
    if len(times) < 2:
        return None
    dt = float(np.min(np.diff(times)))
    k = (times - times[0]) / dt
    return dt if np.all(np.abs(k - np.round(k)) < 1e-6) else None


def truth_at_grid(truth: Mapping[str, np.ndarray], grid: np.ndarray) -> Table:
    """Truth rows at grid instants: ``step`` (grid index), vehicle_id, x_m, y_m, vx/vy_mps."""
    tt = np.asarray(truth["time_s"], float)
    step = np.searchsorted(grid, tt - _EPS_S)
    on_grid = (step < len(grid)) & (np.abs(grid[np.minimum(step, len(grid) - 1)] - tt) <= _EPS_S)
    if on_grid.all() and (len(np.unique(tt)) == len(grid) or not _inside_a_span(
            step, np.asarray(truth["vehicle_id"], np.int64), len(grid))):
        out = {"step": step.astype(np.int64),
               "vehicle_id": np.asarray(truth["vehicle_id"], np.int64)}
        for k in ("x_m", "y_m", "vx_mps", "vy_mps"):
            out[k] = np.asarray(truth[k], float)
    else:
        vids = np.unique(np.asarray(truth["vehicle_id"], np.int64))
        qv = np.repeat(vids, len(grid))
        qs = np.tile(np.arange(len(grid)), len(vids))
        it = interpolate_truth(truth, qv, grid[qs])
        ok = it["valid"]
        out = {"step": qs[ok].astype(np.int64), "vehicle_id": qv[ok]}
        for k in ("x_m", "y_m", "vx_mps", "vy_mps"):
            out[k] = it[k][ok]
    order = lexorder(out["step"], out["vehicle_id"])
    return {k: v[order] for k, v in out.items()}


def _inside_a_span(step: np.ndarray, vid: np.ndarray, n_steps: int) -> bool:
    """Whether a grid step without any truth row lies strictly inside a vehicle's span of steps
    (the vehicle would be interpolated there); grid steps added only where no vehicle is on the
    road (:func:`evaluation_grid` with a window) do not."""
    empty = np.flatnonzero(np.bincount(step, minlength=n_steps) == 0)
    if not len(empty) or not len(step):
        return False
    ids, dense = dense_ids(vid)             # a bitmap for the usual dense vehicle ids
    first = np.full(len(ids), n_steps, np.int64)
    last = np.full(len(ids), -1, np.int64)
    np.minimum.at(first, dense, step)
    np.maximum.at(last, dense, step)
    return bool(np.any(np.searchsorted(empty, last) > np.searchsorted(empty, first, "right")))


def tracks_at_grid(tracks: Mapping[str, np.ndarray], grid: np.ndarray,
                   max_extrapolation_s: float, end_hold_s: float = np.inf,
                   open_end_s: float = None) -> Table:
    """Track states at grid instants: ``step``, track_id, x_m, y_m (sorted by step, track).

    ``open_end_s``: the end of the tracker's input (its last dwell).  A track whose last row is
    at most ``max_extrapolation_s`` before it did not end (the tracker had no later dwell to
    report it in): it is held, extrapolated, up to ``max_extrapolation_s`` after that row
    instead of ``end_hold_s``.
    """
    tid = np.asarray(tracks["track_id"], np.int64)
    tt = np.asarray(tracks["time_s"], float)
    empty = {"step": np.zeros(0, np.int64), "track_id": np.zeros(0, np.int64),
             "x_m": np.zeros(0), "y_m": np.zeros(0)}
    if len(tid) == 0 or len(grid) == 0:
        return empty
    order = lexorder(tid, tt)
    tid, tt = tid[order], tt[order]
    x = np.asarray(tracks["x_m"], float)[order]
    y = np.asarray(tracks["y_m"], float)[order]
    has_v = "vx_mps" in tracks and "vy_mps" in tracks
    vx = np.asarray(tracks["vx_mps"], float)[order] if has_v else np.zeros(len(tid))
    vy = np.asarray(tracks["vy_mps"], float)[order] if has_v else np.zeros(len(tid))
    uniq, dense, _, _ = _keys(tid, tt)
    first = np.searchsorted(dense, np.arange(len(uniq)))
    last = np.searchsorted(dense, np.arange(len(uniq)), side="right") - 1
    lo = np.searchsorted(grid, tt[first] - _EPS_S)
    hold = np.full(len(uniq), min(float(max_extrapolation_s), float(end_hold_s)))
    alive = np.zeros(len(uniq), bool)
    if open_end_s is not None:
        alive = tt[last] >= float(open_end_s) - float(max_extrapolation_s) - _EPS_S
        hold[alive] = float(max_extrapolation_s)
    hi = np.searchsorted(grid, tt[last] + hold + _EPS_S, side="right")
    # a track that ended is held to instants *less* than end_hold_s after its last row (and at
    # that row's own instant): a vehicle that left the road at its track's last row is not
    # followed by a false track at the next truth instant end_hold_s later
    ended = ~alive & (float(end_hold_s) < float(max_extrapolation_s))
    hi[ended] = np.maximum(
        np.searchsorted(grid, tt[last][ended] + _EPS_S, side="right"),
        np.searchsorted(grid, tt[last][ended] + hold[ended] - _EPS_S, side="left"))
    counts = np.maximum(hi - lo, 0)
    qk = np.repeat(np.arange(len(uniq)), counts)
    starts = np.repeat(lo - np.concatenate([[0], np.cumsum(counts)[:-1]]), counts)
    qs = np.arange(counts.sum()) + starts
    t0 = min(float(tt.min()), float(grid.min()))
    span = max(float(tt.max()), float(grid.max())) - t0 + max_extrapolation_s + 1.0
    key = dense * span + (tt - t0)
    j = np.searchsorted(key, qk * span + (grid[qs] - t0) + _EPS_S, side="right") - 1
    ok = (j >= 0) & (dense[np.maximum(j, 0)] == qk)
    j = np.maximum(j, 0)
    dt = grid[qs] - tt[j]
    ok &= dt <= max_extrapolation_s + _EPS_S
    dt = np.maximum(dt, 0.0)
    out = {"step": qs[ok].astype(np.int64), "track_id": uniq[qk[ok]],
           "x_m": (x[j] + vx[j] * dt)[ok], "y_m": (y[j] + vy[j] * dt)[ok]}
    # rows made track by track (tracks in increasing id), steps increasing within: a stable
    # sort by step gives the (step, track) order
    order = small_key_order(out["step"], len(grid))
    return {k: v[order] for k, v in out.items()}
