"""The truth of a built fleet: every vehicle's state at any instant, and ``/truth`` tables.

:class:`Fleet` holds the routes, the speed profiles (:mod:`.motion`, stored per trip) and the
position noise (:mod:`.wander`) that :func:`gmtiflow.scene.vehicles.build_fleet` produced, and
evaluates them exactly at any instant (``state_at``, vectorised over (time, vehicle) pairs).
"""
from __future__ import annotations

import math
from typing import Iterator, List

import numpy as np

from gmtiflow import frames
from gmtiflow.scene import wander as wander_mod
from gmtiflow.tables import Table


#: Rows per block of :meth:`Fleet.state_at`: the ~100 temporaries of a block (16,384 float64:
#: 128 kB each, (3, n) ones 384 kB) stay in the L2 cache and, with glibc's default malloc
#: settings (a program using gmtiflow as a library), in reused memory instead of fresh pages:
#: then a quarter less CPU for the /truth of the fidelity_tradeoff scenes than whole
#: 500,000-row requests (2026-11-25); with the gmtiflow command's settings
#: (:mod:`gmtiflow.allocator`) about the same time, and bounded temporaries either way.
_BLOCK_ROWS = 16_384


def _equal_blocks(n: int, most: int) -> List[slice]:
    """``n`` rows as consecutive slices of equal size (the last maybe shorter), each at most
    ``most`` rows, as few as that allows (none for no rows)."""
    if n <= 0:
        return []
    size = -(-n // -(-n // most))
    return [slice(a, a + size) for a in range(0, n, size)]


# --------------------------------------------------------------------------------------------
class Fleet:
    """All vehicles of a scene; truth at any instant (``state_at``) and ``/truth`` tables."""

    def __init__(self, vehicles, routes, prof, wander, t0, horizon_s, on, off, roadmap):
        self._veh = vehicles
        self._routes = routes
        self.routes = [routes[v.route] for v in vehicles]
        self.profiles = prof
        self._w_knots, self._w_off, self._w_t0, self._w_h = wander
        self._w_knots_t = np.ascontiguousarray(np.asarray(self._w_knots, float).T)
        self.roadmap = roadmap
        n = len(vehicles)
        self._profile = np.asarray([v.profile for v in vehicles], dtype=np.int64)
        self._route = np.asarray([v.route for v in vehicles], dtype=np.int64)
        self._offset = np.asarray([v.offset_m for v in vehicles], dtype=float)
        self._t0 = t0[self._profile] if n else np.zeros(0)
        self._horizon = horizon_s[self._profile] if n else np.zeros(0)
        self._on, self._off = on, off
        #: Time each vehicle appears and reaches its end (inf: not within the simulated time).
        self.start_time_s = self._t0 + on
        self.end_time_s = self._t0 + off
        self.vehicles: Table = {
            "vehicle_id": np.arange(n, dtype=np.int64),
            "name": np.asarray([v.name for v in vehicles], dtype=str),
            "convoy_id": np.asarray([v.convoy_id for v in vehicles], dtype=np.int64),
            "vehicle_type": np.asarray([v.type for v in vehicles], dtype=str),
            "start_time_s": self.start_time_s.copy(),
            "route_length_m": np.asarray([routes[v.route].length_m for v in vehicles], float),
            "off_road": np.asarray([v.off_road for v in vehicles], dtype=bool),
        }
        # Flat route arrays for vectorised look-ups: key = s + route * span is sorted.
        self._span = float(2.0 ** np.ceil(np.log2(max([r.length_m for r in routes] + [1.0])
                                                  * 2.0 + 2.0)))
        self._vx_off = np.concatenate([[0], np.cumsum([len(r.s_m) for r in routes],
                                                      dtype=np.int64)]).astype(np.int64)
        self._vx_xyz = np.concatenate([r.xyz_m for r in routes]) if routes else np.zeros((0, 3))
        self._vx_xyz_t = np.ascontiguousarray(self._vx_xyz.T)
        self._vx_s = np.concatenate([r.s_m for r in routes]) if routes else np.zeros(0)
        # Per vertex, the edge id and invisibility of the segment it starts (a route's last
        # vertex: -1 and False), placed at once instead of padding route by route.
        starts = np.ones(len(self._vx_s), bool)
        starts[self._vx_off[1:] - 1] = False
        self._seg_edge = np.full(len(self._vx_s), -1, np.int64)
        self._seg_inv = np.zeros(len(self._vx_s), bool)
        if routes:
            self._seg_edge[starts] = np.concatenate([r.edge_id for r in routes])
            self._seg_inv[starts] = np.concatenate([r.invisible for r in routes])
        route_of_vx = np.repeat(np.arange(len(routes)), np.diff(self._vx_off))
        self._vx_key = self._vx_s + route_of_vx * self._span
        # Per vehicle, from its route: the key offset (route * span), the first and the last
        # segment's vertex, the route's length (m); and whether it wanders (has knots).
        self._veh_key0 = self._route * self._span
        self._veh_lo = self._vx_off[self._route]
        self._veh_hi = self._vx_off[self._route + 1] - 2
        self._veh_len = self._vx_s[self._vx_off[self._route + 1] - 1]
        self._veh_wanders = self._w_off[1:] > self._w_off[:-1]
        # Road-frame heading per segment (indexed by its first vertex) and the corner blend
        # (half-width, turn) per vertex, for the wander's smoothly turning frame.
        self._seg_psi, self._vx_blend, self._vx_turn = _road_frames(
            routes, self._vx_xyz, self._vx_s, self._vx_off)
        # Per vertex j, of the segment j -> j + 1 it starts (a route's last vertex: unused):
        # the displacement (3, n) m, the length (m), the truth heading of its direction (rad)
        # and the sine and cosine of its road-frame heading, so that state_at gathers them
        # instead of computing them row by row (the same operations, so the same values).
        nv = len(self._vx_s)
        self._seg_d_t = np.zeros((3, nv))
        self._seg_d_t[:, :-1] = self._vx_xyz_t[:, 1:] - self._vx_xyz_t[:, :-1]
        self._seg_len = np.zeros(nv)
        self._seg_len[:-1] = self._vx_s[1:] - self._vx_s[:-1]
        safe = np.where(self._seg_len > 0, self._seg_len, 1.0)
        self._seg_heading = frames.heading_rad(self._seg_d_t[0] / safe, self._seg_d_t[1] / safe)
        self._seg_sin, self._seg_cos = np.sin(self._seg_psi), np.cos(self._seg_psi)

    @property
    def n_vehicles(self) -> int:
        return len(self._veh)

    def state_at(self, time_s, vehicle_id, columns=None) -> Table:
        """Truth of ``vehicle_id[i]`` at ``time_s[i]`` (broadcast): /truth columns + ``active``.

        ``active`` is False before the vehicle appears, from its arrival on, and after the
        simulated horizon (the profile grid covers at least ``duration_s``); inactive rows hold
        NaN, -1 ids, mode 255 and invisible False.

        ``columns``: only these /truth columns (and ``active``, always), the work for the
        others skipped (the sensor reads 8 of the 18); each one's values are those of the
        whole call.  None: all of them.
        """
        t, vid = np.broadcast_arrays(np.asarray(time_s, dtype=float),
                                     np.asarray(vehicle_id, dtype=np.int64))
        shape = t.shape
        out = self._blocks(t.ravel(), vid.ravel(), _columns(columns))
        return {k: c.reshape(shape) for k, c in out.items()}

    def _blocks(self, t, vid, cols, tau=None) -> Table:
        """:meth:`_state_flat` of flat arrays in cache-sized blocks of equal size (every row's
        values are its own); ``tau``: see there."""
        n = t.size
        if n <= _BLOCK_ROWS:
            return self._state_flat(t, vid, cols, tau)
        parts = [self._state_flat(t[sl], vid[sl], cols, None if tau is None else tau[sl])
                 for sl in _equal_blocks(n, _BLOCK_ROWS)]
        return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}

    def _state_flat(self, t, vid, cols=None, tau=None) -> Table:
        """:meth:`state_at` of flat (time, vehicle) arrays; ``cols``: the /truth columns asked
        (a tuple in ``TRUTH_COLUMNS`` order, None: all); ``tau``: the rows' local times when
        the caller knows every row is active (:meth:`_active`, truth_table), else None."""
        cols = TRUTH_COLUMNS if cols is None else cols
        n = t.size
        if self.n_vehicles == 0:
            out = _empty_truth(n, cols)
            _put_ids(out, t, vid)
            out["active"] = np.zeros(n, bool)
            return out
        if tau is None:
            active, valid, vs, tau = self._active(t, vid)
        else:               # _active's values for rows known to be active
            active = valid = np.ones(n, bool)
            vs = vid
        idx = np.flatnonzero(active)
        # every row active (truth_table): no fill values, no gather, no scatter
        whole = idx.size == n and n > 0
        out = dict.fromkeys(cols) if whole else _empty_truth(n, cols)
        _put_ids(out, t, vid)
        out["active"] = active
        if "convoy_id" in out:
            out["convoy_id"] = (self.vehicles["convoy_id"][vs] if whole else
                                np.where(valid, self.vehicles["convoy_id"][vs], -1))
        want = out.__contains__
        need_pos = want("x_m") or want("y_m") or want("z_m")
        need_vel = want("vx_mps") or want("vy_mps") or want("vz_mps")
        need_acc = want("ax_mps2") or want("ay_mps2") or want("az_mps2")
        need = need_pos or need_vel or need_acc or any(
            want(c) for c in ("speed_mps", "heading_rad", "route_s_m", "edge_id", "mode",
                              "invisible"))

        def put(names, values):
            for name, val in zip(names, values):
                if not want(name):
                    continue
                if whole:
                    out[name] = np.asarray(val, dtype=_TRUTH_DTYPES[name])
                else:
                    out[name][idx] = val

        if idx.size and need:
            v_ids = vs if whole else vs[idx]
            t_a = t if whole else t[idx]
            p = self._profile[v_ids]
            s_p, speed, acc, mode = self.profiles.evaluate(tau if whole else tau[idx], p)
            s = np.clip(s_p - self._offset[v_ids], 0.0, self._veh_len[v_ids])
            # Segment under s; one correction step on each side absorbs rounding of the key.
            j = np.searchsorted(self._vx_key, s + self._veh_key0[v_ids], side="right") - 1
            lo = self._veh_lo[v_ids]
            hi = self._veh_hi[v_ids]
            j = np.clip(j, lo, hi)
            j = np.where((s < self._vx_s[j]) & (j > lo), j - 1, j)
            j = np.where((s >= self._vx_s[j + 1]) & (j < hi), j + 1, j)
            # (3, n) arrays: each axis a long contiguous row (an (n, 3) layout with n rows of
            # 3 makes every numpy loop 3 elements long)
            p0 = np.take(self._vx_xyz_t, j, axis=1)     # (np.take: 4x faster than [:, j])
            d = np.take(self._seg_d_t, j, axis=1)       # = vertex j + 1 - vertex j
            s_j, s_j1 = self._vx_s[j], self._vx_s[j + 1]
            seg_len = self._seg_len[j]                  # = s_j1 - s_j
            safe = np.where(seg_len > 0, seg_len, 1.0)
            f = np.where(seg_len > 0, (s - s_j) / safe, 0.0)
            unit = d / safe
            pos = p0 + f * d if need_pos else None
            vel = speed * unit if need_vel else None
            accel = acc * unit if need_acc else None
            # Wander: a smooth process in continuous time, in a frame that turns smoothly
            # through corners; its rates are added, so velocity = d/dt position exactly.
            moving = (np.flatnonzero(self._veh_wanders[v_ids])
                      if need_pos or need_vel or need_acc else np.zeros(0, np.int64))
            if moving.size:
                # every row wanders (the usual case): whole arrays, no gathers or scatters
                every = moving.size == v_ids.size
                sub = (lambda a: a) if every else (lambda a: a[moving])  # noqa: E731
                m_ids = sub(v_ids)
                n, nd, ndd = wander_mod.evaluate(sub(t_a), m_ids, None, self._w_off,
                                                 self._w_t0, self._w_h, knots_t=self._w_knots_t,
                                                 second=need_acc)
                jm = sub(j)
                psi_j = self._seg_psi[jm]
                psi, dpsi, d2psi = wander_mod.corner_heading(
                    sub(s), sub(s_j), sub(s_j1), psi_j, self._vx_blend[jm], self._vx_turn[jm],
                    self._vx_blend[jm + 1], self._vx_turn[jm + 1])
                # sin and cos of ψ: the segment's, except in a corner blend (ψ ≠ ψ_j)
                sin_psi, cos_psi = self._seg_sin[jm], self._seg_cos[jm]
                bent = np.flatnonzero(psi != psi_j)
                if bent.size:
                    sin_psi[bent] = np.sin(psi[bent])
                    cos_psi[bent] = np.cos(psi[bent])
                off, v_off, a_off = wander_mod.world_offset(n, nd, ndd, psi, dpsi, d2psi,
                                                            sub(speed), sub(acc),
                                                            sin_cos=(sin_psi, cos_psi))
                for total, add in ((pos, off), (vel, v_off), (accel, a_off)):
                    if total is None:
                        continue
                    if every:
                        total += add.T
                    else:
                        total[:, moving] += add.T
            if need_pos:
                put(("x_m", "y_m", "z_m"), pos)
            if need_vel:
                put(("vx_mps", "vy_mps", "vz_mps"), vel)
            if need_acc:
                put(("ax_mps2", "ay_mps2", "az_mps2"), accel)
            if want("speed_mps"):
                put(("speed_mps",), (speed,))
            if want("heading_rad"):
                put(("heading_rad",), (self._seg_heading[j],))
            if want("route_s_m"):
                put(("route_s_m",), (s,))
            if want("edge_id"):
                put(("edge_id",), (self._seg_edge[j],))
            if want("mode"):
                put(("mode",), (mode,))
            if want("invisible"):
                put(("invisible",), (self._seg_inv[j],))
        return out

    def _active(self, t, vid):
        """(active, valid, clipped vehicle ids, local time) of flat (time, vehicle) pairs."""
        valid = (vid >= 0) & (vid < self.n_vehicles)
        vs = np.where(valid, vid, 0)
        tau = t - self._t0[vs]
        active = (valid & (tau >= self._on[vs]) & (tau < self._off[vs])
                  & (tau <= self._horizon[vs])
                  & np.isfinite(t))
        return active, valid, vs, tau

    def truth_table(self, times_s) -> Table:
        """``/truth`` rows of the active vehicles at ``times_s``, sorted by time then vehicle:
        the blocks of :meth:`truth_blocks` joined."""
        parts = list(self.truth_blocks(times_s))
        if not parts:
            st = self.state_at(np.zeros(0), np.zeros(0, np.int64))
            st.pop("active")
            return st
        if len(parts) == 1:
            return parts[0]
        return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}

    def truth_blocks(self, times_s, block_rows: int = _BLOCK_ROWS) -> Iterator[Table]:
        """``/truth`` rows of the active vehicles at ``times_s``, sorted by time then vehicle,
        as consecutive tables of at most ``block_rows`` rows (none for no rows): a caller
        that streams them (the truth stage) holds one block at a time, not the whole table
        (the Stone Soup peer's 1,000 targets: 43 MB of fresh memory fewer to fault in).

        Only the (time, vehicle) pairs within each vehicle's trip (one sample of margin on each
        side, then the exact ``active`` test) are evaluated, so the cost is the rows written,
        not vehicles x times; every row's values are its own, whatever the blocks."""
        times = np.sort(np.asarray(times_s, dtype=float).ravel(), kind="stable")
        n = self.n_vehicles
        if n and len(times):
            end = np.minimum(self.end_time_s, self._t0 + self._horizon)
            i0 = np.maximum(np.searchsorted(times, self.start_time_s, side="left") - 1, 0)
            i1 = np.minimum(np.searchsorted(times, end, side="right") + 1, len(times))
            count = np.maximum(i1 - i0, 0)
        else:
            count = np.zeros(n, np.int64)
        vid = np.repeat(np.arange(n, dtype=np.int64), count)
        first = np.cumsum(count) - count
        ti = np.arange(len(vid), dtype=np.int64) - np.repeat(first - i0[:n], count) \
            if len(vid) else np.zeros(0, np.int64)
        # by time, then vehicle: vid ascends within each time already, so a stable sort of ti
        # alone (a radix sort when ti fits 16 bits) gives the order of (ti, vid)
        order = np.argsort(ti.astype(np.uint16) if len(times) <= 1 << 16 else ti, kind="stable")
        vid, ti = vid[order], ti[order]
        t = times[ti]
        tau = t
        if len(vid):        # the active pairs only (state_at then neither gathers nor scatters)
            keep, _, _, tau = self._active(t, vid)
            vid, t, tau = vid[keep], t[keep], tau[keep]
        for sl in _equal_blocks(len(vid), block_rows):
            st = self._state_flat(t[sl], vid[sl], None, tau[sl])
            mask = st.pop("active")
            yield st if mask.all() else {k: c[mask] for k, c in st.items()}


def _road_frames(routes, xyz, s, off):
    """Per vertex of the flat routes (``xyz``, ``s``, route r at ``off[r]:off[r + 1]``): the
    heading of the segment it starts (a route's last vertex: its last segment's), and the
    corner blend half-width and turn (:func:`wander.segment_headings`,
    :func:`wander.corner_blends` of each route, the same operations on all routes at once;
    a route with a segment without horizontal extent takes them route by route)."""
    nv = len(s)
    if not routes:
        return np.zeros(0), np.zeros(0), np.zeros(0)
    last = off[1:] - 1                    # each route's last vertex
    d = xyz[1:] - xyz[:-1]                # row i: vertex i to i + 1 (across routes at `last`)
    psi = np.empty(nv)
    psi[:-1] = np.arctan2(d[:, 0], d[:, 1])
    flat = ~(np.hypot(d[:, 0], d[:, 1]) > 0)
    flat[last[:-1]] = False
    psi[last] = psi[last - 1]
    seg = s[1:] - s[:-1]
    blend = np.zeros(nv)
    turn = np.zeros(nv)
    blend[1:-1] = np.minimum(wander_mod.CORNER_BLEND_M, 0.5 * np.minimum(seg[:-1], seg[1:]))
    turn[1:-1] = np.mod(psi[1:-1] - psi[:-2] + math.pi, 2.0 * math.pi) - math.pi
    blend[off[:-1]] = blend[last] = 0.0
    turn[off[:-1]] = turn[last] = 0.0
    if flat.any():                          # those routes as wander does them
        for r in np.unique(np.searchsorted(off, np.flatnonzero(flat), side="right") - 1):
            a, b = int(off[r]), int(off[r + 1])
            h = wander_mod.segment_headings(routes[r].xyz_m)
            psi[a:b - 1], psi[b - 1] = h, h[-1]
            blend[a:b], turn[a:b] = wander_mod.corner_blends(routes[r].s_m, h)
    return psi, blend, turn


TRUTH_COLUMNS = ("time_s", "vehicle_id", "convoy_id", "x_m", "y_m", "z_m", "vx_mps", "vy_mps",
                 "vz_mps", "ax_mps2", "ay_mps2", "az_mps2", "speed_mps", "heading_rad",
                 "route_s_m", "edge_id", "mode", "invisible")


_TRUTH_DTYPES = {c: (np.int64 if c in ("vehicle_id", "convoy_id", "edge_id") else
                     np.uint8 if c == "mode" else bool if c == "invisible" else np.float64)
                 for c in TRUTH_COLUMNS}


def _columns(columns):
    """``columns`` of :meth:`Fleet.state_at` as a tuple in ``TRUTH_COLUMNS`` order (None: all)."""
    if columns is None:
        return None
    asked = set(columns)
    unknown = asked.difference(TRUTH_COLUMNS, ("active",))
    if unknown:
        raise ValueError(f"unknown truth columns {sorted(unknown)}; "
                         f"known: {', '.join(TRUTH_COLUMNS)}")
    return tuple(c for c in TRUTH_COLUMNS if c in asked)


def _put_ids(out: Table, t, vid) -> None:
    """The time and vehicle id columns of a state, where asked."""
    if "time_s" in out:
        out["time_s"] = t.copy()
    if "vehicle_id" in out:
        out["vehicle_id"] = vid.copy()


def _empty_truth(n: int, cols=TRUTH_COLUMNS) -> Table:
    out: Table = {}
    for c in cols:
        if c in ("vehicle_id", "convoy_id", "edge_id"):
            out[c] = np.full(n, -1, dtype=np.int64)
        elif c == "mode":
            out[c] = np.full(n, 255, dtype=np.uint8)
        elif c == "invisible":
            out[c] = np.zeros(n, dtype=bool)
        else:
            out[c] = np.full(n, np.nan)
    return out
