"""Per-track errors against the associated truth (the paper's Fig. 5): position, speed, heading
and range rate, at the track's own row times.

A track row at time ``t`` is compared with the vehicle the track is associated with at the grid
step nearest to ``t`` (:mod:`gmtiflow.evaluate.identity`); rows of an unassociated track carry no
error.  Truth is interpolated linearly to ``t`` (:func:`gmtiflow.evaluate.align.interpolate_truth`).

* ``position_error_m`` = ‖track − truth‖ (ground plane);
* ``speed_error_mps`` = track speed − truth speed (signed);
* ``heading_error_rad`` = track heading − truth heading wrapped into [-π, π); NaN when the truth
  moves slower than ``MIN_SPEED_FOR_HEADING_MPS`` (a heading is meaningless at standstill);
* ``range_rate_error_mps`` = track range rate − truth range rate, both seen from the platform
  at ``t`` (the track's ``range_rate_mps`` column when it has one, else implied by its
  velocity); only when a /platform table is given.

Speed and heading errors need the track's velocity columns; they are NaN without them.
"""
from __future__ import annotations

from typing import Mapping, Optional

import numpy as np

from gmtiflow import frames
from gmtiflow.evaluate.align import interpolate_truth
from gmtiflow.evaluate.order import dense_ids
from gmtiflow.tables import Table

MIN_SPEED_FOR_HEADING_MPS = 0.5


def _platform_at(platform: Mapping[str, np.ndarray], t: np.ndarray):
    pt = np.asarray(platform["time_s"], float)
    o = np.argsort(pt)
    cols = ("x_m", "y_m", "z_m", "vx_mps", "vy_mps", "vz_mps")
    return [np.interp(t, pt[o], np.asarray(platform[c], float)[o]) for c in cols]


def track_errors(tracks: Mapping[str, np.ndarray], truth: Mapping[str, np.ndarray],
                 grid: np.ndarray, assoc_step: np.ndarray, assoc_vehicle: np.ndarray,
                 assoc_track: np.ndarray, platform: Optional[Mapping[str, np.ndarray]] = None
                 ) -> Table:
    """Error rows for every track row associated with a truth (see the module docstring)."""
    tid = np.asarray(tracks["track_id"], np.int64)
    tt = np.asarray(tracks["time_s"], float)
    # nearest grid step of each row
    if len(grid) == 0 or len(tid) == 0:
        step = np.zeros(len(tid), np.int64)
    else:
        k = np.clip(np.searchsorted(grid, tt), 1, max(len(grid) - 1, 1))
        k0 = np.maximum(k - 1, 0)
        step = np.where(np.abs(grid[np.minimum(k, len(grid) - 1)] - tt) < np.abs(grid[k0] - tt),
                        np.minimum(k, len(grid) - 1), k0)
    has = assoc_track >= 0
    # lookup (track, step) -> vehicle, keyed by the tracks' dense index (ids may be anywhere
    # in 0 .. 2^63 - 1, where id * (steps + 1) overflowed)
    uniq, dense = dense_ids(tid)
    known = np.searchsorted(uniq, assoc_track[has])    # every associated id is a track's
    pair_key = known * (len(grid) + 1) + assoc_step[has]
    o = np.argsort(pair_key)
    pk, pv = pair_key[o], assoc_vehicle[has][o]
    q = dense * (len(grid) + 1) + step
    j = np.searchsorted(pk, q)
    found = (j < len(pk)) & (pk[np.minimum(j, max(len(pk) - 1, 0))] == q) if len(pk) else \
        np.zeros(len(q), bool)
    vid = np.where(found, pv[np.minimum(j, max(len(pv) - 1, 0))] if len(pv) else -1, -1)
    rows = np.flatnonzero(found)
    truth_i = interpolate_truth(truth, vid[rows], tt[rows])
    rows = rows[truth_i["valid"]]
    truth_i = {k: v[truth_i["valid"]] for k, v in truth_i.items()}
    x = np.asarray(tracks["x_m"], float)[rows]
    y = np.asarray(tracks["y_m"], float)[rows]
    out = {"track_id": tid[rows], "time_s": tt[rows], "vehicle_id": vid[rows],
           "position_error_m": np.hypot(x - truth_i["x_m"], y - truth_i["y_m"])}
    n = len(rows)
    if "vx_mps" in tracks:
        vx = np.asarray(tracks["vx_mps"], float)[rows]
        vy = np.asarray(tracks["vy_mps"], float)[rows]
        out["speed_error_mps"] = np.hypot(vx, vy) - truth_i["speed_mps"]
        moving = truth_i["speed_mps"] >= MIN_SPEED_FOR_HEADING_MPS
        dh = frames.wrap_pi(frames.heading_rad(vx, vy) - truth_i["heading_rad"])
        out["heading_error_rad"] = np.where(moving, dh, np.nan)
    else:
        vx = vy = None
        out["speed_error_mps"] = np.full(n, np.nan)
        out["heading_error_rad"] = np.full(n, np.nan)
    if platform is not None and n:
        px, py, pz, pvx, pvy, pvz = _platform_at(platform, tt[rows])
        z = truth_i["z_m"] if "z_m" in truth_i else np.zeros(n)
        dx, dy, dz = truth_i["x_m"] - px, truth_i["y_m"] - py, z - pz
        r = np.sqrt(dx ** 2 + dy ** 2 + dz ** 2)
        rr_truth = (dx * (truth_i["vx_mps"] - pvx) + dy * (truth_i["vy_mps"] - pvy)
                    + dz * (-pvz)) / r
        if "range_rate_mps" in tracks:
            rr_track = np.asarray(tracks["range_rate_mps"], float)[rows]
        elif vx is not None:
            tdx, tdy = x - px, y - py
            rt = np.sqrt(tdx ** 2 + tdy ** 2 + dz ** 2)
            rr_track = (tdx * (vx - pvx) + tdy * (vy - pvy) + dz * (-pvz)) / rt
        else:
            rr_track = np.full(n, np.nan)
        out["range_rate_error_mps"] = rr_track - rr_truth
    else:
        out["range_rate_error_mps"] = np.full(n, np.nan)
    return out
