"""Step 1 of a sensor chunk: the platform pose and the antenna axes per dwell, and /dwells.

:func:`chunk_poses` evaluates the platform once per dwell of a chunk of whole revisits;
:func:`dwell_table` builds the chunk's ``/dwells`` rows (docs/tables.md) and sets each dwell's
clutter-notch half-width (``mdv_mps``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import numpy as np

from gmtiflow import frames
from gmtiflow.sensor import antenna, gain, geolocate, geometry, scan
from gmtiflow.sensor.context import SensorRun
from gmtiflow.tables import Table


@dataclass
class Poses:
    """Platform pose per dwell of a chunk of whole revisits (arrays of length n_dwells_in_chunk):
    run-wide ``dwell_ids``, ``n_rev`` revisits, times, ENU position and velocity, antenna axes
    (boresight ``b``, scan axis ``h``, up ``u``) and the platform's state table."""

    dwell_ids: np.ndarray
    n_rev: int
    time_s: np.ndarray
    pos: tuple           # 3-tuples of arrays, ENU
    vel: tuple
    b: tuple
    h: tuple
    u: tuple
    state: Table
    mdv: Optional[np.ndarray] = None   # per dwell: the notch half-width (set with the dwell table)
    radius_m: float = geometry.DEFAULT_RADIUS_M   # the round earth (frames.sphere_radius_m)


def chunk_poses(run: SensorRun, rev_ids: np.ndarray) -> Poses:
    """The poses of every dwell of revisits ``rev_ids`` (consecutive, ascending)."""
    cfg, n_d = run.cfg, run.sched.n_dwells
    dwell_ids = (rev_ids[:, None] * n_d + np.arange(n_d)[None, :]).ravel()
    time_s = run.sched.dwell_time_s(dwell_ids)
    shared = _shared_revisit_times(time_s, n_d)
    if shared is not None:
        # every dwell of a revisit at one instant (instant_scan): the platform and the axes
        # once per revisit, repeated over its dwells (the same values: both are elementwise)
        st, b, h, u = _poses_at(run, shared, cfg.mount_deg)
        st = {k: _repeat(v, n_d, len(shared)) for k, v in st.items()}
        b, h, u = (tuple(np.repeat(c, n_d) for c in v) for v in (b, h, u))
    else:
        st, b, h, u = _poses_at(run, time_s, cfg.mount_deg)
    pos = tuple(np.asarray(st[k], float) for k in ("x_m", "y_m", "z_m"))
    vel = tuple(np.asarray(st[k], float) for k in ("vx_mps", "vy_mps", "vz_mps"))
    return Poses(dwell_ids, len(rev_ids), np.asarray(time_s, float), pos, vel, b, h, u, st,
                 radius_m=frames.sphere_radius_m(run.origin))


def _poses_at(run: SensorRun, time_s: np.ndarray, mount_deg: float):
    """The platform's state table and the antenna axes ``b, h, u`` at ``time_s``."""
    st = run.platform.state_at(time_s)
    pitch = st.get("pitch_rad", np.zeros(len(time_s)))
    b, h, u = antenna.antenna_axes(st["heading_rad"], pitch, st["bank_rad"],
                                   math.radians(mount_deg))
    return st, b, h, u


def _shared_revisit_times(time_s: np.ndarray, n_d: int) -> Optional[np.ndarray]:
    """The revisits' times when every dwell of each revisit (consecutive runs of ``n_d``
    dwells) has its revisit's one time, else None."""
    if n_d < 2 or len(time_s) == 0 or len(time_s) % n_d:
        return None
    per_rev = time_s.reshape(-1, n_d)
    first = per_rev[:, 0]
    return np.ascontiguousarray(first) if (per_rev == first[:, None]).all() else None


def _repeat(value, n_d: int, n_rev: int):
    """A per-revisit state column repeated over each revisit's ``n_d`` dwells (anything that
    is not one value per revisit is kept as it is)."""
    if isinstance(value, np.ndarray) and value.ndim == 1 and len(value) == n_rev:
        return np.repeat(value, n_d)
    return value


def dwell_table(run: SensorRun, poses: Poses) -> Table:
    """The chunk's /dwells rows; sets ``poses.mdv`` (the notch half-width per dwell)."""
    cfg, sched, terrain, origin = run.cfg, run.sched, run.terrain, run.origin
    dwell_ids = poses.dwell_ids
    n_d = sched.n_dwells
    idx = dwell_ids % n_d
    beam = sched.beam_scan_rad[idx]
    st = poses.state
    n = len(dwell_ids)
    # the beam's trigonometry once per beam position, gathered (the same values as per dwell)
    cos_b = np.take(np.cos(sched.beam_scan_rad), idx)
    sin_b = np.take(np.sin(sched.beam_scan_rad), idx)
    zero = np.zeros(n)
    # antenna.direction(beam, 0, b, h, u): cos 0 = 1 exactly, and 1·x = x
    beam_dir = tuple(cos_b * poses.b[k] + sin_b * poses.h[k] + zero * poses.u[k]
                     for k in range(3))
    if all(k in st for k in ("lat_deg", "lon_deg", "height_m")):
        plat, plon, ph = (np.asarray(st[k], float) for k in ("lat_deg", "lon_deg", "height_m"))
    else:
        plat, plon, ph = frames.enu_to_geodetic(origin, *poses.pos)
    r_centre = np.full(n, 0.5 * (cfg.range_min_m + cfg.range_max_m))
    centre, el_centre, _ = geolocate.geolocate(poses.pos, r_centre, beam, poses.b, poses.h,
                                               poses.u, terrain, radius_m=poses.radius_m,
                                               elevation=cfg.mdv_auto, cos_sin=(cos_b, sin_b))
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
        "angle_half_extent_rad": np.take(0.5 * scan.broadened_beamwidth_rad(
            cfg, sched.beam_scan_rad), idx),
        "mdv_mps": poses.mdv,
        "wrap_velocity_mps": np.full(n, cfg.wrap_velocity_mps),
    }


def _mdv_per_dwell(cfg, poses, beam, el_rad):
    """The clutter notch's half-width per dwell (m/s): ``mdv_mps``, or with ``auto``: with STAP
    half the main-beam clutter spread across the 3-dB beam
    (:func:`gain.mainlobe_clutter_halfwidth_mps`, Δu = half a beamwidth in sine space, v_p the
    platform's true velocity).  Without STAP the Doppler filter must reject the
    whole main-lobe clutter band, to the first nulls (Δu = the footprint, one beamwidth): its
    half-width, twice the STAP value, centred on the beam centre's clutter."""
    if not cfg.mdv_auto:     # a fixed width (without STAP, 0 = no clutter: the paper's case)
        return np.full(len(beam), float(cfg.mdv_mps))
    half = (0.5 if cfg.stap else cfg.footprint_beamwidths) * cfg.beamwidth_sine
    # the true platform velocity, as in every range rate (map rates are (R + z)/R slower)
    vel = geometry.true_velocity(poses.vel, poses.pos[2], poses.radius_m)
    return gain.mainlobe_clutter_halfwidth_mps(vel, beam, el_rad, poses.b, poses.h, poses.u,
                                                half)
