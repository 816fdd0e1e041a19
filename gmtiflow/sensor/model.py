"""The sensor stage: dwells, detections and looks of an airborne GMTI radar (DESIGN §5).

:func:`simulate` runs the scan schedule (:mod:`.scan`) over the fleet's truth, vectorised over
(dwell, target) pairs, and returns the ``dwells``, ``detections`` and ``looks`` tables of
docs/tables.md.  Per chunk of revisits:

1. **Poses.**  The platform state and the antenna axes are computed once per dwell.
2. **Pairs.**  ``dwell_resolved``: each active vehicle is paired with the dwells of its revisit
   whose beam centre is within ``footprint_beamwidths`` beamwidths of it in sine space
   (|sin az_t − sin az_b| ≤ footprint · kλ/d_a, target in front of the antenna), its truth
   evaluated at each dwell's own time.  Candidate dwells come from every vehicle's position at
   the scan's middle dwell, widened by the most it can move in sine space during the scan; the
   exact test then runs at each candidate dwell's time.  A vehicle in no footprint gets one look row against the nearest dwell (smallest
   sine-space distance), outcome ``outside_fov``.  ``instant_scan``: one pair per active vehicle
   and revisit, at the scan's middle instant, beam centred on the target (no scalloping, no scan
   loss beyond cos^{3/2} of the target's own azimuth), booked against the nearest dwell.
3. **Visibility** in this order (the first failing test names the outcome): footprint and
   field of view (azimuth sector, elevation, slant range), invisible road, terrain line of sight
   (skipped entirely for a flat terrain).
4. **SNR, detection, errors** for the visible pairs (:mod:`.gain`, :mod:`.snr`, :mod:`.rcs`,
   :mod:`.detect`, :mod:`.measurement`, :mod:`.geolocate`).
5. **Effects seam.**  Each callable in ``effects`` receives ``(context, detections, looks)`` of
   the chunk and returns the new ``(detections, looks)`` (merging, clutter, ambiguities belong
   there).  Chunk-local ``det_id`` values must stay consistent between the two tables; the stage
   renumbers them run-wide afterwards.

Random draws are counter-based on (dwell_id, vehicle_id) with keys
``counter_key(seed, "sensor", purpose)`` for purpose in pd, error_range, error_azimuth,
error_range_rate: a vehicle's draws do not depend on any other vehicle.
"""
from __future__ import annotations

import math
from collections import deque
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Callable, Dict, Iterable, Iterator, Optional, Tuple

import numpy as np

from tqdm import tqdm

from gmtiflow import frames, rng
from gmtiflow.sensor import (antenna, detect, gain, geolocate, geometry, measurement, scan,
                             snr, visibility)
from gmtiflow.sensor.config import SensorConfig
from gmtiflow.sensor.outcome import Outcome
from gmtiflow.sensor.rcs import RcsModels
from gmtiflow.tables import Table

DWELL_COLUMNS = {
    "dwell_id": np.int64, "revisit_id": np.int64, "dwell_index": np.int64, "last_dwell": bool,
    "time_s": float, "cpi_s": float, "beam_scan_rad": float, "beam_az_rad": float,
    "platform_x_m": float, "platform_y_m": float, "platform_z_m": float,
    "platform_vx_mps": float, "platform_vy_mps": float, "platform_vz_mps": float,
    "platform_heading_rad": float, "platform_pitch_rad": float, "platform_bank_rad": float,
    "platform_lat_deg": float, "platform_lon_deg": float, "platform_height_m": float,
    "area_lat_deg": float, "area_lon_deg": float, "range_half_extent_m": float,
    "angle_half_extent_rad": float, "mdv_mps": float, "wrap_velocity_mps": float,
}
DETECTION_COLUMNS = {
    "det_id": np.int64, "dwell_id": np.int64, "time_s": float, "range_m": float,
    "azimuth_rad": float, "range_rate_mps": float, "true_range_m": float,
    "true_azimuth_rad": float, "true_range_rate_mps": float, "snr_db": float,
    "sigma_range_m": float, "sigma_azimuth_rad": float, "sigma_range_rate_mps": float,
    "x_m": float, "y_m": float, "z_m": float, "lat_deg": float, "lon_deg": float,
    "height_m": float, "truth_id": np.int64, "merged": bool, "range_folded": bool,
    "doppler_wrapped": bool, "implausible": bool, "rcs_dbsm": float, "wrap_velocity_mps": float,
}
LOOK_COLUMNS = {
    "dwell_id": np.int64, "vehicle_id": np.int64, "time_s": float, "outcome": np.uint8,
    "snr_db": float, "pd": float, "range_m": float, "azimuth_rad": float,
    "range_rate_mps": float, "det_id": np.int64,
}


def empty_table(columns: Dict[str, type]) -> Table:
    return {name: np.zeros(0, dtype) for name, dtype in columns.items()}


@dataclass(frozen=True)
class ChunkContext:
    """What an effect (merge, clutter, ambiguity) may use about the chunk it post-processes.

    The helper methods take run-wide ``dwell_id`` arrays of this chunk's dwells and ENU points
    or measurements, vectorised, so that an effect sees the scene exactly as the sensor does.
    """

    cfg: SensorConfig
    seed: int
    terrain: object
    origin: frames.Origin
    dwells: Table                    # the chunk's /dwells rows
    boresight: tuple                 # antenna axes per dwell of the chunk: 3-tuples of arrays
    scan_axis: tuple
    antenna_up: tuple
    los_step_m: float = 30.0         # terrain line-of-sight ray step (fidelity.terrain_step_m)

    def _local(self, dwell_id) -> np.ndarray:
        return np.asarray(dwell_id, np.int64) - int(self.dwells["dwell_id"][0])

    def _platform(self, k):
        return tuple(self.dwells[f"platform_{c}_m"][k] for c in "xyz")

    def antenna_angles(self, dwell_id, x_m, y_m, z_m):
        """(slant range m, azimuth rad, elevation rad) of points in the dwell's antenna frame."""
        k = self._local(dwell_id)
        rng_m, los = geometry.line_of_sight(self._platform(k), (np.asarray(x_m, float),
                                                                np.asarray(y_m, float),
                                                                np.asarray(z_m, float)))
        az, el, _, _ = antenna.target_angles(los, antenna.take(self.boresight, k),
                                             antenna.take(self.scan_axis, k),
                                             antenna.take(self.antenna_up, k))
        return rng_m, az, el

    def in_fov(self, dwell_id, x_m, y_m, z_m=None):
        """The sensor's field-of-view test (sector, elevation, slant range) for points of the
        dwell; ``z_m`` None = on the terrain.  Does not test the footprint or terrain LOS."""
        if z_m is None:
            z_m = np.nan_to_num(np.asarray(self.terrain.height_at(x_m, y_m), float))
        rng_m, az, el = self.antenna_angles(dwell_id, x_m, y_m, z_m)
        return visibility.in_field_of_view(self.cfg, az, el, rng_m)

    def visible(self, dwell_id, x_m, y_m, z_m):
        """Points seen from the dwell's platform position: above the radar horizon and, on a
        non-flat terrain, with a clear terrain line of sight (the targets' masks)."""
        k = self._local(dwell_id)
        pts = (np.asarray(x_m, float), np.asarray(y_m, float), np.asarray(z_m, float))
        plat = self._platform(k)
        ok = visibility.within_horizon(plat, pts, self.cfg.horizon_k_factor)
        if not getattr(self.terrain, "flat", False) and np.any(ok):
            i = np.flatnonzero(ok)
            ok[i] = visibility.terrain_clear(self.terrain, antenna.take(plat, i),
                                             antenna.take(pts, i), self.los_step_m)
        return ok

    def dwell_cell_rad(self, dwell_id):
        """(low, high) antenna-frame scan angles of each dwell's cell: the sine-space interval
        between the midpoints to its neighbours (one beam step, ≤ the configured spacing); the
        cells tile the azimuth sector."""
        k = self._local(dwell_id)
        u = np.sin(self.dwells["beam_scan_rad"][k])
        u_min = math.sin(math.radians(self.cfg.az_min_deg))
        u_max = math.sin(math.radians(self.cfg.az_max_deg))
        half = 0.5 * (u_max - u_min) / scan.n_dwells(self.cfg)
        return np.arcsin(np.maximum(u - half, u_min)), np.arcsin(np.minimum(u + half, u_max))

    def range_rate_of_ground(self, dwell_id, x_m, y_m, z_m):
        """ṙ_MLC = −v_p·ℓ of ground points (the clutter's range rate, m/s)."""
        k = self._local(dwell_id)
        _, los = geometry.line_of_sight(self._platform(k), (np.asarray(x_m, float),
                                                            np.asarray(y_m, float),
                                                            np.asarray(z_m, float)))
        vel = tuple(self.dwells[f"platform_v{c}_mps"][k] for c in "xyz")
        return geometry.clutter_range_rate(vel, los)

    def geolocate(self, dwell_id, range_m, azimuth_rad):
        """Ground points ``(x, y, z)`` and ``reached`` of measured slant ranges and *world*
        azimuths (as in /detections), on the terrain, as the sensor geolocates."""
        k = self._local(dwell_id)
        return geolocate.geolocate_world_azimuth(self._platform(k), range_m, azimuth_rad,
                                                 self.terrain)


Effect = Callable[[ChunkContext, Table, Table], Tuple[Table, Table]]


@dataclass
class _Poses:
    """Platform pose per dwell of a chunk (arrays of length n_dwells_in_chunk)."""

    time_s: np.ndarray
    pos: tuple           # 3-tuples of arrays, ENU
    vel: tuple
    b: tuple
    h: tuple
    u: tuple
    state: Table
    mdv: Optional[np.ndarray] = None   # per dwell: the notch half-width (set with the dwell table)


def _poses(cfg: SensorConfig, platform, time_s: np.ndarray) -> _Poses:
    st = platform.state_at(time_s)
    n = len(time_s)
    pitch = st.get("pitch_rad", np.zeros(n))
    b, h, u = antenna.antenna_axes(st["heading_rad"], pitch, st["bank_rad"],
                                   math.radians(cfg.mount_deg))
    pos = tuple(np.asarray(st[k], float) for k in ("x_m", "y_m", "z_m"))
    vel = tuple(np.asarray(st[k], float) for k in ("vx_mps", "vy_mps", "vz_mps"))
    return _Poses(np.asarray(time_s, float), pos, vel, b, h, u, st)


def _dwell_table(cfg, sched: scan.Schedule, dwell_ids, poses: _Poses, terrain, origin) -> Table:
    n_d = sched.n_dwells
    idx = dwell_ids % n_d
    beam = sched.beam_scan_rad[idx]
    st = poses.state
    n = len(dwell_ids)
    beam_dir = antenna.direction(beam, np.zeros(n), poses.b, poses.h, poses.u)
    if all(k in st for k in ("lat_deg", "lon_deg", "height_m")):
        plat, plon, ph = (np.asarray(st[k], float) for k in ("lat_deg", "lon_deg", "height_m"))
    else:
        plat, plon, ph = frames.enu_to_geodetic(origin, *poses.pos)
    r_centre = np.full(n, 0.5 * (cfg.range_min_m + cfg.range_max_m))
    centre, el_centre, _ = geolocate.geolocate(poses.pos, r_centre, beam, poses.b, poses.h,
                                               poses.u, terrain)
    poses.mdv = _mdv_per_dwell(cfg, poses, beam, el_centre)
    alat, alon, _ = frames.enu_to_geodetic(origin, *centre)
    return {
        "dwell_id": dwell_ids.astype(np.int64),
        "revisit_id": (dwell_ids // n_d).astype(np.int64),
        "dwell_index": idx.astype(np.int64),
        "last_dwell": idx == n_d - 1,
        "time_s": poses.time_s,
        "cpi_s": np.full(n, cfg.cpi_s),
        "beam_scan_rad": beam,
        "beam_az_rad": frames.heading_rad(beam_dir[0], beam_dir[1]),
        "platform_x_m": poses.pos[0], "platform_y_m": poses.pos[1], "platform_z_m": poses.pos[2],
        "platform_vx_mps": poses.vel[0], "platform_vy_mps": poses.vel[1],
        "platform_vz_mps": poses.vel[2],
        "platform_heading_rad": np.asarray(st["heading_rad"], float),
        "platform_pitch_rad": np.asarray(st.get("pitch_rad", np.zeros(n)), float),
        "platform_bank_rad": np.asarray(st["bank_rad"], float),
        "platform_lat_deg": plat, "platform_lon_deg": plon, "platform_height_m": ph,
        "area_lat_deg": alat, "area_lon_deg": alon,
        "range_half_extent_m": np.full(n, 0.5 * (cfg.range_max_m - cfg.range_min_m)),
        "angle_half_extent_rad": 0.5 * scan.broadened_beamwidth_rad(cfg, beam),
        "mdv_mps": poses.mdv,
        "wrap_velocity_mps": np.full(n, cfg.wrap_velocity_mps),
    }


def _mdv_per_dwell(cfg, poses, beam, el_rad):
    """The clutter notch's half-width per dwell (m/s): ``mdv_mps``, or with ``auto``: with STAP
    half the main-beam clutter spread across the 3-dB beam (:func:`gain.mainlobe_clutter_halfwidth_mps`,
    Δu = half a beamwidth in sine space).  Without STAP the Doppler filter must reject the
    whole main-lobe clutter band, to the first nulls (Δu = the footprint, one beamwidth): its
    half-width, twice the STAP value, centred on the beam centre's clutter."""
    if not cfg.mdv_auto:     # a fixed width (without STAP, 0 = no clutter: the paper's case)
        return np.full(len(beam), float(cfg.mdv_mps))
    half = (0.5 if cfg.stap else cfg.footprint_beamwidths) * cfg.beamwidth_sine
    return gain.mainlobe_clutter_halfwidth_mps(poses.vel, beam, el_rad, poses.b, poses.h,
                                                poses.u, half)


def _azimuth(east, north):
    """World azimuth clockwise from north in [0, 2π) (as frames.heading_rad, without np.mod)."""
    a = np.arctan2(east, north)
    a[a < 0] += 2.0 * np.pi
    return a


def _xyz(state: Table):
    return tuple(np.asarray(state[k], float) for k in ("x_m", "y_m", "z_m"))


def _vel(state: Table):
    return tuple(np.asarray(state[k], float) for k in ("vx_mps", "vy_mps", "vz_mps"))


def _nearest_beam(u_beam, s):
    """Index of the beam centre nearest to sine coordinates ``s`` (ties to the lower index)."""
    n = len(u_beam)
    if n == 1:
        return np.zeros(len(s), np.int64)
    right = np.clip(np.searchsorted(u_beam, s), 1, n - 1)
    left_closer = np.abs(u_beam[right - 1] - s) <= np.abs(u_beam[right] - s)
    return np.where(left_closer, right - 1, right)


def _coarse(cfg, sched, poses, fleet, vehicle_ids, n_rev):
    """Every vehicle at one reference dwell per revisit: the middle one (its time, its pose).

    Returns the vehicles' state there, the reference dwells (chunk-local), the vehicle ids,
    activity, slant range and sine coordinate per (revisit, vehicle), revisit-major.  Only
    what the candidate search needs is computed, broadcasting each revisit's pose over its
    vehicles instead of gathering it.
    """
    n_d = sched.n_dwells
    n_v = len(vehicle_ids)
    ref = np.arange(n_rev) * n_d + n_d // 2
    d_rep = np.repeat(ref, n_v)
    v_rep = np.tile(vehicle_ids, n_rev)
    st = fleet.state_at(poses.time_s[d_rep], v_rep)
    active = np.asarray(st["active"], bool)
    d = []
    for k, c in enumerate(_xyz(st)):
        if not np.all(active):
            c = np.where(active, c, 0.0)
        d.append(c.reshape(n_rev, n_v) - poses.pos[k][ref][:, None])
    b = [c[ref][:, None] for c in poses.b]
    h = [c[ref][:, None] for c in poses.h]
    lb = d[0] * b[0] + d[1] * b[1] + d[2] * b[2]
    lh = d[0] * h[0] + d[1] * h[1] + d[2] * h[2]
    rng_m = np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).ravel()
    horiz = np.hypot(lb, lh)
    sin_az = np.divide(lh, horiz, out=np.zeros_like(lh), where=horiz > 0)
    # behind the antenna: beyond every beam, on the side it is turned to
    s = np.where(lb > 0, sin_az, np.where(lh >= 0, 2.0, -2.0)).ravel()
    return st, d_rep, v_rep, active, rng_m, s


def _candidate_pairs(cfg, sched, poses, fleet, vehicle_ids, n_rev):
    """Candidate (chunk-local dwell, vehicle) pairs, grouped by (revisit, vehicle), dwells
    ascending within a group.  Returns ``(dwell_local, vehicle_id, group)``.

    A vehicle's sine coordinate is taken at the scan's middle dwell; over the scan it moves by
    at most (|v_p| + |v_t|)·Δt / R plus the antenna's rotation (turns), which widens the
    window of candidate beams.  The exact footprint test runs later at each dwell's time.

    Also returns, per group, whether the vehicle is active at the middle dwell (``mid_active``)
    and that dwell (``mid_dwell``), so a vehicle that leaves or appears mid-scan and is inactive
    at all its candidate dwells still gets its one look row (at the middle dwell).
    """
    n_d = sched.n_dwells
    n_v = len(vehicle_ids)
    u_beam = np.sin(sched.beam_scan_rad)
    bw = cfg.beamwidth_sine
    st, d_ref, v_rep, active, rng_m, s = _coarse(cfg, sched, poses, fleet, vehicle_ids, n_rev)
    # motion margin
    dt = float(np.max(np.abs(sched.time_offset_s - sched.time_offset_s[n_d // 2])))
    vp = np.sqrt(antenna.dot(poses.vel, poses.vel))
    bx, by, bz = (c.reshape(n_rev, n_d) for c in poses.b)
    mid = n_d // 2
    cosang = bx * bx[:, mid:mid + 1] + by * by[:, mid:mid + 1] + bz * bz[:, mid:mid + 1]
    rot = np.arccos(np.clip(cosang, -1.0, 1.0)).max(axis=1)          # per revisit
    vt = np.hypot(np.hypot(np.nan_to_num(np.asarray(st["vx_mps"], float)),
                           np.nan_to_num(np.asarray(st["vy_mps"], float))),
                  np.nan_to_num(np.asarray(st["vz_mps"], float)))
    move = (vp[d_ref] + vt) * dt
    margin = move / np.maximum(rng_m - move, 1.0) + np.repeat(rot, n_v) + 0.02 * bw
    w = cfg.footprint_beamwidths * bw + margin
    rev = np.repeat(np.arange(n_rev), n_v)
    mid_active = active
    if not np.all(active):
        # a vehicle inactive at the middle may still be active at one end of the scan
        keep = active | _active_at_ends(sched, poses, fleet, v_rep, rev)
        s, w, rev, v_rep = s[keep], w[keep], rev[keep], v_rep[keep]
        s = np.where(active[keep], s, 0.0)
        w = np.where(active[keep], w, 2.0)     # unknown position: try every beam
        mid_active = active[keep]
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
    group = np.repeat(np.arange(len(lo)), count)
    starts = np.cumsum(count) - count
    within = np.arange(total) - starts[group]
    dwell_local = rev[group] * n_d + lo[group] + within
    return dwell_local, v_rep[group], group, mid_active, rev * n_d + n_d // 2


def _active_at_ends(sched, poses, fleet, v_rep, rev):
    n_d = sched.n_dwells
    out = np.zeros(len(v_rep), bool)
    for k in (0, n_d - 1):
        st = fleet.state_at(poses.time_s[rev * n_d + k], v_rep)
        out |= np.asarray(st["active"], bool)
    return out


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
          "invisible")   # the truth columns the sensor reads


def _pair_geometry(poses: _Poses, dl, st: Table) -> Dict[str, np.ndarray]:
    """Geometry of (dwell, target) pairs: the pose of chunk-local dwell ``dl`` and the target
    state ``st`` (inactive targets get a harmless position, never NaN)."""
    active = np.asarray(st["active"], bool)
    pos_t = _xyz(st)
    vel_t = _vel(st)
    if not np.all(active):
        pos_t = tuple(np.where(active, c, 0.0) for c in pos_t)
        vel_t = tuple(np.where(active, c, 0.0) for c in vel_t)
    rng_m, los = geometry.line_of_sight(antenna.take(poses.pos, dl), pos_t)
    az, el, sin_az, lb = antenna.target_angles(los, antenna.take(poses.b, dl),
                                               antenna.take(poses.h, dl),
                                               antenna.take(poses.u, dl))
    own_rr = antenna.dot(vel_t, los)                                  # ṙ − ṙ_MLC
    rr = own_rr + geometry.clutter_range_rate(antenna.take(poses.vel, dl), los)   # ṙ
    return {"active": active, "range_m": rng_m, "los_e": los[0], "los_n": los[1],
            "az": az, "el": el, "sin_az": sin_az, "lb": lb, "own_rr": own_rr,
            "rr": rr, "x_m": pos_t[0], "y_m": pos_t[1], "z_m": pos_t[2],
            "heading_rad": np.asarray(st["heading_rad"], float),
            "invisible": np.asarray(st["invisible"], bool)}


def _select_pairs(cfg, sched, poses, fleet, vehicle_ids, n_rev):
    """The looks of a chunk ordered by (dwell, vehicle): ``(dwell_local, vehicle, geometry)``,
    and the number of (dwell, target) pairs evaluated."""
    n_d = sched.n_dwells
    u_beam_all = np.sin(sched.beam_scan_rad)
    if sched.instant:
        st, d_ref, veh, active, _, s = _coarse(cfg, sched, poses, fleet, vehicle_ids, n_rev)
        dl = d_ref - n_d // 2 + _nearest_beam(u_beam_all, s)
        sel = np.flatnonzero(active)
        n_eval = len(sel)
        # all dwells of an instant scan share one time and pose: the reference's geometry holds
        geo = _pair_geometry(poses, d_ref[sel], {k: np.asarray(st[k])[sel] for k in _STATE})
        geo["in_fp"] = geo["lb"] > 0        # the beam is on the target, if it is in front
        dl, veh = dl[sel], veh[sel]
        sel = np.arange(len(dl))
    else:
        dl, veh, group, mid_active, mid_dwell = _candidate_pairs(cfg, sched, poses, fleet,
                                                                 vehicle_ids, n_rev)
        n_eval = len(dl)
        geo = _pair_geometry(poses, dl, fleet.state_at(poses.time_s[dl], veh))
        active = geo["active"]
        sel = np.zeros(0, np.int64)
        extra = False
        if group.size:
            # groups are contiguous runs of (revisit, vehicle); a vehicle in no footprint keeps
            # one row: its first candidate of least sine-space distance (the nearest dwell)
            starts = np.flatnonzero(np.r_[True, group[1:] != group[:-1]])
            gidx = np.cumsum(np.r_[False, group[1:] != group[:-1]])
            g_active = np.logical_or.reduceat(active, starts)
            # active at the middle dwell but at none of its candidate dwells (it left or
            # appeared mid-scan): one more candidate, the middle dwell itself
            lost = np.flatnonzero(~g_active & mid_active[group[starts]])
            if lost.size:
                extra = True
                g_lost = group[starts[lost]]
                dl_x, veh_x = mid_dwell[g_lost], veh[starts[lost]]
                geo_x = _pair_geometry(poses, dl_x, fleet.state_at(poses.time_s[dl_x], veh_x))
                n_eval += lost.size
                geo = {k: np.concatenate([v, geo_x[k]]) for k, v in geo.items()}
                dl, veh = np.concatenate([dl, dl_x]), np.concatenate([veh, veh_x])
                gidx = np.concatenate([gidx, lost])
                active = geo["active"]
                g_active[lost] = active[-lost.size:]
            dist = np.where((geo["lb"] > 0) & active,
                            np.abs(geo["sin_az"] - u_beam_all[dl % n_d]), 1e300)
            in_fp = dist <= cfg.footprint_beamwidths * cfg.beamwidth_sine * (1 + 1e-12)
            if extra:     # the extra rows sit after every group: unbuffered group reductions
                any_fp = np.zeros(len(starts), bool)
                np.logical_or.at(any_fp, gidx, in_fp)
                gmin = np.full(len(starts), np.inf)
                np.minimum.at(gmin, gidx, dist)
            else:
                any_fp = np.logical_or.reduceat(in_fp, starts)
                gmin = np.minimum.reduceat(dist, starts)
            is_min = active & (dist <= gmin[gidx])
            if extra:
                first = np.zeros(len(dl), bool)
                cand = np.flatnonzero(is_min)
                _, first_of = np.unique(gidx[cand], return_index=True)
                first[cand[first_of]] = True
            else:
                first = _first_in_group(gidx, is_min)
            fallback = ~any_fp[gidx] & g_active[gidx] & first
            sel = np.flatnonzero((in_fp & active) | fallback)
            geo["in_fp"] = in_fp
        else:
            geo["in_fp"] = np.zeros(0, bool)
    # candidates come grouped by (revisit, vehicle), dwells ascending: a stable sort on the
    # dwell orders rows by (dwell, vehicle); int16 keys sort by radix
    if sched.instant or not extra:
        key = dl[sel]
        key = key.astype(np.int16) if len(poses.time_s) < 32_000 else key
        sel = sel[np.argsort(key, kind="stable")]
    else:     # the extra middle-dwell rows come last: sort on (dwell, vehicle) explicitly
        sel = sel[np.lexsort((veh[sel], dl[sel]))]
    return dl[sel], veh[sel], _Rows(geo, sel), n_eval


class _Rows:
    """The selected rows of candidate-level columns, gathered only when (and where) used."""

    def __init__(self, columns: Dict[str, np.ndarray], sel: np.ndarray):
        self.columns, self.sel, self.cache = columns, sel, {}

    def __getitem__(self, name: str) -> np.ndarray:
        if name not in self.cache:
            self.cache[name] = self.columns[name][self.sel]
        return self.cache[name]

    def at(self, name: str, index: np.ndarray) -> np.ndarray:
        """Column ``name`` at selected rows ``index`` (without gathering the others)."""
        if name in self.cache:
            return self.cache[name][index]
        return self.columns[name][self.sel[index]]


def _simulate_chunk(cfg, sched, fleet, platform, terrain, seed, origin, rcs_models, type_codes,
                    vehicle_ids, rev_ids, effects, block_vehicles, los_step_m):
    """One chunk of whole revisits; vehicles in blocks of ``block_vehicles`` (bounded working
    memory for big fleets), merged back into (dwell, vehicle) order before the effects, which
    need every detection of a dwell."""
    n_d = sched.n_dwells
    dwell_ids = (rev_ids[:, None] * n_d + np.arange(n_d)[None, :]).ravel()
    poses = _poses(cfg, platform, sched.dwell_time_s(dwell_ids))
    dwells = _dwell_table(cfg, sched, dwell_ids, poses, terrain, origin)
    vehicle_ids = _on_the_road(fleet, vehicle_ids, poses.time_s)
    parts = [_evaluate_block(cfg, sched, fleet, terrain, seed, origin, rcs_models, type_codes,
                             vehicle_ids[v0:v0 + block_vehicles], len(rev_ids), poses,
                             dwell_ids, los_step_m)
             for v0 in range(0, len(vehicle_ids), block_vehicles)]
    n_eval = sum(p[2] for p in parts)
    if not parts:     # no vehicles: the dwells still produce false alarms
        detections, looks = empty_table(DETECTION_COLUMNS), empty_table(LOOK_COLUMNS)
    elif len(parts) == 1:
        detections, looks = parts[0][0], parts[0][1]
    else:
        detections, looks = _merge_blocks([p[0] for p in parts], [p[1] for p in parts])
    if effects:
        ctx = ChunkContext(cfg, seed, terrain, origin, dwells, poses.b, poses.h, poses.u,
                           los_step_m)
        for effect in effects:
            detections, looks = effect(ctx, detections, looks)
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


def _evaluate_block(cfg, sched, fleet, terrain, seed, origin, rcs_models, type_codes,
                    vehicle_ids, n_rev, poses, dwell_ids, los_step_m):
    """Detections and looks of some vehicles over the chunk's revisits (chunk-local det ids)."""
    n_d = sched.n_dwells
    instant = sched.instant
    dl, veh, geo, n_eval = _select_pairs(cfg, sched, poses, fleet, vehicle_ids, n_rev)
    n = len(dl)
    veh = veh.astype(np.int64)
    rng_m, az, el, rr = (geo[k] for k in ("range_m", "az", "el", "rr"))
    beam = sched.beam_scan_rad[dl % n_d]
    dwell_id = dwell_ids[dl]
    time_s = poses.time_s[dl]
    true_az_world = _azimuth(geo["los_e"], geo["los_n"])
    in_fp = geo["in_fp"]

    # --- visibility: field of view, invisible road, terrain -------------------------------
    outcome = np.full(n, Outcome.OUTSIDE_FOV, np.uint8)
    fov = in_fp & visibility.in_field_of_view(cfg, az, el, rng_m)
    invisible = geo["invisible"]
    outcome[fov & invisible] = Outcome.INVISIBLE_ROAD
    cand = fov & ~invisible
    clear = np.zeros(n, bool)
    ci = np.flatnonzero(cand)
    p_ci = antenna.take(poses.pos, dl[ci])
    t_ci = tuple(geo.at(k, ci) for k in ("x_m", "y_m", "z_m"))
    clear[ci] = visibility.within_horizon(p_ci, t_ci, cfg.horizon_k_factor)
    if not getattr(terrain, "flat", False):
        cc = np.flatnonzero(clear[ci])
        clear[ci[cc]] = visibility.terrain_clear(terrain, antenna.take(p_ci, cc),
                                                 antenna.take(t_ci, cc), los_step_m)
    outcome[cand & ~clear] = Outcome.TERRAIN

    # --- SNR and the Swerling-I draw for the visible pairs -------------------------------
    vis = np.flatnonzero(cand & clear)
    snr_db_col = np.full(n, np.nan)
    pd_col = np.zeros(n)
    det_local = np.full(n, -1, np.int64)
    scan_angle = az[vis] if instant else beam[vis]
    f_mis = 1.0 if instant else gain.mismatch(geo.at("sin_az", vis), np.sin(beam[vis]),
                                              cfg.beamwidth_sine)
    g_t = gain.transmit_gain(cfg.n_elements, scan_angle, f_mis)
    mdv = poses.mdv[dl[vis]]
    if cfg.stap:
        own_rr = geo.at("own_rr", vis)                                 # ṙ − ṙ_MLC at the target
    else:   # no STAP: the Doppler filter rejects the main-lobe clutter around the beam centre's
        dv = dl[vis]
        l_bc = antenna.direction(scan_angle, el[vis], antenna.take(poses.b, dv),
                                 antenna.take(poses.h, dv), antenna.take(poses.u, dv))
        own_rr = rr[vis] + antenna.dot(antenna.take(poses.vel, dv), l_bc)
    if cfg.stap:
        g_r = g_t * gain.stap_notch(own_rr, mdv, cfg.blind_speed_mps)
    else:
        g_r = g_t * gain.clutter_band_gain(own_rr, mdv, cfg.blind_speed_mps)
    rcs_v = rcs_models.rcs_dbsm(type_codes[veh[vis]], geo.at("heading_rad", vis),
                                geo.at("los_e", vis), geo.at("los_n", vis))
    s_db = snr.snr_db(cfg, rng_m[vis], g_t, g_r, rcs_v)
    s_lin = snr.db_to_linear(s_db)
    lpd = detect.log_pd(s_lin, cfg.pfa)
    uni = rng.pair_uniform(rng.counter_key(seed, "sensor", "pd"), dwell_id[vis], veh[vis])
    hit = np.log(uni) < lpd
    snr_db_col[vis] = s_db
    pd_col[vis] = np.exp(lpd)
    miss = vis[~hit]
    blind = np.abs(gain.blind_offset(own_rr[~hit], cfg.blind_speed_mps)) < mdv[~hit]
    outcome[miss] = np.where(blind, Outcome.DOPPLER_BLIND, Outcome.PD_MISS)

    # --- detections: reported SNR, errors, geolocation ----------------------------------
    d = vis[hit]
    k = d.size
    outcome[d] = Outcome.DETECTED
    det_local[d] = np.arange(k)
    snr_rep = detect.reported_snr(uni[hit], s_lin[hit])
    bw_rad = scan.broadened_beamwidth_rad(cfg, scan_angle[hit])
    s_r, s_az, s_rr = measurement.sigmas(cfg, snr_rep, bw_rad)
    e_r, e_az, e_rr = measurement.draw_errors(seed, dwell_id[d], veh[d], s_r, s_az, s_rr)
    r_meas = np.maximum(rng_m[d] + e_r, 0.0)
    az_meas = az[d] + e_az
    dd = dl[d]
    ppd = antenna.take(poses.pos, dd)
    ground, _, _ = geolocate.geolocate(ppd, r_meas, az_meas, antenna.take(poses.b, dd),
                                       antenna.take(poses.h, dd), antenna.take(poses.u, dd),
                                       terrain)
    lat, lon, hgt = frames.enu_to_geodetic(origin, *ground)
    detections = {
        "det_id": np.arange(k, dtype=np.int64),
        "dwell_id": dwell_id[d],
        "time_s": time_s[d],
        "range_m": r_meas,
        "azimuth_rad": _azimuth(ground[0] - ppd[0], ground[1] - ppd[1]),
        "range_rate_mps": rr[d] + e_rr,
        "true_range_m": rng_m[d],
        "true_azimuth_rad": true_az_world[d],
        "true_range_rate_mps": rr[d],
        "snr_db": 10.0 * np.log10(snr_rep),
        "sigma_range_m": s_r, "sigma_azimuth_rad": s_az, "sigma_range_rate_mps": s_rr,
        "x_m": ground[0], "y_m": ground[1], "z_m": ground[2],
        "lat_deg": np.atleast_1d(lat), "lon_deg": np.atleast_1d(lon),
        "height_m": np.atleast_1d(hgt),
        "truth_id": veh[d],
        "merged": np.zeros(k, bool), "range_folded": np.zeros(k, bool),
        "doppler_wrapped": np.zeros(k, bool), "implausible": np.zeros(k, bool),
        "rcs_dbsm": rcs_v[hit],
        "wrap_velocity_mps": np.full(k, cfg.wrap_velocity_mps),
    }
    looks = {
        "dwell_id": dwell_id, "vehicle_id": veh, "time_s": time_s,
        "outcome": outcome, "snr_db": snr_db_col, "pd": pd_col, "range_m": rng_m,
        "azimuth_rad": true_az_world, "range_rate_mps": rr, "det_id": det_local,
    }
    return detections, looks, n_eval


def _renumber(detections: Table, looks: Table, offset: int) -> None:
    old = np.asarray(detections["det_id"], np.int64)
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
    codes = rcs_models.type_codes(list(vehicles["vehicle_type"]))
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

    def run(rev_ids):
        return _simulate_chunk(cfg, sched, fleet, platform, terrain, seed, origin, rcs_models,
                               type_codes, vehicle_ids, rev_ids, effects, block_vehicles,
                               los_step_m)

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
    for dw, det, look in tqdm(chunks, desc="sensor", unit="chunk", leave=False,
                              disable=None if progress else True):
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
