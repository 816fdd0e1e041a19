"""Small synthetic scenes in the exact docs/tables.md columns, for tests and benchmarks.

Vehicles drive straight lines at constant speed (optionally stopping instantly for a while);
a platform flies a straight line far to the south; one dwell per revisit whose beam covers the
whole scene; every vehicle is detected each revisit unless a *blind* interval or a stop hides
it, with isotropic Gaussian ground-position noise of σ ``sigma_m`` (the detection's
``sigma_range_m`` / ``sigma_azimuth_rad`` are set so that the tracker's measurement covariance is
exactly ``σ² I``) and Gaussian range-rate noise.  Optional uniform clutter.

These scenes stand in for the sensor stage while it is not there; they are not a radar model.
"""
from __future__ import annotations

from typing import Dict, Optional, Sequence, Tuple

import numpy as np

from gmtiflow import frames
from gmtiflow.tables import Table

PLATFORM_START = np.array([-20000.0, -40000.0, 6000.0])
PLATFORM_VEL = np.array([150.0, 0.0, 0.0])


def _truth_table(grid, ids, state, convoy_id, stopped_heading_rad=None) -> Table:
    """/truth rows (docs/tables.md) of vehicles moving in the ground plane, sorted by time then
    vehicle.  ``state(t, v) -> (pos (n, 2), vel (n, 2), moving (n,))``; a stopped vehicle keeps
    ``stopped_heading_rad[v]`` as its heading and has mode 2."""
    parts = []
    n = len(grid)
    for v in ids:
        pos, vel, moving = state(grid, v)
        heading = frames.heading_rad(vel[:, 0], vel[:, 1])
        if stopped_heading_rad is not None:
            heading = np.where(moving, heading, stopped_heading_rad[v] % (2 * np.pi))
        parts.append({
            "time_s": grid, "vehicle_id": np.full(n, v), "convoy_id": np.full(n, convoy_id[v]),
            "x_m": pos[:, 0], "y_m": pos[:, 1], "z_m": np.zeros(n),
            "vx_mps": vel[:, 0], "vy_mps": vel[:, 1], "vz_mps": np.zeros(n),
            "ax_mps2": np.zeros(n), "ay_mps2": np.zeros(n), "az_mps2": np.zeros(n),
            "speed_mps": np.hypot(vel[:, 0], vel[:, 1]), "heading_rad": heading,
            "route_s_m": np.zeros(n), "edge_id": np.full(n, -1, np.int64),
            "mode": np.where(moving, 0, 2).astype(np.uint8), "invisible": np.zeros(n, bool)})
    truth = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    order = np.lexsort((truth["vehicle_id"], truth["time_s"]))
    return {k: c[order] for k, c in truth.items()}


def _dwell_schedule(n_revisits: int, n_beams: int, revisit_s: float, dwell_s: float):
    """(revisit, beam index, time) of every dwell: beams back to back from each revisit start."""
    revisit = np.repeat(np.arange(n_revisits), n_beams)
    index = np.tile(np.arange(n_beams), n_revisits)
    return revisit, index, revisit * revisit_s + index * dwell_s


def straight_scene(*, n_vehicles: int = 1, n_revisits: int = 60, revisit_s: float = 2.0,
                   sigma_m: float = 10.0, sigma_rr_mps: float = 0.5, speed_mps: float = 10.0,
                   spacing_m: float = 500.0, truth_dt_s: float = 1.0, seed: int = 0,
                   headings_rad: Optional[Sequence[float]] = None,
                   stops: Optional[Dict[int, Tuple[float, float]]] = None,
                   blind: Optional[Dict[int, Sequence[Tuple[float, float]]]] = None,
                   clutter_per_dwell: float = 0.0, clutter_half_width_m: float = 3000.0,
                   convoy_ids: Optional[Sequence[int]] = None, n_beams: int = 1,
                   dwell_s: float = 0.05) -> Dict[str, Table]:
    """A scene of straight-driving vehicles; returns truth, vehicles, dwells, detections, looks.

    ``stops``: vehicle -> (t0, t1), standing still (mode 2, undetectable) on [t0, t1].
    ``blind``: vehicle -> list of (t0, t1) intervals in which it is Doppler blind (outcome 4).
    ``n_beams``: dwells per revisit, ``dwell_s`` apart, whose beams tile a ±30° sector around the
    scene centre; a vehicle is looked at (and can be detected) only by the beam it is in.
    """
    rng = np.random.default_rng(seed)
    stops = stops or {}
    blind = blind or {}
    ids = np.arange(n_vehicles, dtype=np.int64)
    if headings_rad is None:
        headings_rad = np.radians(np.linspace(20.0, 70.0, n_vehicles))
    headings = np.asarray(headings_rad, float)
    start = np.stack([ids * spacing_m, np.zeros(n_vehicles)], axis=1)
    unit = np.stack([np.sin(headings), np.cos(headings)], axis=1)
    convoy = (np.full(n_vehicles, -1, np.int64) if convoy_ids is None
              else np.asarray(convoy_ids, np.int64))

    def state(t, v):
        t = np.asarray(t, float)
        t0, t1 = stops.get(int(v), (np.inf, np.inf))
        s = speed_mps * (np.minimum(t, t0) + np.maximum(t - t1, 0.0))
        moving = (t < t0) | (t > t1)
        pos = start[v] + s[:, None] * unit[v]
        vel = np.where(moving[:, None], speed_mps * unit[v], 0.0)
        return pos, vel, moving

    duration = (n_revisits - 1) * revisit_s
    grid = np.arange(0.0, duration + 1e-9, truth_dt_s)
    truth = _truth_table(grid, ids, state, convoy, headings)

    revisit, index, t_dw = _dwell_schedule(n_revisits, n_beams, revisit_s, dwell_s)
    plat = PLATFORM_START[None, :] + t_dw[:, None] * PLATFORM_VEL[None, :]
    centre = np.array([n_vehicles * spacing_m / 2.0, 500.0])
    half = np.radians(30.0) / n_beams
    beam_az = (frames.heading_rad(centre[0] - plat[:, 0], centre[1] - plat[:, 1])
               + (2 * index - (n_beams - 1)) * half)
    nd = len(t_dw)
    dwells = {
        "dwell_id": np.arange(nd, dtype=np.int64), "revisit_id": revisit.astype(np.int64),
        "dwell_index": index.astype(np.int64), "last_dwell": index == n_beams - 1,
        "time_s": t_dw,
        "cpi_s": np.full(nd, 0.05), "beam_scan_rad": np.zeros(nd), "beam_az_rad": beam_az,
        "platform_x_m": plat[:, 0], "platform_y_m": plat[:, 1], "platform_z_m": plat[:, 2],
        "platform_vx_mps": np.full(nd, PLATFORM_VEL[0]),
        "platform_vy_mps": np.full(nd, PLATFORM_VEL[1]),
        "platform_vz_mps": np.full(nd, PLATFORM_VEL[2]),
        "angle_half_extent_rad": np.full(nd, half),
        "mdv_mps": np.full(nd, 1.0), "wrap_velocity_mps": np.full(nd, np.nan)}

    det_parts, look_parts = [], []
    for v in ids:
        pos, vel, moving = state(t_dw, v)
        d = np.concatenate([pos - plat[:, :2], -plat[:, 2:3]], axis=1)
        rng_m = np.linalg.norm(d, axis=1)
        ground = np.hypot(d[:, 0], d[:, 1])
        w = np.concatenate([vel - PLATFORM_VEL[None, :2], np.zeros((nd, 1))], axis=1)
        rr = np.einsum("ij,ij->i", d, w) / rng_m
        outcome = np.zeros(nd, np.uint8)
        for t0, t1 in blind.get(int(v), ()):
            outcome[(t_dw >= t0) & (t_dw <= t1)] = 4
        outcome[~moving] = 4
        in_beam = np.abs(frames.wrap_pi(frames.heading_rad(d[:, 0], d[:, 1]) - beam_az)) <= half
        outcome[~in_beam] = 1
        noise = rng.normal(0.0, sigma_m, (nd, 2))
        rr_noise = rng.normal(0.0, sigma_rr_mps, nd)
        det = outcome == 0
        n = int(det.sum())
        det_parts.append({
            "dwell_id": np.arange(nd)[det], "time_s": t_dw[det], "range_m": rng_m[det],
            "azimuth_rad": frames.heading_rad(d[det, 0], d[det, 1]),
            "range_rate_mps": rr[det] + rr_noise[det], "true_range_m": rng_m[det],
            "true_azimuth_rad": frames.heading_rad(d[det, 0], d[det, 1]),
            "true_range_rate_mps": rr[det], "snr_db": np.full(n, 20.0),
            "sigma_range_m": sigma_m * ground[det] / rng_m[det],
            "sigma_azimuth_rad": sigma_m / rng_m[det],
            "sigma_range_rate_mps": np.full(n, sigma_rr_mps),
            "x_m": pos[det, 0] + noise[det, 0], "y_m": pos[det, 1] + noise[det, 1],
            "z_m": np.zeros(n), "truth_id": np.full(n, v, np.int64)})
        look_parts.append({"dwell_id": np.flatnonzero(in_beam).astype(np.int64),
                           "vehicle_id": np.full(int(in_beam.sum()), v, np.int64),
                           "time_s": t_dw[in_beam], "outcome": outcome[in_beam],
                           "det_id": np.full(int(in_beam.sum()), -1, np.int64)})
    if clutter_per_dwell > 0:
        counts = rng.poisson(clutter_per_dwell, nd)
        k = np.repeat(np.arange(nd), counts)
        n = len(k)
        xy = centre + rng.uniform(-clutter_half_width_m, clutter_half_width_m, (n, 2))
        az = frames.heading_rad(xy[:, 0] - plat[k, 0], xy[:, 1] - plat[k, 1])
        inside = np.abs(frames.wrap_pi(az - beam_az[k])) <= half      # nothing outside the beam
        k, xy = k[inside], xy[inside]
        n = len(k)
        d = np.concatenate([xy - plat[k, :2], -plat[k, 2:3]], axis=1)
        rng_m = np.linalg.norm(d, axis=1)
        ground = np.hypot(d[:, 0], d[:, 1])
        det_parts.append({
            "dwell_id": k, "time_s": t_dw[k], "range_m": rng_m,
            "azimuth_rad": frames.heading_rad(d[:, 0], d[:, 1]),
            "range_rate_mps": rng.uniform(-20, 20, n) - PLATFORM_VEL[0] * d[:, 0] / rng_m,
            "true_range_m": rng_m, "true_azimuth_rad": frames.heading_rad(d[:, 0], d[:, 1]),
            "true_range_rate_mps": np.full(n, np.nan), "snr_db": np.full(n, 13.0),
            "sigma_range_m": sigma_m * ground / rng_m, "sigma_azimuth_rad": sigma_m / rng_m,
            "sigma_range_rate_mps": np.full(n, sigma_rr_mps), "x_m": xy[:, 0], "y_m": xy[:, 1],
            "z_m": np.zeros(n), "truth_id": np.full(n, -1, np.int64)})
    dets = {k: np.concatenate([p[k] for p in det_parts]) for k in det_parts[0]}
    order = np.lexsort((dets["truth_id"], dets["dwell_id"]))
    dets = {k: c[order] for k, c in dets.items()}
    nd_rows = len(dets["dwell_id"])
    dets["det_id"] = np.arange(nd_rows, dtype=np.int64)
    for name, dtype in (("merged", bool), ("range_folded", bool), ("doppler_wrapped", bool),
                        ("implausible", bool)):
        dets[name] = np.zeros(nd_rows, dtype)
    looks = {k: np.concatenate([p[k] for p in look_parts]) for k in look_parts[0]}
    order = np.lexsort((looks["vehicle_id"], looks["dwell_id"]))
    looks = {k: c[order] for k, c in looks.items()}
    vehicles = {"vehicle_id": ids, "name": np.array([f"v{i}" for i in ids]),
                "convoy_id": convoy, "vehicle_type": np.array(["car"] * n_vehicles),
                "start_time_s": np.zeros(n_vehicles), "route_length_m": np.full(n_vehicles, 1e4),
                "off_road": np.ones(n_vehicles, bool)}
    return {"truth": truth, "vehicles": vehicles, "dwells": dwells, "detections": dets,
            "looks": looks}


def gmti_scene(*, n_vehicles: int = 4, n_revisits: int = 40, revisit_s: float = 5.0,
               standoff_m: float = 30000.0, height_m: float = 6000.0,
               sigma_range_m: float = 0.3, sigma_cross_m: float = 74.0,
               sigma_rr_mps: float = 0.05, speed_mps: float = 20.0,
               headings_rad: Optional[Sequence[float]] = None,
               starts_xy: Optional[Sequence[Tuple[float, float]]] = None,
               spacing_m: float = 2000.0, pd: float = 0.8, n_beams: int = 6,
               dwell_s: float = 0.032, truth_dt_s: float = 1.0,
               turns: Optional[Dict[int, Tuple[float, float]]] = None,
               blind: Optional[Dict[int, Sequence[Tuple[float, float]]]] = None,
               seed: int = 0) -> Dict[str, Table]:
    """A scene in the default sensor's geometry, for tracker tests: the same tables as
    :func:`straight_scene`.

    The platform flies east at 150 m/s, ``standoff_m`` south of the scene and ``height_m`` up.
    Plots have the GMTI error shape: slant range σ ``sigma_range_m`` (0.3 m), azimuth σ such that
    the cross-range σ at the scene is ``sigma_cross_m`` (74 m), range rate σ ``sigma_rr_mps``;
    they are geolocated on flat ground (z = 0), so the measured ground position lies on the
    measured range circle.  A revisit has ``n_beams`` dwells ``dwell_s`` apart whose beams
    (half extent = beam spacing) overlap by half: every vehicle is in two adjacent beams and is
    detected in each independently with probability ``pd`` (the adjacent-beam double detections
    of the real sensor).  ``turns``: vehicle -> (t, new heading), an instant turn at constant
    speed.  ``blind``: vehicle -> intervals without detections (outcome 4).
    """
    rng = np.random.default_rng(seed)
    turns = turns or {}
    blind = blind or {}
    ids = np.arange(n_vehicles, dtype=np.int64)
    if headings_rad is None:
        headings_rad = np.radians(np.linspace(20.0, 160.0, n_vehicles))
    heading0 = np.asarray(headings_rad, float)
    if starts_xy is None:
        starts = np.stack([(ids - (n_vehicles - 1) / 2.0) * spacing_m, np.zeros(n_vehicles)], 1)
    else:
        starts = np.asarray(starts_xy, float).reshape(n_vehicles, 2)
    plat_vel = np.array([150.0, 0.0, 0.0])
    plat0 = np.array([-plat_vel[0] * n_revisits * revisit_s / 2.0, -standoff_m, height_m])

    def state(t, v):
        t = np.asarray(t, float)
        t_turn, h1 = turns.get(int(v), (np.inf, heading0[v]))
        u0 = np.array([np.sin(heading0[v]), np.cos(heading0[v])])
        u1 = np.array([np.sin(h1), np.cos(h1)])
        s0 = speed_mps * np.minimum(t, t_turn)
        s1 = speed_mps * np.maximum(t - t_turn, 0.0)
        pos = starts[v] + s0[:, None] * u0 + s1[:, None] * u1
        vel = np.where((t < t_turn)[:, None], speed_mps * u0, speed_mps * u1)
        return pos, vel

    grid = np.arange(0.0, (n_revisits - 1) * revisit_s + 1e-9, truth_dt_s)
    truth = _truth_table(grid, ids, lambda t, v: (*state(t, v), np.ones(len(t), bool)),
                         np.full(len(ids), -1, np.int64))

    revisit, index, t_dw = _dwell_schedule(n_revisits, n_beams, revisit_s, dwell_s)
    plat = plat0[None, :] + t_dw[:, None] * plat_vel[None, :]
    # Beams tile the sector holding every vehicle's whole course, half-overlapping.
    every = np.concatenate([state(grid, v)[0] for v in ids])
    half_width = np.abs(every[:, 0]).max() + 2000.0
    sector = 2.0 * np.arctan2(half_width, standoff_m)
    spacing = sector / n_beams
    beam_az = (frames.heading_rad(-plat[:, 0], -plat[:, 1])
               + (index - (n_beams - 1) / 2.0) * spacing)
    nd = len(t_dw)
    dwells = {
        "dwell_id": np.arange(nd, dtype=np.int64), "revisit_id": revisit.astype(np.int64),
        "dwell_index": index.astype(np.int64), "last_dwell": index == n_beams - 1,
        "time_s": t_dw, "cpi_s": np.full(nd, dwell_s), "beam_scan_rad": np.zeros(nd),
        "beam_az_rad": beam_az,
        "platform_x_m": plat[:, 0], "platform_y_m": plat[:, 1], "platform_z_m": plat[:, 2],
        "platform_vx_mps": np.full(nd, plat_vel[0]), "platform_vy_mps": np.full(nd, plat_vel[1]),
        "platform_vz_mps": np.full(nd, plat_vel[2]),
        "angle_half_extent_rad": np.full(nd, spacing),
        "mdv_mps": np.full(nd, 1.0), "wrap_velocity_mps": np.full(nd, np.nan)}

    sigma_az = sigma_cross_m / np.hypot(standoff_m, height_m)
    det_parts, look_parts = [], []
    for v in ids:
        pos, vel = state(t_dw, v)
        d = np.concatenate([pos - plat[:, :2], -plat[:, 2:3]], axis=1)
        rng_m = np.linalg.norm(d, axis=1)
        az = frames.heading_rad(d[:, 0], d[:, 1])
        w = np.concatenate([vel - plat_vel[None, :2], np.zeros((nd, 1))], axis=1)
        rr = np.einsum("ij,ij->i", d, w) / rng_m
        in_beam = np.abs(frames.wrap_pi(az - beam_az)) <= spacing
        outcome = np.where(rng.uniform(size=nd) < pd, 0, 5).astype(np.uint8)
        for t0, t1 in blind.get(int(v), ()):
            outcome[(t_dw >= t0) & (t_dw <= t1)] = 4
        outcome[~in_beam] = 1
        det = outcome == 0
        n = int(det.sum())
        r_meas = rng_m[det] + rng.normal(0.0, sigma_range_m, n)
        az_meas = az[det] + rng.normal(0.0, sigma_az, n)
        ground = np.sqrt(np.maximum(r_meas ** 2 - plat[det, 2] ** 2, 0.0))
        det_parts.append({
            "dwell_id": np.arange(nd)[det], "time_s": t_dw[det], "range_m": r_meas,
            "azimuth_rad": np.mod(az_meas, 2 * np.pi),
            "range_rate_mps": rr[det] + rng.normal(0.0, sigma_rr_mps, n),
            "true_range_m": rng_m[det], "true_azimuth_rad": az[det],
            "true_range_rate_mps": rr[det], "snr_db": np.full(n, 20.0),
            "sigma_range_m": np.full(n, sigma_range_m), "sigma_azimuth_rad": np.full(n, sigma_az),
            "sigma_range_rate_mps": np.full(n, sigma_rr_mps),
            "x_m": plat[det, 0] + ground * np.sin(az_meas),
            "y_m": plat[det, 1] + ground * np.cos(az_meas),
            "z_m": np.zeros(n), "truth_id": np.full(n, v, np.int64)})
        look_parts.append({"dwell_id": np.flatnonzero(in_beam).astype(np.int64),
                           "vehicle_id": np.full(int(in_beam.sum()), v, np.int64),
                           "time_s": t_dw[in_beam], "outcome": outcome[in_beam],
                           "det_id": np.full(int(in_beam.sum()), -1, np.int64)})
    dets = {k: np.concatenate([p[k] for p in det_parts]) for k in det_parts[0]}
    order = np.lexsort((dets["truth_id"], dets["dwell_id"]))
    dets = {k: c[order] for k, c in dets.items()}
    nd_rows = len(dets["dwell_id"])
    dets["det_id"] = np.arange(nd_rows, dtype=np.int64)
    for name in ("merged", "range_folded", "doppler_wrapped", "implausible"):
        dets[name] = np.zeros(nd_rows, bool)
    looks = {k: np.concatenate([p[k] for p in look_parts]) for k in look_parts[0]}
    order = np.lexsort((looks["vehicle_id"], looks["dwell_id"]))
    looks = {k: c[order] for k, c in looks.items()}
    vehicles = {"vehicle_id": ids, "name": np.array([f"v{i}" for i in ids]),
                "convoy_id": np.full(n_vehicles, -1, np.int64),
                "vehicle_type": np.array(["car"] * n_vehicles),
                "start_time_s": np.zeros(n_vehicles), "route_length_m": np.full(n_vehicles, 1e4),
                "off_road": np.ones(n_vehicles, bool)}
    return {"truth": truth, "vehicles": vehicles, "dwells": dwells, "detections": dets,
            "looks": looks}
