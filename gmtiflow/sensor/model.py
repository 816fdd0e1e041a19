"""The sensor stage: dwells, detections and looks of an airborne GMTI radar (DESIGN §5).

:func:`simulate` runs the scan schedule (:mod:`.scan`) over the fleet's truth, vectorised over
(dwell, target) pairs, and returns the ``dwells``, ``detections`` and ``looks`` tables of
docs/tables.md.  Per chunk of revisits:

1. **Poses.**  The platform state and the antenna axes are computed once per dwell.
2. **Pairs.**  ``dwell_resolved``: each active vehicle is paired with the dwells of its revisit
   whose beam centre is within ``footprint_beamwidths`` beamwidths of it in sine space
   (|sin az_t − sin az_b| ≤ footprint · kλ/d_a, target in front of the antenna), its truth
   evaluated at each dwell's own time.  Candidate dwells come from the vehicle's azimuth at the
   first and last dwell of the scan (plus a margin), then the exact test runs at each dwell's
   time.  A vehicle in no footprint gets one look row against the nearest dwell (smallest
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
from dataclasses import dataclass
from typing import Callable, Dict, Iterable, Optional, Tuple

import numpy as np

from gmtiflow import frames, rng
from gmtiflow.sensor import (antenna, detect, gain, geolocate, geometry, measurement, scan,
                             snr, visibility)
from gmtiflow.sensor.config import SensorConfig
from gmtiflow.sensor.outcome import Outcome
from gmtiflow.sensor.rcs import RcsModels, aspect_rad
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
    """What an effect (merge, clutter, ambiguity) may use about the chunk it post-processes."""

    cfg: SensorConfig
    seed: int
    terrain: object
    origin: frames.Origin
    dwells: Table                    # the chunk's /dwells rows
    boresight: np.ndarray            # (n_dwells, 3) antenna axes per dwell, ENU
    scan_axis: np.ndarray
    antenna_up: np.ndarray


Effect = Callable[[ChunkContext, Table, Table], Tuple[Table, Table]]


@dataclass
class _Poses:
    """Platform pose per dwell of a chunk (arrays of length n_dwells_in_chunk)."""

    time_s: np.ndarray
    pos: np.ndarray      # (n, 3)
    vel: np.ndarray      # (n, 3)
    b: np.ndarray
    h: np.ndarray
    u: np.ndarray
    state: Table


def _poses(cfg: SensorConfig, platform, time_s: np.ndarray) -> _Poses:
    st = platform.state_at(time_s)
    n = len(time_s)
    pitch = st.get("pitch_rad", np.zeros(n))
    b, h, u = antenna.antenna_axes(st["heading_rad"], pitch, st["bank_rad"],
                                   math.radians(cfg.mount_deg))
    pos = np.stack([st["x_m"], st["y_m"], st["z_m"]], axis=-1).astype(float)
    vel = np.stack([st["vx_mps"], st["vy_mps"], st["vz_mps"]], axis=-1).astype(float)
    return _Poses(np.asarray(time_s, float), pos, vel, b, h, u, st)


def _xyz(state: Table, prefix: str = "", suffix: str = "_m") -> np.ndarray:
    return np.stack([state[f"{prefix}x{suffix}"], state[f"{prefix}y{suffix}"],
                     state[f"{prefix}z{suffix}"]], axis=-1).astype(float)


def _vel(state: Table) -> np.ndarray:
    return np.stack([state["vx_mps"], state["vy_mps"], state["vz_mps"]], axis=-1).astype(float)


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
        plat, plon, ph = frames.enu_to_geodetic(origin, *poses.pos.T)
    r_centre = np.full(n, 0.5 * (cfg.range_min_m + cfg.range_max_m))
    centre, _, _ = geolocate.geolocate(poses.pos, r_centre, beam, poses.b, poses.h, poses.u,
                                       terrain)
    alat, alon, _ = frames.enu_to_geodetic(origin, *centre.T)
    return {
        "dwell_id": dwell_ids.astype(np.int64),
        "revisit_id": (dwell_ids // n_d).astype(np.int64),
        "dwell_index": idx.astype(np.int64),
        "last_dwell": idx == n_d - 1,
        "time_s": poses.time_s,
        "cpi_s": np.full(n, cfg.cpi_s),
        "beam_scan_rad": beam,
        "beam_az_rad": frames.heading_rad(beam_dir[:, 0], beam_dir[:, 1]),
        "platform_x_m": poses.pos[:, 0], "platform_y_m": poses.pos[:, 1],
        "platform_z_m": poses.pos[:, 2],
        "platform_vx_mps": poses.vel[:, 0], "platform_vy_mps": poses.vel[:, 1],
        "platform_vz_mps": poses.vel[:, 2],
        "platform_heading_rad": np.asarray(st["heading_rad"], float),
        "platform_pitch_rad": np.asarray(st.get("pitch_rad", np.zeros(n)), float),
        "platform_bank_rad": np.asarray(st["bank_rad"], float),
        "platform_lat_deg": plat, "platform_lon_deg": plon, "platform_height_m": ph,
        "area_lat_deg": alat, "area_lon_deg": alon,
        "range_half_extent_m": np.full(n, 0.5 * (cfg.range_max_m - cfg.range_min_m)),
        "angle_half_extent_rad": 0.5 * scan.broadened_beamwidth_rad(cfg, beam),
        "mdv_mps": np.full(n, cfg.mdv_mps if cfg.stap else 0.0),
        "wrap_velocity_mps": np.full(n, cfg.wrap_velocity_mps),
    }


def _angles(pos_t, pos_p, b, h, u):
    rng_m, los = geometry.line_of_sight(pos_p, pos_t)
    az, el, sin_az, lb = antenna.target_angles(los, b, h, u)
    return rng_m, los, az, el, sin_az, lb


def _candidate_pairs(cfg, sched, poses, fleet, vehicle_ids, rev_local):
    """Candidate (local dwell index, vehicle id) pairs of the chunk's revisits.

    Returns ``(dwell_local, vehicle_id, group)`` with ``group`` numbering (revisit, vehicle).
    """
    n_d = sched.n_dwells
    n_v = len(vehicle_ids)
    n_r = len(rev_local)
    u_beam = np.sin(sched.beam_scan_rad)
    bw = cfg.beamwidth_sine
    if cfg.dwell_mode == "instant_scan":
        ends = [rev_local * n_d]
    else:
        ends = [rev_local * n_d, rev_local * n_d + n_d - 1]
    sins, actives = [], []
    for dl in ends:
        d_rep = np.repeat(dl, n_v)
        v_rep = np.tile(vehicle_ids, n_r)
        st = fleet.state_at(poses.time_s[d_rep], v_rep)
        active = np.asarray(st["active"], bool)
        pos = _xyz(st)
        pos[~active] = 0.0
        _, _, az, _, sin_az, lb = _angles(pos, poses.pos[d_rep], poses.b[d_rep], poses.h[d_rep],
                                          poses.u[d_rep])
        # behind the antenna: beyond every beam, on the side it is turned to
        sin_az = np.where(lb > 0, sin_az, np.where(az >= 0, 2.0, -2.0))
        sins.append(sin_az)
        actives.append(active)
    if len(ends) == 1:
        s_lo = s_hi = sins[0]
        any_active = actives[0]
    else:
        a0, a1 = actives
        s0 = np.where(a0, sins[0], sins[1])
        s1 = np.where(a1, sins[1], sins[0])
        s_lo, s_hi = np.minimum(s0, s1), np.maximum(s0, s1)
        any_active = a0 | a1
    rev_rep = np.repeat(np.arange(n_r), n_v)
    veh_rep = np.tile(vehicle_ids, n_r)
    s_lo, s_hi, rev_rep, veh_rep = (a[any_active] for a in (s_lo, s_hi, rev_rep, veh_rep))
    nearest = np.clip(np.searchsorted(u_beam, 0.5 * (s_lo + s_hi)), 1, max(n_d - 1, 1))
    if n_d > 1:
        left_closer = np.abs(u_beam[nearest - 1] - 0.5 * (s_lo + s_hi)) <= \
            np.abs(u_beam[np.minimum(nearest, n_d - 1)] - 0.5 * (s_lo + s_hi))
        nearest = np.where(left_closer, nearest - 1, nearest)
    else:
        nearest = np.zeros_like(nearest)
    if cfg.dwell_mode == "instant_scan":
        lo, count = nearest, np.ones_like(nearest)
    else:
        w = cfg.footprint_beamwidths * bw + 0.5 * cfg.dwell_spacing_beamwidths * bw
        lo = np.searchsorted(u_beam, s_lo - w, side="left")
        hi = np.searchsorted(u_beam, s_hi + w, side="right")
        none = hi <= lo
        lo = np.where(none, nearest, lo)
        count = np.where(none, 1, hi - lo)
    total = int(count.sum())
    group = np.repeat(np.arange(len(lo)), count)
    starts = np.cumsum(count) - count
    within = np.arange(total) - starts[group]
    dwell_local = rev_rep[group] * n_d + lo[group] + within
    return dwell_local, veh_rep[group], group


def _first_in_group(group, mask):
    """Mask of the first True of ``mask`` in each (sorted, contiguous) group."""
    idx = np.flatnonzero(mask)
    if idx.size == 0:
        return np.zeros_like(mask)
    g = group[idx]
    first = np.ones(idx.size, bool)
    first[1:] = g[1:] != g[:-1]
    out = np.zeros_like(mask)
    out[idx[first]] = True
    return out


def _simulate_chunk(cfg, sched, fleet, platform, terrain, seed, origin, rcs_models, type_codes,
                    vehicle_ids, rev_ids, effects):
    n_d = sched.n_dwells
    dwell_ids = (rev_ids[:, None] * n_d + np.arange(n_d)[None, :]).ravel()
    poses = _poses(cfg, platform, sched.dwell_time_s(dwell_ids))
    dwells = _dwell_table(cfg, sched, dwell_ids, poses, terrain, origin)
    rev_local = np.arange(len(rev_ids))
    dl, veh, group = _candidate_pairs(cfg, sched, poses, fleet, vehicle_ids, rev_local)
    n_pairs_evaluated = len(dl)
    st = fleet.state_at(poses.time_s[dl], veh)
    active = np.asarray(st["active"], bool)
    pos_t = _xyz(st)
    pos_t[~active] = 0.0
    rng_m, los, az, el, sin_az, lb = _angles(pos_t, poses.pos[dl], poses.b[dl], poses.h[dl],
                                             poses.u[dl])
    beam = sched.beam_scan_rad[dl % n_d]
    instant = cfg.dwell_mode == "instant_scan"
    if instant:
        in_fp = lb > 0
        keep = active
    else:
        dist = np.where((lb > 0) & active, np.abs(sin_az - np.sin(beam)), 1e300)
        in_fp = dist <= cfg.footprint_beamwidths * cfg.beamwidth_sine * (1 + 1e-12)
        # groups are contiguous runs of (revisit, vehicle); a vehicle in no footprint keeps one
        # row: its first candidate of least sine-space distance (the nearest dwell)
        starts = np.flatnonzero(np.r_[True, group[1:] != group[:-1]]) if group.size else group
        any_fp = np.add.reduceat(in_fp.astype(np.int64), starts) > 0 if group.size else in_fp
        gmin = np.minimum.reduceat(dist, starts) if group.size else dist
        g_active = np.add.reduceat(active.astype(np.int64), starts) > 0 if group.size else active
        is_min = active & (dist <= gmin[group])
        fallback = ~any_fp[group] & g_active[group] & _first_in_group(group, is_min)
        keep = (in_fp & active) | fallback
    # one gather per needed column, rows ordered by (dwell, vehicle): candidates come grouped
    # by (revisit, vehicle) with dwells ascending, so a stable sort on the dwell is enough
    sel = np.flatnonzero(keep)
    sel = sel[np.argsort(dl[sel], kind="stable")]
    dl, veh, in_fp, rng_m, los, az, el, sin_az, beam = (
        a[sel] for a in (dl, veh, in_fp, rng_m, los, az, el, sin_az, beam))
    u_beam = np.sin(beam)
    pos_t = pos_t[sel]
    vel_t = _vel(st)[sel]
    pos_p, vel_p = poses.pos[dl], poses.vel[dl]
    invisible = np.asarray(st["invisible"], bool)[sel]
    heading_t = np.asarray(st["heading_rad"], float)[sel]

    n = len(dl)
    dwell_id = dwell_ids[dl]
    time_s = poses.time_s[dl]
    rr = geometry.range_rate(vel_t, vel_p, los)
    own_rr = np.einsum("ij,ij->i", vel_t, los)  # ṙ − ṙ_MLC
    true_az_world = frames.heading_rad(pos_t[:, 0] - pos_p[:, 0], pos_t[:, 1] - pos_p[:, 1])

    outcome = np.full(n, Outcome.OUTSIDE_FOV, np.uint8)
    fov = in_fp & visibility.in_field_of_view(cfg, az, el, rng_m)
    outcome[fov & invisible] = Outcome.INVISIBLE_ROAD
    cand = fov & ~invisible
    clear = np.zeros(n, bool)
    ci = np.flatnonzero(cand)
    clear[ci] = visibility.terrain_clear(terrain, pos_p[ci], pos_t[ci], cfg.los_step_m)
    outcome[cand & ~clear] = Outcome.TERRAIN

    vis = np.flatnonzero(cand & clear)
    snr_db_col = np.full(n, np.nan)
    pd_col = np.zeros(n)
    det_local = np.full(n, -1, np.int64)

    # --- SNR and detection for the visible pairs -----------------------------------------
    scan_angle = az[vis] if instant else beam[vis]
    f_mis = 1.0 if instant else gain.mismatch(sin_az[vis], u_beam[vis], cfg.beamwidth_sine)
    g_t = gain.transmit_gain(cfg.n_elements, scan_angle, f_mis)
    g_r = g_t * gain.stap_notch(own_rr[vis], cfg.mdv_mps, cfg.blind_speed_mps) if cfg.stap \
        else g_t
    aspect = aspect_rad(heading_t[vis], los[vis])
    rcs_v = rcs_models.rcs_dbsm(type_codes[veh[vis]], aspect)
    s_db = snr.snr_db(cfg, rng_m[vis], g_t, g_r, rcs_v)
    s_lin = snr.db_to_linear(s_db)
    lpd = detect.log_pd(s_lin, cfg.pfa)
    uni = rng.pair_uniform(rng.counter_key(seed, "sensor", "pd"), dwell_id[vis], veh[vis])
    hit = np.log(uni) < lpd
    snr_db_col[vis] = s_db
    pd_col[vis] = np.exp(lpd)
    miss = vis[~hit]
    if cfg.stap:
        blind = np.abs(gain.blind_offset(own_rr[miss], cfg.blind_speed_mps)) < cfg.mdv_mps
    else:
        blind = np.zeros(miss.size, bool)
    outcome[miss] = np.where(blind, Outcome.DOPPLER_BLIND, Outcome.PD_MISS)

    # --- detections ----------------------------------------------------------------------
    d = vis[hit]
    outcome[d] = Outcome.DETECTED
    det_local[d] = np.arange(d.size)
    snr_rep = detect.reported_snr(uni[hit], s_lin[hit])
    bw_rad = scan.broadened_beamwidth_rad(cfg, scan_angle[hit])
    s_r, s_az, s_rr = measurement.sigmas(cfg, snr_rep, bw_rad)
    e_r, e_az, e_rr = measurement.draw_errors(seed, dwell_id[d], veh[d], s_r, s_az, s_rr)
    r_meas = np.maximum(rng_m[d] + e_r, 0.0)
    az_meas = az[d] + e_az
    rr_meas = rr[d] + e_rr
    ground, _, _ = geolocate.geolocate(pos_p[d], r_meas, az_meas, poses.b[dl[d]],
                                       poses.h[dl[d]], poses.u[dl[d]], terrain)
    lat, lon, hgt = frames.enu_to_geodetic(origin, ground[:, 0], ground[:, 1], ground[:, 2])
    k = d.size
    detections = {
        "det_id": np.arange(k, dtype=np.int64),
        "dwell_id": dwell_id[d],
        "time_s": time_s[d],
        "range_m": r_meas,
        "azimuth_rad": frames.heading_rad(ground[:, 0] - pos_p[d, 0], ground[:, 1] - pos_p[d, 1]),
        "range_rate_mps": rr_meas,
        "true_range_m": rng_m[d],
        "true_azimuth_rad": true_az_world[d],
        "true_range_rate_mps": rr[d],
        "snr_db": 10.0 * np.log10(snr_rep),
        "sigma_range_m": s_r, "sigma_azimuth_rad": s_az, "sigma_range_rate_mps": s_rr,
        "x_m": ground[:, 0], "y_m": ground[:, 1], "z_m": ground[:, 2],
        "lat_deg": np.atleast_1d(lat), "lon_deg": np.atleast_1d(lon),
        "height_m": np.atleast_1d(hgt),
        "truth_id": veh[d].astype(np.int64),
        "merged": np.zeros(k, bool), "range_folded": np.zeros(k, bool),
        "doppler_wrapped": np.zeros(k, bool), "implausible": np.zeros(k, bool),
        "rcs_dbsm": rcs_v[hit],
        "wrap_velocity_mps": np.full(k, cfg.wrap_velocity_mps),
    }
    looks = {
        "dwell_id": dwell_id, "vehicle_id": veh.astype(np.int64), "time_s": time_s,
        "outcome": outcome, "snr_db": snr_db_col, "pd": pd_col, "range_m": rng_m,
        "azimuth_rad": true_az_world, "range_rate_mps": rr, "det_id": det_local,
    }
    if effects:
        ctx = ChunkContext(cfg, seed, terrain, origin, dwells, poses.b, poses.h, poses.u)
        for effect in effects:
            detections, looks = effect(ctx, detections, looks)
    return dwells, detections, looks, n_pairs_evaluated


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


def simulate(cfg: SensorConfig, fleet, platform, terrain, seed: int, duration_s: float,
             origin: frames.Origin, *, effects: Iterable[Effect] = (),
             chunk_pairs: int = 1_000_000, stats: Optional[dict] = None) -> Dict[str, Table]:
    """Dwells, detections and looks of a run (docs/tables.md).

    Parameters
    ----------
    cfg : SensorConfig
    fleet, platform, terrain : objects with the interfaces of docs/architecture.md
    seed : root seed (draws use ``counter_key(seed, "sensor", purpose)``)
    duration_s : scene duration; revisits whose last dwell falls after it are not run
    origin : the scene's geodetic origin (for lat/lon columns)
    effects : post-processors per chunk of dwells (merge, clutter, ambiguity)
    chunk_pairs : about how many (revisit, vehicle) pairs to hold in memory at once
    stats : if a dict is given, ``pairs_evaluated`` and ``n_revisits`` are stored in it
    """
    sched = scan.build_schedule(cfg, duration_s)
    rcs_models = RcsModels.from_config(cfg.rcs)
    vehicles = fleet.vehicles
    vehicle_ids = np.asarray(vehicles["vehicle_id"], np.int64)
    codes = rcs_models.type_codes(list(vehicles["vehicle_type"]))
    type_codes = np.zeros(int(vehicle_ids.max()) + 1 if vehicle_ids.size else 0, np.int64)
    type_codes[vehicle_ids] = codes
    effects = tuple(effects)
    per_rev = max(1, len(vehicle_ids) * (1 if cfg.dwell_mode == "instant_scan" else 3))
    revs_per_chunk = max(1, chunk_pairs // per_rev)
    out_d, out_det, out_look = [], [], []
    n_det = 0
    evaluated = 0
    for r0 in range(0, sched.n_revisits, revs_per_chunk):
        rev_ids = np.arange(r0, min(sched.n_revisits, r0 + revs_per_chunk))
        if vehicle_ids.size == 0:
            n_d = sched.n_dwells
            dids = (rev_ids[:, None] * n_d + np.arange(n_d)[None, :]).ravel()
            poses = _poses(cfg, platform, sched.dwell_time_s(dids))
            out_d.append(_dwell_table(cfg, sched, dids, poses, terrain, origin))
            continue
        dw, det, look, n_eval = _simulate_chunk(cfg, sched, fleet, platform, terrain, seed,
                                                origin, rcs_models, type_codes, vehicle_ids,
                                                rev_ids, effects)
        _renumber(det, look, n_det)
        n_det += len(det["det_id"])
        evaluated += n_eval
        out_d.append(dw)
        out_det.append(det)
        out_look.append(look)
    if stats is not None:
        stats["pairs_evaluated"] = evaluated
        stats["n_revisits"] = sched.n_revisits
    return {
        "dwells": _concat(out_d, DWELL_COLUMNS),
        "detections": _concat(out_det, DETECTION_COLUMNS),
        "looks": _concat(out_look, LOOK_COLUMNS),
    }


def _concat(tables, columns) -> Table:
    if not tables:
        return empty_table(columns)
    return {name: np.concatenate([np.asarray(t[name]) for t in tables]).astype(dtype, copy=False)
            for name, dtype in columns.items()}
