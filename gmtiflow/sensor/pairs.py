"""Step 2 of a sensor chunk: which (dwell, target) pairs to evaluate, and their geometry.

``dwell_resolved``: each active vehicle is paired with the dwells of its revisit whose beam
centre is within ``footprint_beamwidths`` beamwidths of it in sine space (|sin az_t − sin az_b|
≤ footprint · kλ/d_a, target in front of the antenna), its truth evaluated at each dwell's own
time.  Candidate dwells come from every vehicle's position at the scan's middle dwell, widened
by the most it can move in sine space during the scan; the exact test then runs at each
candidate dwell's time.  A vehicle in no footprint gets one look row against the nearest dwell
(smallest sine-space distance).  ``instant_scan``: one pair per active vehicle and revisit, at
the scan's middle instant, booked against the nearest dwell.  :func:`select_pairs` returns the
looks of a chunk ordered by (dwell, vehicle) with their geometry (:class:`Rows`).
"""
from __future__ import annotations

from typing import Dict, NamedTuple, Optional

import numpy as np

from gmtiflow.sensor import antenna, fastnp, geometry, visibility
from gmtiflow.sensor.context import SensorRun
from gmtiflow.sensor.poses import Poses
from gmtiflow.tables import Table


def _xyz(state: Table):
    return tuple(np.asarray(state[k], float) for k in ("x_m", "y_m", "z_m"))


def _vel(state: Table):
    return tuple(np.asarray(state[k], float) for k in ("vx_mps", "vy_mps", "vz_mps"))


def _nearest_beam(u_beam, s):
    """Index of the beam centre nearest to sine coordinates ``s`` (ties to the lower index)."""
    n = len(u_beam)
    if n == 1:
        return np.zeros(len(s), np.int64)
    right = np.clip(_searchsorted_uniform(u_beam, s), 1, n - 1)
    left_closer = np.abs(u_beam[right - 1] - s) <= np.abs(u_beam[right] - s)
    return np.where(left_closer, right - 1, right)


def _searchsorted_uniform(u, s):
    """``np.searchsorted(u, s)`` (side left) for ascending ``u`` of about equal steps (the beams
    in sine space): the position from the step, kept where u[i−1] < s ≤ u[i] holds, searched
    where it does not (uneven steps, NaN)."""
    n = len(u)
    with np.errstate(invalid="ignore"):
        guess = np.ceil((s - u[0]) / (u[-1] - u[0]) * (n - 1))
    pos = np.clip(np.nan_to_num(guess, nan=0.0), 0, n).astype(np.int64)
    lower = np.concatenate(([-np.inf], u))      # u[pos − 1], −inf before the first
    upper = np.concatenate((u, [np.inf]))       # u[pos], +inf after the last
    bad = np.flatnonzero(~((lower[pos] < s) & (s <= upper[pos])))
    if bad.size:
        pos[bad] = np.searchsorted(u, s[bad])
    return pos


def _may_be_active(fleet, time_s, vehicle_id):
    """False where the fleet's activity window (``start_time_s``/``end_time_s``, padded as in
    :func:`gmtiflow.sensor.model._on_the_road`) rules the vehicle out at that time; None when
    the fleet has no windows or every row may be active.  Element-wise: ``time_s`` (n_rev, 1)
    against ``vehicle_id`` (1, n_v) gives the (revisit, vehicle) grid."""
    start = getattr(fleet, "start_time_s", None)
    end = getattr(fleet, "end_time_s", None)
    if start is None or end is None or not len(time_s):
        return None
    pad = 1e-6 * np.maximum(1.0, np.abs(time_s))
    maybe = ((np.asarray(start)[vehicle_id] <= time_s + pad)
             & (np.asarray(end)[vehicle_id] >= time_s - pad))
    return None if maybe.all() else maybe


def _state_at(fleet, time_s, vehicle_id, columns=None) -> Table:
    """``fleet.state_at`` asked only for the rows its activity windows leave open; the others
    are inactive rows (NaN, False, −1), which is what the fleet gives for them.  Only
    ``active`` is read of an inactive row."""
    maybe = _may_be_active(fleet, time_s, vehicle_id)
    if maybe is None:
        return fleet.state_at(time_s, vehicle_id, columns=columns)
    ask = np.flatnonzero(maybe)
    sub = fleet.state_at(time_s[ask], vehicle_id[ask], columns=columns)
    out = {}
    for k, v in sub.items():
        v = np.asarray(v)
        fill = {"f": np.nan, "b": False, "i": -1}.get(v.dtype.kind, 0)
        col = np.full(len(time_s), fill, v.dtype)
        col[ask] = v
        out[k] = col
    return out


def _coarse(run: SensorRun, poses: Poses, vehicle_ids):
    """Every vehicle at one reference dwell per revisit: the middle one (its time, its pose).

    Returns the vehicles' state there, the reference dwells (chunk-local), the vehicle ids,
    activity, slant range and sine coordinate per (revisit, vehicle), revisit-major.  Only
    what the candidate search needs is computed, broadcasting each revisit's pose over its
    vehicles instead of gathering it.
    """
    sched, fleet, n_rev = run.sched, run.fleet, poses.n_rev
    n_d = sched.n_dwells
    n_v = len(vehicle_ids)
    ref = np.arange(n_rev) * n_d + n_d // 2
    d_rep = np.repeat(ref, n_v)
    v_rep = np.tile(vehicle_ids, n_rev)
    st = _state_at(fleet, np.repeat(poses.time_s[ref], n_v), v_rep,    # = time_s[d_rep]
                   columns=_COARSE)
    active = np.asarray(st["active"], bool)
    xyz = [(c if np.all(active) else np.where(active, c, 0.0)).reshape(n_rev, n_v)
           for c in _xyz(st)]
    d, _ = geometry.offsets(tuple(c[ref][:, None] for c in poses.pos), xyz, poses.radius_m,
                            target_frame=False)
    b = [c[ref][:, None] for c in poses.b]
    h = [c[ref][:, None] for c in poses.h]
    lb = d[0] * b[0] + d[1] * b[1] + d[2] * b[2]
    lh = d[0] * h[0] + d[1] * h[1] + d[2] * h[2]
    rng_m = np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).ravel()
    horiz = np.hypot(lb, lh)
    sin_az = fastnp.ratio(lh, horiz)
    # behind the antenna: beyond every beam, on the side it is turned to
    s = np.where(lb > 0, sin_az, np.where(lh >= 0, 2.0, -2.0)).ravel()
    return st, d_rep, v_rep, active, rng_m, s


def _instant_rows(run: SensorRun, poses: Poses, vehicle_ids):
    """``instant_scan``: the (revisit, vehicle) pairs active at the scan's instant, revisit-major
    (what :func:`_coarse` gives at its active rows, computed for those alone: an inactive pair
    has no look, and a fleet with activity windows has most of its rows inactive in a long
    scene).  Returns their state (the columns the sensor reads), reference dwell (chunk-local),
    vehicle id and sine coordinate, and the geometry computed on the way that
    :func:`_pair_geometry` needs again (:class:`_Known`)."""
    sched, fleet, n_rev = run.sched, run.fleet, poses.n_rev
    n_d = sched.n_dwells
    n_v = len(vehicle_ids)
    ref = np.arange(n_rev) * n_d + n_d // 2
    t_ref = poses.time_s[ref]
    # row r of the (revisit, vehicle) grid: revisit r // n_v, vehicle vehicle_ids[r % n_v]
    # (gathered for the rows asked about only, not repeated over the whole grid first)
    maybe = _may_be_active(fleet, t_ref[:, None], np.asarray(vehicle_ids)[None, :])
    if maybe is None:           # every pair asked: the whole grid, repeated
        rev = col = None
        v_rep = np.tile(vehicle_ids, n_rev)
        st = fleet.state_at(np.repeat(t_ref, n_v), v_rep, columns=_STATE)
    else:
        rev, col = np.divmod(np.flatnonzero(maybe.ravel()), n_v)
        st = fleet.state_at(np.take(t_ref, rev), np.take(vehicle_ids, col), columns=_STATE)
    active = np.asarray(st["active"], bool)
    if active.all():
        st = {k: np.asarray(st[k]) for k in _STATE}
    else:
        act = np.flatnonzero(active)
        st = {k: np.take(np.asarray(st[k]), act) for k in _STATE}
        rev, col = np.divmod(act, n_v) if rev is None else (np.take(rev, act),
                                                            np.take(col, act))
    if rev is None:
        d_ref, veh = np.repeat(ref, n_v), v_rep
    else:
        d_ref, veh = np.take(ref, rev), np.take(vehicle_ids, col)
    plat = antenna.take(poses.pos, d_ref)
    offsets = geometry.pair_offsets(plat, _xyz(st), poses.radius_m)
    d = offsets[0]
    b, h = antenna.take(poses.b, d_ref), antenna.take(poses.h, d_ref)
    lb = d[0] * b[0] + d[1] * b[1] + d[2] * b[2]
    lh = d[0] * h[0] + d[1] * h[1] + d[2] * h[2]
    horiz = np.hypot(lb, lh)
    sin_az = fastnp.ratio(lh, horiz)
    # behind the antenna: beyond every beam, on the side it is turned to
    s = np.where(lb > 0, sin_az, np.where(lh >= 0, 2.0, -2.0))
    return st, d_ref, veh, s, _Known(plat, offsets, b, h)


class _Known(NamedTuple):
    """Geometry of pairs already computed at their dwells (:func:`_instant_rows`): the
    platform positions, :func:`geometry.pair_offsets` of the targets (every one active), the
    boresight and scan axes.  :func:`_pair_geometry` takes them instead of computing them
    again (1,000-vehicle fast scene: ~150,000 pairs a chunk)."""

    plat: tuple
    offsets: tuple
    b: tuple
    h: tuple


def _candidate_pairs(run: SensorRun, poses: Poses, vehicle_ids):
    """Candidate (chunk-local dwell, vehicle) pairs, grouped by (revisit, vehicle), dwells
    ascending within a group.  Returns ``(dwell_local, vehicle_id, group)``.

    A vehicle's sine coordinate is taken at the scan's middle dwell; over the scan it moves by
    at most (|v_p| + |v_t|)·Δt / R plus the antenna's rotation (turns), which widens the
    window of candidate beams.  The exact footprint test runs later at each dwell's time.

    Also returns, per group, whether the vehicle is active at the middle dwell (``mid_active``)
    and that dwell (``mid_dwell``), so a vehicle that leaves or appears mid-scan and is inactive
    at all its candidate dwells still gets its one look row (at the middle dwell); and each
    group's first row (``starts``; every group has at least one, so ``group`` numbers them
    0, 1, 2, ... in order) and each candidate's beam position in its scan (``dwell % n_d``).
    """
    cfg, sched, n_rev = run.cfg, run.sched, poses.n_rev
    n_d = sched.n_dwells
    n_v = len(vehicle_ids)
    u_beam = np.sin(sched.beam_scan_rad)
    bw = cfg.beamwidth_sine
    st, d_ref, v_rep, active, rng_m, s = _coarse(run, poses, vehicle_ids)
    # motion margin
    dt = float(np.max(np.abs(sched.time_offset_s - sched.time_offset_s[n_d // 2])))
    vp = np.sqrt(antenna.dot(poses.vel, poses.vel))
    bx, by, bz = (c.reshape(n_rev, n_d) for c in poses.b)
    mid = n_d // 2
    cosang = bx * bx[:, mid:mid + 1] + by * by[:, mid:mid + 1] + bz * bz[:, mid:mid + 1]
    rot = np.arccos(np.clip(cosang, -1.0, 1.0)).max(axis=1)          # per revisit
    vt = _speed(*(st[k] for k in ("vx_mps", "vy_mps", "vz_mps")))
    # per (revisit, vehicle), revisit-major: the revisit's values broadcast, not gathered
    move = ((vp[d_ref[::n_v]][:, None] + vt.reshape(n_rev, n_v)) * dt).ravel() if n_v else vt
    margin = (move / np.maximum(rng_m - move, 1.0)).reshape(n_rev, n_v) + rot[:, None]
    w = (cfg.footprint_beamwidths * bw + (margin + 0.02 * bw)).ravel()
    rev = np.repeat(np.arange(n_rev), n_v)
    mid_active = active
    if not np.all(active):
        # a vehicle inactive at the middle may still be active at one end of the scan
        keep = np.flatnonzero(active | _active_at_ends(run, poses, v_rep, rev))
        s, w, rev, v_rep = (np.take(a, keep) for a in (s, w, rev, v_rep))
        mid_active = np.take(active, keep)
        s = np.where(mid_active, s, 0.0)
        w = np.where(mid_active, w, 2.0)     # unknown position: try every beam
    # beams are uniform in sine space, u_i = u_0 + i Δ: index arithmetic instead of a search
    # (a candidate window one beam too wide costs nothing: the exact test follows)
    if n_d > 1:
        step = u_beam[1] - u_beam[0]
        lo = np.clip(np.ceil((s - w - u_beam[0]) / step - 1e-9), 0, n_d).astype(np.int64)
        hi = np.clip(np.floor((s + w - u_beam[0]) / step + 1e-9) + 1, 0, n_d).astype(np.int64)
    else:
        lo = np.where(np.abs(s - u_beam[0]) <= w, 0, 1)
        hi = np.ones_like(lo)
    none = np.flatnonzero(hi <= lo)
    lo[none] = _nearest_beam(u_beam, s[none])
    count = hi - lo
    count[none] = 1
    total = int(count.sum())
    # per-group values spread over their candidates with np.repeat (x[group], cheaper)
    group = np.repeat(np.arange(len(lo)), count)
    starts = np.cumsum(count) - count
    # candidate i of group g is beam lo[g] + (i − starts[g]): one spread per column
    row = np.arange(total)
    beam = np.repeat(lo - starts, count) + row
    dwell_local = np.repeat(rev * n_d + (lo - starts), count) + row
    return (dwell_local, np.repeat(v_rep, count), group, mid_active, rev * n_d + n_d // 2,
            starts, beam)


def _finite(v):
    """``np.nan_to_num`` of a float array (without its copy and passes when all are finite)."""
    v = np.asarray(v, float)
    return v if np.isfinite(v).all() else np.nan_to_num(v)


def _speed(vx, vy, vz):
    """|v| as hypot(hypot(vx, vy), vz), NaN and ±inf taken as 0 and ±max float.  Where every vz
    is 0 (ground vehicles on flat ground) the outer hypot is skipped: hypot(x, ±0) = |x|
    exactly (C99 F.9.4.3), and hypot costs ~13 ns a value here."""
    horiz = np.hypot(_finite(vx), _finite(vy))
    vz = _finite(vz)
    return horiz if not np.any(vz) else np.hypot(horiz, vz)


def _active_at_ends(run: SensorRun, poses: Poses, v_rep, rev):
    """Whether each (vehicle, revisit) is active at the scan's first or last dwell.  With the
    fleet's activity windows (``start_time_s``/``end_time_s``, padded as in
    :func:`gmtiflow.sensor.model._on_the_road`) only the vehicles whose window reaches that
    instant are asked (``state_at``): most inactive ones have long finished or not started."""
    n_d, fleet = run.sched.n_dwells, run.fleet
    out = np.zeros(len(v_rep), bool)
    for k in (0, n_d - 1):
        t = poses.time_s[rev * n_d + k]
        maybe = _may_be_active(fleet, t, v_rep)
        ask = np.flatnonzero(~out if maybe is None else maybe & ~out)
        if ask.size:
            out[ask] = np.asarray(fleet.state_at(t[ask], v_rep[ask], columns=())["active"],
                                  bool)
    return out


def _nearest_rows(dist, active, starts, groups):
    """The fallback row of each group in ``groups`` (contiguous candidate runs beginning at
    ``starts``, the last one ending with ``dist``): its first active row whose ``dist`` is the
    group's least (over all its rows; none when that is NaN).  Only these groups' rows are
    read, not every candidate's."""
    if groups.size == 0:
        return np.zeros(0, np.int64)
    ends = np.append(starts[1:], len(dist))
    count = ends[groups] - starts[groups]
    offset = np.cumsum(count) - count
    rows = np.repeat(starts[groups] - offset, count) + np.arange(int(count.sum()))
    d = dist[rows]
    least = np.repeat(np.minimum.reduceat(d, offset), count)
    is_min = active[rows] & (d <= least)
    return rows[_first_in_group(np.repeat(np.arange(groups.size), count), is_min)]


def _first_in_group(group, mask):
    """Mask of the first True of ``mask`` in each (sorted, contiguous) group."""
    idx = np.flatnonzero(mask)
    out = np.zeros(len(mask), bool)
    if idx.size == 0:
        return out
    g = group[idx]
    first = np.ones(idx.size, bool)
    first[1:] = g[1:] != g[:-1]
    out[idx[first]] = True
    return out



_STATE = ("active", "x_m", "y_m", "z_m", "vx_mps", "vy_mps", "vz_mps", "heading_rad",
          "invisible")   # the truth columns the sensor reads (fleet.state_at's ``columns``)
_COARSE = _STATE[:7]     # those the candidate search reads (position and velocity)


def _pair_geometry(poses: Poses, dl, st: Table, known: Optional[_Known] = None
                   ) -> Dict[str, np.ndarray]:
    """Geometry of (dwell, target) pairs: the pose of chunk-local dwell ``dl`` and the target
    state ``st`` (inactive targets get a harmless position, never NaN); ``known``: what
    :func:`_instant_rows` computed of it (used when every target is active, as there)."""
    active = np.asarray(st["active"], bool)
    pos_t = _xyz(st)
    vel_t = _vel(st)
    if not np.all(active):
        pos_t = tuple(np.where(active, c, 0.0) for c in pos_t)
        vel_t = tuple(np.where(active, c, 0.0) for c in vel_t)
        known = None
    plat = antenna.take(poses.pos, dl) if known is None else known.plat
    rng_m, los, los_t, d2 = geometry.lines_of_sight(
        plat, pos_t, poses.radius_m, ground_d2=True,
        offsets=None if known is None else known.offsets)
    if d2 is None:      # flat geometry: Δx² + Δy² as the horizon test writes it
        dx, dy = pos_t[0] - plat[0], pos_t[1] - plat[1]
        d2 = dx * dx + dy * dy
    b, h = ((antenna.take(poses.b, dl), antenna.take(poses.h, dl)) if known is None
            else (known.b, known.h))
    az, el, sin_az, lb = antenna.target_angles(los, b, h, antenna.take(poses.u, dl))
    # ṙ − ṙ_MLC: the target's velocity (its own local frame) on the LOS seen there
    own_rr = antenna.dot(geometry.true_velocity(vel_t, pos_t[2], poses.radius_m), los_t)
    vel_p = antenna.take(geometry.true_velocity(poses.vel, poses.pos[2], poses.radius_m), dl)
    # ṙ = (ṙ − ṙ_MLC) + ṙ_MLC with ṙ_MLC = −v_p·ℓ: a + (−b) is a − b in IEEE arithmetic
    rr = own_rr - antenna.dot(vel_p, los)
    return {"active": active, "range_m": rng_m, "los_az": np.arctan2(los[0], los[1]),
            "az": az, "el": el, "sin_az": sin_az, "lb": lb, "own_rr": own_rr,
            "rr": rr, "x_m": pos_t[0], "y_m": pos_t[1], "z_m": pos_t[2], "ground_d2": d2,
            "heading_rad": np.asarray(st["heading_rad"], float),
            "invisible": np.asarray(st["invisible"], bool)}


def select_pairs(run: SensorRun, poses: Poses, vehicle_ids):
    """The looks of a chunk ordered by (dwell, vehicle): ``(dwell_local, vehicle, geometry)``,
    and the number of (dwell, target) pairs evaluated."""
    cfg, sched, fleet = run.cfg, run.sched, run.fleet
    n_d = sched.n_dwells
    u_beam_all = np.sin(sched.beam_scan_rad)
    if sched.instant:
        st, d_ref, veh, s, known = _instant_rows(run, poses, vehicle_ids)
        dl = d_ref - n_d // 2 + _nearest_beam(u_beam_all, s)
        n_eval = len(dl)
        # all dwells of an instant scan share one time and pose: the reference's geometry holds
        geo = _pair_geometry(poses, d_ref, st, known)
        geo["in_fp"] = geo["lb"] > 0        # the beam is on the target, if it is in front
        sel = np.arange(len(dl))
    else:
        dl, veh, group, mid_active, mid_dwell, starts, beam = _candidate_pairs(run, poses,
                                                                               vehicle_ids)
        n_eval = len(dl)
        geo = _pair_geometry(poses, dl, fleet.state_at(np.take(poses.time_s, dl), veh,
                                                       columns=_STATE))
        active = geo["active"]
        sel = np.zeros(0, np.int64)
        extra = False
        if group.size:
            # groups are contiguous runs of (revisit, vehicle); a vehicle in no footprint keeps
            # one row: its first candidate of least sine-space distance (the nearest dwell)
            gidx = group                # groups are numbered 0, 1, 2, ... in row order
            all_active = active.all()
            g_active = (np.ones(len(starts), bool) if all_active else
                        np.logical_or.reduceat(active, starts))
            # active at the middle dwell but at none of its candidate dwells (it left or
            # appeared mid-scan): one more candidate, the middle dwell itself
            lost = (np.zeros(0, np.int64) if all_active else
                    np.flatnonzero(~g_active & mid_active[group[starts]]))
            if lost.size:
                extra = True
                g_lost = group[starts[lost]]
                dl_x, veh_x = mid_dwell[g_lost], veh[starts[lost]]
                geo_x = _pair_geometry(poses, dl_x, fleet.state_at(poses.time_s[dl_x], veh_x,
                                                                   columns=_STATE))
                n_eval += lost.size
                geo = {k: np.concatenate([v, geo_x[k]]) for k, v in geo.items()}
                dl, veh = np.concatenate([dl, dl_x]), np.concatenate([veh, veh_x])
                gidx = np.concatenate([gidx, lost])
                beam = np.concatenate([beam, np.full(lost.size, n_d // 2, beam.dtype)])
                active = geo["active"]
                g_active[lost] = active[-lost.size:]
            dist = np.where((geo["lb"] > 0) & active,
                            np.abs(geo["sin_az"] - np.take(u_beam_all, beam)), 1e300)
            in_fp = dist <= cfg.footprint_beamwidths * cfg.beamwidth_sine * (1 + 1e-12)
            if extra:     # the extra rows sit after every group: unbuffered group reductions
                any_fp = np.zeros(len(starts), bool)
                np.logical_or.at(any_fp, gidx, in_fp)
                gmin = np.full(len(starts), np.inf)
                np.minimum.at(gmin, gidx, dist)
                is_min = active & (dist <= gmin[gidx])
                first = np.zeros(len(dl), bool)
                cand = np.flatnonzero(is_min)
                _, first_of = np.unique(gidx[cand], return_index=True)
                first[cand[first_of]] = True
                fallback = ~any_fp[gidx] & g_active[gidx] & first
                sel = np.flatnonzero((in_fp & active) | fallback)
            else:
                any_fp = np.logical_or.reduceat(in_fp, starts)
                keep = in_fp & active
                keep[_nearest_rows(dist, active, starts, np.flatnonzero(~any_fp & g_active))] \
                    = True
                sel = np.flatnonzero(keep)
            geo["in_fp"] = in_fp
            geo["beam_offset_sine"] = dist     # |u_t − u_b| where in front and active
        else:
            geo["in_fp"] = np.zeros(0, bool)
            geo["beam_offset_sine"] = np.zeros(0)
    # footprint and field of view per candidate: the looks then gather one flag, not az and el
    geo["fov"] = geo["in_fp"] & visibility.in_field_of_view(cfg, geo["az"], geo["el"],
                                                             geo["range_m"])
    # candidates come grouped by (revisit, vehicle), dwells ascending: a stable sort on the
    # dwell orders rows by (dwell, vehicle); int16 keys sort by radix
    if sched.instant or not extra:
        key = dl[sel]
        key = key.astype(np.int16) if len(poses.time_s) < 32_000 else key
        sel = sel[np.argsort(key, kind="stable")]
    else:     # the extra middle-dwell rows come last: sort on (dwell, vehicle) explicitly
        sel = sel[np.lexsort((veh[sel], dl[sel]))]
    return np.take(dl, sel), np.take(veh, sel), Rows(geo, sel), n_eval


class Rows:
    """The selected rows of candidate-level columns, gathered only when (and where) used."""

    def __init__(self, columns: Dict[str, np.ndarray], sel: np.ndarray):
        self.columns, self.sel, self.cache = columns, sel, {}
        self._at = (None, None)       # the last ``index`` of :meth:`at` and sel[index]

    def __getitem__(self, name: str) -> np.ndarray:
        if name not in self.cache:
            self.cache[name] = np.take(self.columns[name], self.sel)
        return self.cache[name]

    def at(self, name: str, index: np.ndarray) -> np.ndarray:
        """Column ``name`` at selected rows ``index`` (an integer array; without gathering the
        other rows).  Successive calls with the same ``index`` object compose it once."""
        if name in self.cache:
            return np.take(self.cache[name], index)
        if self._at[0] is not index:
            self._at = (index, np.take(self.sel, index))
        return np.take(self.columns[name], self._at[1])
