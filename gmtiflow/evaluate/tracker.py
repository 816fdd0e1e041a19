"""Baseline NN-Kalman tracker: the stage ``track(cfg, detections, dwells, seed) -> /tracks``.

A baseline, honest and simple, so every run shows the whole chain; not the product.

Per dwell, in time order (a Python loop over dwells; everything inside is batched numpy):

1. **Coverage.**  A track is *covered* by a dwell when its constant-velocity extrapolated
   position lies inside the dwell's footprint: world azimuth from the platform within
   ``beam_az_rad ± angle_half_extent_rad`` and, when the scene origin is given, slant range within
   ``range_half_extent_m`` of the slant range to the dwell-area centre (``area_lat_deg
   area_lon_deg``); both widened by ``footprint_margin_m``.  Without these /dwells columns every
   dwell covers every track.  Only covered tracks are gated against a dwell's detections.
2. **Predict** the covered tracks from their last update to the dwell time (CV model,
   :mod:`gmtiflow.evaluate.kalman`).
3. **Gate and assign.**  Squared Mahalanobis distance of every (track, detection) innovation,
   chi-square gate with ``gate_probability`` (2 degrees of freedom, 3 with range rate); global
   nearest neighbour with :func:`~gmtiflow.evaluate.assignment.gated_assignment`, first for the
   confirmed tracks, then for the tentative tracks on the detections left over.
4. **Update** assigned tracks (Kalman on position, EKF on range rate; the range-rate innovation
   is wrapped into ± ``wrap_velocity_mps`` when the detection carries a finite one).
5. **Confirm / delete**, counted in *revisits* (``revisit_id``; each dwell is its own revisit
   when /dwells has no such column): a revisit *covers* a track when any of its dwells covers
   it, and *hits* it when any of them updates it — so overlapping beams of one scan neither
   double-count a hit nor turn the neighbouring beam's look into a miss.  A tentative track is
   confirmed at ``confirm_m`` hits within its first ``confirm_n`` covering revisits and deleted
   when it has not made it by then; a confirmed track is deleted after ``delete_misses``
   consecutive covering revisits without a hit (a track outside every beam of a revisit is not
   missed).  Any track not updated for ``max_coast_s`` is deleted too.
6. **Initiate** a tentative track at every detection left unassigned: single-point initiation,
   position and covariance from the detection, velocity prior 0 ± ``init_speed_sigma_mps`` per
   axis, refined at once by the detection's range rate when ``use_range_rate``.

Output: one /tracks row per (track, covering dwell), updated or coasted (a coasted row is the
prediction; it is not stored back, so the next update predicts from the last measurement).
Without footprints: a row per update, and a coasted row at the end of a revisit that missed the
track.  A deleted track has no row at the dwell that deleted it.  ``range_rate_mps`` is the range
rate the track state implies, seen from the dwell's platform.  Detections flagged
``implausible`` (a folded report below the surface, as the processor flags it) are not used.  Track ids count from
0 in order of creation.  The tracker draws no random numbers; ``seed`` is accepted for the stage
interface only, and the output is deterministic.
"""
from __future__ import annotations

import dataclasses
from typing import Mapping, Optional

import numpy as np

from gmtiflow import frames
from gmtiflow.evaluate import kalman
from gmtiflow.evaluate.assignment import sparse_gated_assignment
from gmtiflow.evaluate.config import TrackerConfig
from gmtiflow.evaluate.protocol import (Batch, SceneInfo, _Prepared, load_tracker,
                                        run_tracker)
from gmtiflow.evaluate.tracks import TRACK_COLUMNS, empty_tracks  # noqa: F401 (re-exported)
from gmtiflow.tables import Table


#: Up to this many (covered track, detection) pairs a dwell gates them all at once (dense);
#: above, candidates come from a k-d tree (:func:`gmtiflow.evaluate.kalman.gated_pairs`).  Both
#: give the same pairs and values; the threshold only trades fixed cost for scaling.
DENSE_PAIRS = 4096


def _column(det, name, n, default):
    """Column ``name`` of the (one dwell's) detections, non-finite values and absence -> default."""
    if name in det:
        col = np.asarray(det[name], float)
        return np.where(np.isfinite(col), col, default)
    return np.full(n, float(default))


def _usable(det) -> np.ndarray:
    """Which detections the tracker uses: finite positions, not flagged ``implausible``."""
    usable = np.ones(len(det["dwell_id"]), bool)
    if len(usable):
        if "implausible" in det:
            usable &= ~np.asarray(det["implausible"], bool)
        for c in ("x_m", "y_m"):
            usable &= np.isfinite(np.asarray(det[c], float))
    return usable


#: Columns :func:`track` adds to the baseline's prepared /detections (the batches slice them as
#: they slice the others): the usable mask and :func:`_measurements` of every usable plot.
_USABLE, _ZMEAS, _R, _ZDET, _WRAP = ("_tracker_usable", "_tracker_zmeas", "_tracker_R",
                                     "_tracker_zdet", "_tracker_wrap")


def _add_measurements(det, dw, cfg: TrackerConfig) -> None:
    """Add the :data:`_USABLE` ... :data:`_WRAP` columns to ``det``, the detections of ``dw``
    grouped by dwell in its order (``dw["n_detections"]`` rows each, as
    :class:`~gmtiflow.evaluate.protocol._Prepared` holds them).

    One pass over the run's plots instead of one per dwell (4,602 calls, ~0.2 s of the
    1,000-vehicle run): the same element-wise numpy operations on the same values, each plot
    seen from its own dwell's platform, so the values are those :func:`_measurements` gives per
    dwell bit for bit (``tests/evaluate/test_tracker.py``).  Unusable rows hold NaN."""
    n = len(det["dwell_id"])
    usable = _usable(det)
    idx = np.flatnonzero(usable)
    at = np.repeat(np.arange(len(dw["n_detections"])), dw["n_detections"])[idx]
    plat = tuple(np.asarray(dw[c], float)[at] for c in ("platform_x_m", "platform_y_m",
                                                       "platform_z_m"))
    zmeas, R, zdet, wrap = _measurements(det, idx, plat, cfg)
    det[_USABLE] = usable
    for name, got in ((_ZMEAS, zmeas), (_R, R), (_ZDET, zdet), (_WRAP, wrap)):
        if got is not None:
            full = np.full((n,) + got.shape[1:], np.nan)
            full[idx] = got
            det[name] = full


class _Tracks:
    """Live track state as parallel arrays (rows = live tracks)."""

    def __init__(self) -> None:
        self.id = np.zeros(0, np.int64)
        self.x = np.zeros((0, 4))
        self.P = np.zeros((0, 4, 4))
        self.t = np.zeros(0)
        self.z = np.zeros(0)
        self.hits = np.zeros(0, np.int64)
        self.covered = np.zeros(0, np.int64)
        self.misses = np.zeros(0, np.int64)
        self.confirmed = np.zeros(0, bool)
        self.rev_covered = np.zeros(0, bool)
        self.rev_hit = np.zeros(0, bool)

    _FIELDS = ("id", "x", "P", "t", "z", "hits", "covered", "misses", "confirmed", "rev_covered",
               "rev_hit")

    def keep(self, mask) -> None:
        for f in self._FIELDS:
            setattr(self, f, getattr(self, f)[mask])

    def append(self, **new) -> None:
        for f in self._FIELDS:
            setattr(self, f, np.concatenate([getattr(self, f), new[f]]))


def _covered(dw, k: int, pos: np.ndarray, z: np.ndarray, plat: np.ndarray, margin_m: float):
    """Which positions (n, 2) the footprint of the batch's dwell ``k`` covers."""
    dx, dy, dz = pos[:, 0] - plat[0], pos[:, 1] - plat[1], z - plat[2]
    ground = np.hypot(dx, dy)
    az = frames.heading_rad(dx, dy)
    off = np.abs(frames.wrap_pi(az - float(dw["beam_az_rad"][k])))
    half = float(dw["angle_half_extent_rad"][k])
    ok = np.ones(len(pos), bool)
    if np.isfinite(half):
        ok &= off <= half + margin_m / np.maximum(ground, 1.0)
    if "area_range_m" in dw and "range_half_extent_m" in dw:
        centre, half_r = float(dw["area_range_m"][k]), float(dw["range_half_extent_m"][k])
        if np.isfinite(centre) and np.isfinite(half_r):
            slant = np.sqrt(ground ** 2 + dz ** 2)
            ok &= np.abs(slant - centre) <= half_r + margin_m
    return ok


def _measurements(det, idx, plat, cfg: TrackerConfig):
    """Position (and range-rate) measurements of detections ``idx`` and their covariances;
    ``plat`` the platform position, one (3,) or three arrays, one value per detection."""
    n = len(idx)
    x = np.asarray(det["x_m"], float)[idx]
    y = np.asarray(det["y_m"], float)[idx]
    z = _column(det, "z_m", len(det["x_m"]), 0.0)[idx]
    dx, dy, dz = x - plat[0], y - plat[1], z - plat[2]
    ground = np.hypot(dx, dy)
    slant = np.sqrt(ground ** 2 + dz ** 2)
    los_az = frames.heading_rad(dx, dy)
    nall = len(det["x_m"])
    s_r = _column(det, "sigma_range_m", nall, cfg.default_sigma_range_m)[idx]
    s_az = _column(det, "sigma_azimuth_rad", nall, np.radians(cfg.default_sigma_azimuth_deg))[idx]
    s_r = np.maximum(s_r, 1e-3)                 # a zero σ would make the covariance singular
    s_az = np.maximum(s_az, 1e-9)
    along = s_r * slant / np.maximum(ground, 0.1 * slant)
    cross = slant * s_az
    R_pos = kalman.position_covariance(los_az, along, cross)
    use_rr = cfg.use_range_rate and "range_rate_mps" in det
    if not use_rr:
        return np.stack([x, y], axis=1), R_pos, z, None
    rr = np.asarray(det["range_rate_mps"], float)[idx]
    s_rr = np.maximum(_column(det, "sigma_range_rate_mps", nall,
                              cfg.default_sigma_range_rate_mps)[idx], 1e-4)
    # A detection without a range rate still updates the position: its range-rate row gets a
    # value of 0 with a σ so large that it carries no information.
    no_rr = ~np.isfinite(rr)
    rr = np.where(no_rr, 0.0, rr)
    s_rr = np.where(no_rr, 1e6, s_rr)
    wrap = _column(det, "wrap_velocity_mps", nall, np.nan)[idx]
    R = np.zeros((n, 3, 3))
    R[:, :2, :2] = R_pos
    R[:, 2, 2] = s_rr ** 2
    return np.stack([x, y, rr], axis=1), R, z, wrap


def _model(x: np.ndarray, z: np.ndarray, plat_pos, plat_vel, use_rr: bool):
    """Linearised measurement model ``h`` (n, m) and ``H`` (n, m, 4) at states ``x``."""
    n = len(x)
    m = 3 if use_rr else 2
    H = np.zeros((n, m, 4))
    H[:, 0, 0] = 1.0
    H[:, 1, 1] = 1.0
    h = np.zeros((n, m))
    h[:, :2] = x[:, :2]
    if use_rr:
        h[:, 2], H[:, 2, :] = kalman.predicted_range_rate(x, z, plat_pos, plat_vel)
    return h, H


class NNKalmanTracker:
    """The baseline as a tracker of the protocol (:mod:`gmtiflow.evaluate.protocol`).

    ``update`` runs steps 1–6 of the module docstring for each dwell of the batch and returns
    that batch's /tracks rows; per-dwell and per-revisit batches give the same tracks.
    """

    def __init__(self, cfg: Optional[TrackerConfig] = None, **overrides) -> None:
        cfg = cfg if cfg is not None else TrackerConfig()
        if overrides:
            cfg = dataclasses.replace(cfg, **overrides)
        self.cfg = cfg
        self._gate = {m: chi2_quantile(cfg.gate_probability, m) for m in (2, 3)}
        self.reset(SceneInfo())

    def reset(self, scene: SceneInfo) -> None:
        self._tr = _Tracks()
        self._next_id = 0

    def finish(self) -> None:
        return None

    def update(self, batch: Batch) -> Optional[Table]:
        dw, det = batch.dwells, batch.detections
        if not len(dw["dwell_id"]):
            return None
        has_fp = "beam_az_rad" in dw and "angle_half_extent_rad" in dw
        usable = det[_USABLE] if _USABLE in det else _usable(det)
        out = []
        one = len(dw["dwell_id"]) == 1          # per-dwell batches: the batch is the dwell
        for k, rows in batch.dwell_slices():
            idx = np.flatnonzero(usable[rows])
            sub = det if one or not len(idx) else {name: col[rows] for name, col in det.items()}
            self._dwell(dw, k, sub, idx, has_fp, out)
        if not out:
            return None
        if len(out) == 1:
            return out[0]
        return {name: np.concatenate([o[name] for o in out]) for name in TRACK_COLUMNS}

    def _dwell(self, dw, k: int, det, didx, has_fp: bool, out: list) -> None:
        cfg, tr = self.cfg, self._tr
        if len(tr.id) == 0 and len(didx) == 0:      # no track, no detection: nothing to do
            return
        use_rr = cfg.use_range_rate and "range_rate_mps" in det
        gate = self._gate[3 if use_rr else 2]
        init_var_v = cfg.init_speed_sigma_mps ** 2
        t = float(dw["time_s"][k])
        plat_pos = np.array([dw["platform_x_m"][k], dw["platform_y_m"][k],
                             dw["platform_z_m"][k]], float)
        plat_vel = np.array([dw["platform_vx_mps"][k], dw["platform_vy_mps"][k],
                             dw["platform_vz_mps"][k]], float)
        n_tr = len(tr.id)
        dt = t - tr.t
        pos_guess = kalman.extrapolate_position(tr.x, dt)
        if has_fp:
            cov = _covered(dw, k, pos_guess, tr.z, plat_pos, cfg.footprint_margin_m)
        else:
            cov = np.ones(n_tr, bool)
        ci = np.flatnonzero(cov)
        if len(ci) == 0 and len(didx) == 0:     # nothing to predict, gate or start here
            dead, _ = self._bookkeeping(dw, k, t, ci, ci.astype(bool))
            if dead.any():
                tr.keep(~dead)
            return
        xp, Pp = kalman.cv_predict(tr.x[ci], tr.P[ci], dt[ci], cfg.accel_sigma_mps2,
                                  cfg.process_noise)
        assigned_track = np.full(len(ci), -1, np.int64)       # detection slot per covered track
        det_taken = np.zeros(len(didx), bool)
        if len(didx):
            if _ZMEAS in det:               # computed once for the run (track())
                zmeas, R, zdet = det[_ZMEAS][didx], det[_R][didx], det[_ZDET][didx]
                wrap = det[_WRAP][didx] if use_rr else None
            else:
                zmeas, R, zdet, wrap = _measurements(det, didx, plat_pos, cfg)
        if len(didx) and len(ci):
            h, H = _model(xp, tr.z[ci], plat_pos, plat_vel, use_rr)
            HPHt = H @ Pp @ np.transpose(H, (0, 2, 1))
            if len(ci) * len(didx) <= DENSE_PAIRS:      # small: every pair's pre-test at once
                ti, di, nu, d2 = kalman.dense_gated_pairs(HPHt, zmeas, R, h, wrap, gate)
            else:                                        # large: k-d tree candidates
                ti, di, nu, d2 = kalman.gated_pairs(xp[:, :2], HPHt, zmeas, R, h, wrap, gate)
            for group in (tr.confirmed[ci], ~tr.confirmed[ci]):
                sel = group[ti] & ~det_taken[di]
                r, c = sparse_gated_assignment(ti[sel], di[sel], d2[sel], gate)
                assigned_track[r] = c
                det_taken[c] = True
            a = np.flatnonzero(assigned_track >= 0)
            if len(a):
                j = assigned_track[a]
                at = np.searchsorted(ti * len(didx) + di, a * len(didx) + j)   # pairs are sorted
                xu, Pu = kalman.kalman_update(xp[a], Pp[a], H[a], nu[at], HPHt[a] + R[j], R[j])
                gi = ci[a]
                tr.x[gi], tr.P[gi], tr.t[gi], tr.z[gi] = xu, Pu, t, zdet[j]
                xp[a], Pp[a] = xu, Pu
        hit = assigned_track >= 0

        # Initiation from the detections no track took (before the bookkeeping, so that a track
        # started in a revisit's last dwell is counted in that revisit).
        free = np.flatnonzero(~det_taken)
        nf = len(free)
        if nf:
            x0 = np.zeros((nf, 4))
            x0[:, :2] = zmeas[free, :2]
            P0 = np.zeros((nf, 4, 4))
            P0[:, :2, :2] = R[free, :2, :2]
            P0[:, 2, 2] = P0[:, 3, 3] = init_var_v
            if use_rr:
                h, H = _model(x0, zdet[free], plat_pos, plat_vel, True)
                H1, h1 = H[:, 2:3, :], h[:, 2:3]
                nu1 = kalman.wrap_symmetric(zmeas[free, 2:3] - h1, wrap[free, None])
                S1 = H1 @ P0 @ np.transpose(H1, (0, 2, 1)) + R[free, 2:3, 2:3]
                x0, P0 = kalman.kalman_update(x0, P0, H1, nu1, S1, R[free, 2:3, 2:3])
            ids = self._next_id + np.arange(nf, dtype=np.int64)
            self._next_id += nf
            zeros = np.zeros(nf, np.int64)
            tr.append(id=ids, x=x0, P=P0, t=np.full(nf, t), z=zdet[free], hits=zeros,
                      covered=zeros, misses=zeros, confirmed=np.full(nf, cfg.confirm_m <= 1),
                      rev_covered=np.ones(nf, bool), rev_hit=np.ones(nf, bool))

        dead, missed_rev = self._bookkeeping(dw, k, t, ci, hit)

        # Rows: covered tracks (updated or coasted) with footprints; without, the updated tracks
        # and, at a revisit's end, the ones it missed.  New tracks: their first row.
        if has_fp:
            row_sel = np.ones(len(ci), bool)
        else:
            row_sel = hit | np.isin(ci, missed_rev)
        row_sel &= ~dead[ci]
        rows_i = ci[row_sel]
        if nf:          # the covered tracks' rows, then the new tracks' first rows
            new = n_tr + np.arange(nf)
            new = new[~dead[new]]
            if len(rows_i):
                both = np.concatenate([rows_i, new])
                out.append(_rows(tr.id[both], t, np.concatenate([xp[row_sel], tr.x[new]]),
                                 np.concatenate([Pp[row_sel], tr.P[new]]), tr.z[both],
                                 plat_pos, plat_vel, tr.confirmed[both]))
            elif len(new):
                out.append(_rows(tr.id[new], t, tr.x[new], tr.P[new], tr.z[new], plat_pos,
                                 plat_vel, tr.confirmed[new]))
        elif len(rows_i):
            out.append(_rows(tr.id[rows_i], t, xp[row_sel], Pp[row_sel], tr.z[rows_i], plat_pos,
                             plat_vel, tr.confirmed[rows_i]))
        if dead.any():
            tr.keep(~dead)

    def _bookkeeping(self, dw, k: int, t: float, ci: np.ndarray, hit: np.ndarray):
        """Per revisit: a revisit covers a track when one of its dwells does (every dwell,
        without footprints) and hits it when one of them updates it; hits, covered revisits and
        consecutive misses are counted at the revisit's last dwell.  Returns the tracks to delete
        (a mask; the caller deletes them after writing rows) and those the ending revisit missed
        (indices)."""
        cfg, tr = self.cfg, self._tr
        tr.rev_covered[ci] = True
        tr.rev_hit[ci[hit]] = True
        dead = (t - tr.t) > cfg.max_coast_s
        missed_rev = np.zeros(0, np.int64)
        if dw["revisit_end"][k]:
            counted = np.flatnonzero(tr.rev_covered)
            got = tr.rev_hit[counted]
            tr.covered[counted] += 1
            tr.hits[counted[got]] += 1
            tr.misses[counted[got]] = 0
            tr.misses[counted[~got]] += 1
            tr.confirmed |= tr.hits >= cfg.confirm_m
            c_conf = tr.confirmed[counted]
            dead[counted] |= ((c_conf & (tr.misses[counted] >= cfg.delete_misses))
                              | (~c_conf & (tr.covered[counted] >= cfg.confirm_n)))
            missed_rev = counted[~got]
            tr.rev_covered[:] = False
            tr.rev_hit[:] = False
        return dead, missed_rev


def chi2_quantile(probability: float, dof: int) -> float:
    """The χ² quantile ``scipy.stats.chi2.ppf(probability, dof)`` (the same value: that is
    how it computes it) without importing scipy.stats (~0.5 s)."""
    from scipy.special import gammaincinv
    return float(2 * gammaincinv(dof / 2, probability))


def make_tracker(cfg: TrackerConfig):
    """The tracker ``cfg`` names: the baseline, or ``cfg.target`` built with ``cfg.params``."""
    if cfg.target:
        return load_tracker(cfg.target, cfg.params)
    return NNKalmanTracker(cfg)


def track(cfg: TrackerConfig, detections: Mapping[str, np.ndarray],
          dwells: Mapping[str, np.ndarray], seed: int = 0, *,
          origin: Optional[frames.Origin] = None, epoch_utc: Optional[str] = None,
          duration_s: Optional[float] = None) -> Table:
    """The tracker stage: run the configured tracker over every dwell; returns /tracks.

    The baseline (``cfg.target`` empty) or the user's tracker (:func:`make_tracker`) is fed the
    blind batches of :func:`gmtiflow.evaluate.protocol.batches` (one per dwell, or per revisit
    with ``cfg.per``).  ``origin`` (the scene's geodetic origin) enables the slant-range test
    of dwell footprints; without it only the azimuth extent is used.  ``seed`` is handed to the
    tracker in its :class:`~gmtiflow.evaluate.protocol.SceneInfo` (the baseline draws no
    random numbers).
    """
    if not cfg.enabled:
        return empty_tracks()
    tracker = make_tracker(cfg)
    prepared = _Prepared(detections, dwells, origin, cfg.per)
    if isinstance(tracker, NNKalmanTracker):
        _add_measurements(prepared.detections, prepared.dwells, tracker.cfg)
    scene = SceneInfo(origin=origin, epoch_utc=epoch_utc, duration_s=duration_s,
                      n_dwells=prepared.n_dwells, n_batches=len(prepared),
                      sensor_ids=prepared.sensor_ids, per=cfg.per, seed=int(seed))
    table = run_tracker(tracker, prepared, scene, origin)
    return empty_tracks() if table is None else table


def _rows(ids, t, x, P, z, plat_pos, plat_vel, confirmed) -> Table:
    rr, _ = kalman.predicted_range_rate(x, z, plat_pos, plat_vel)
    return {"track_id": np.asarray(ids, np.int64), "time_s": np.full(len(ids), float(t)),
            "x_m": x[:, 0].copy(), "y_m": x[:, 1].copy(), "vx_mps": x[:, 2].copy(),
            "vy_mps": x[:, 3].copy(), "cov_xx_m2": P[:, 0, 0].copy(),
            "cov_xy_m2": P[:, 0, 1].copy(), "cov_yy_m2": P[:, 1, 1].copy(),
            "range_rate_mps": rr, "confirmed": np.asarray(confirmed, bool).copy()}
