"""Synthetic /dwells, /detections, /truth and /tracks tables for tests, examples and benchmarks.

Plausible, not physical: a platform flying a straight line near (lat0, lon0) scanning a sector,
detections scattered inside each dwell's footprint with consistent range/azimuth/lat/lon.  The
converters are checked against these tables, never the simulation itself (``formats`` never
imports gmtiflow).
"""
from __future__ import annotations

import numpy as np

EPOCH_UTC = "2026-11-21T13:00:00.250Z"


def tables(n_dwells: int = 20, n_detections: int = 200, *, seed: int = 0,
           lat0: float = 43.74, lon0: float = 7.42, dwells_per_revisit: int = 7,
           dwell_period_s: float = 0.5) -> tuple[dict, dict]:
    """(dwells, detections) with the docs/tables.md columns; some dwells have no detections."""
    rng = np.random.default_rng(seed)
    i = np.arange(n_dwells)
    t = i * dwell_period_s + 0.013
    speed = 120.0
    heading = np.radians(80.0)
    vx, vy = speed * np.sin(heading), speed * np.cos(heading)
    x, y = vx * t - 30_000.0, vy * t - 40_000.0
    m_per_deg_lat = 111_132.0
    m_per_deg_lon = 111_320.0 * np.cos(np.radians(lat0))
    plat_lat = lat0 + y / m_per_deg_lat
    plat_lon = lon0 + x / m_per_deg_lon
    beam_az = np.radians(30.0) + np.radians(4.0) * (i % dwells_per_revisit)
    ground_range = 50_000.0
    area_lat = plat_lat + ground_range * np.cos(beam_az) / m_per_deg_lat
    area_lon = plat_lon + ground_range * np.sin(beam_az) / m_per_deg_lon
    dwells = {
        "dwell_id": i.astype(np.int64),
        "revisit_id": (i // dwells_per_revisit).astype(np.int64),
        "dwell_index": (i % dwells_per_revisit).astype(np.int64),
        "last_dwell": (i % dwells_per_revisit) == dwells_per_revisit - 1,
        "time_s": t,
        "cpi_s": np.full(n_dwells, 0.05),
        "beam_scan_rad": beam_az - heading,
        "beam_az_rad": beam_az,
        "platform_x_m": x, "platform_y_m": y, "platform_z_m": np.full(n_dwells, 7000.0),
        "platform_vx_mps": np.full(n_dwells, vx), "platform_vy_mps": np.full(n_dwells, vy),
        "platform_vz_mps": rng.uniform(-2, 2, n_dwells),
        "platform_heading_rad": np.full(n_dwells, heading),
        "platform_pitch_rad": np.radians(rng.uniform(-3, 3, n_dwells)),
        "platform_bank_rad": np.radians(rng.uniform(-20, 20, n_dwells)),
        "platform_lat_deg": plat_lat, "platform_lon_deg": plat_lon,
        "platform_height_m": np.full(n_dwells, 7050.0) + rng.uniform(-5, 5, n_dwells),
        "area_lat_deg": area_lat, "area_lon_deg": area_lon,
        "range_half_extent_m": np.full(n_dwells, 5_000.0),
        "angle_half_extent_rad": np.full(n_dwells, np.radians(2.0)),
        "mdv_mps": np.full(n_dwells, 1.5),
        "wrap_velocity_mps": np.full(n_dwells, 75.0),
    }
    # Detections: dwells drawn with a few empty ones; sorted by dwell.
    weights = rng.uniform(0, 1, n_dwells)
    weights[rng.uniform(size=n_dwells) < 0.2] = 0.0
    if weights.sum() == 0:
        weights[:] = 1.0
    dwell = np.sort(rng.choice(n_dwells, size=n_detections, p=weights / weights.sum()))
    n = n_detections
    az = beam_az[dwell] + rng.uniform(-np.radians(2), np.radians(2), n)
    gr = ground_range + rng.uniform(-5000, 5000, n)
    lat = plat_lat[dwell] + gr * np.cos(az) / m_per_deg_lat
    lon = plat_lon[dwell] + gr * np.sin(az) / m_per_deg_lon
    h = rng.uniform(-20, 600, n)
    rngm = np.hypot(gr, 7050.0 - h)
    truth = rng.integers(0, 40, n)
    truth[rng.uniform(size=n) < 0.1] = -1
    dets = {
        "det_id": np.arange(n, dtype=np.int64),
        "dwell_id": dwell.astype(np.int64),
        "time_s": t[dwell],
        "range_m": rngm, "azimuth_rad": np.mod(az, 2 * np.pi),
        "range_rate_mps": rng.uniform(-60, 60, n),
        "true_range_m": rngm + rng.normal(0, 10, n),
        "true_azimuth_rad": np.mod(az + rng.normal(0, 1e-3, n), 2 * np.pi),
        "true_range_rate_mps": rng.uniform(-60, 60, n),
        "snr_db": rng.uniform(10, 40, n),
        "sigma_range_m": rng.uniform(5, 20, n),
        "sigma_azimuth_rad": rng.uniform(1e-3, 3e-3, n),
        "sigma_range_rate_mps": rng.uniform(0.3, 1.5, n),
        "x_m": x[dwell] + gr * np.sin(az), "y_m": y[dwell] + gr * np.cos(az), "z_m": h - 50.0,
        "lat_deg": lat, "lon_deg": lon, "height_m": h,
        "truth_id": truth.astype(np.int64),
        "merged": rng.uniform(size=n) < 0.05,
        "range_folded": np.zeros(n, bool),
        "doppler_wrapped": rng.uniform(size=n) < 0.02,
        "implausible": np.zeros(n, bool),
        "rcs_dbsm": rng.uniform(-5, 25, n),
        "wrap_velocity_mps": np.full(n, 75.0),
    }
    # STANAG 4607 D32.7: the LOS velocity corrected for platform motion (the target's own
    # radial speed), a column of its own beside the full range rate
    dets["los_velocity_mps"] = rng.uniform(-30, 30, n)
    return dwells, dets


def truth(n_vehicles: int = 5, n_times: int = 20, *, seed: int = 0,
          lat0: float = 43.74, lon0: float = 7.42) -> dict:
    """A /truth table (plus lat_deg lon_deg height_m) sorted by time then vehicle."""
    rng = np.random.default_rng(seed)
    tt, vv = np.meshgrid(np.arange(n_times) * 1.0, np.arange(n_vehicles), indexing="ij")
    tt, vv = tt.ravel(), vv.ravel()
    n = len(tt)
    speed = 10.0 + vv
    heading = np.radians(30.0 * vv)
    x = 100.0 * vv + speed * np.sin(heading) * tt
    y = -50.0 * vv + speed * np.cos(heading) * tt
    return {
        "time_s": tt, "vehicle_id": vv.astype(np.int64),
        "convoy_id": np.where(vv < 2, 0, -1).astype(np.int64),
        "x_m": x, "y_m": y, "z_m": rng.uniform(0, 50, n),
        "vx_mps": speed * np.sin(heading), "vy_mps": speed * np.cos(heading), "vz_mps": np.zeros(n),
        "ax_mps2": np.zeros(n), "ay_mps2": np.zeros(n), "az_mps2": np.zeros(n),
        "speed_mps": speed, "heading_rad": heading, "route_s_m": speed * tt,
        "edge_id": rng.integers(-1, 30, n).astype(np.int64),
        "mode": rng.integers(0, 4, n).astype(np.uint8),
        "invisible": rng.uniform(size=n) < 0.1,
        "lat_deg": lat0 + y / 111_132.0, "lon_deg": lon0 + x / 80_000.0,
        "height_m": rng.uniform(0, 300, n),
    }


def tracks(n_tracks: int = 3, n_times: int = 10, *, seed: int = 0) -> dict:
    """A /tracks table."""
    rng = np.random.default_rng(seed)
    tt, kk = np.meshgrid(np.arange(n_times) * 2.0, np.arange(n_tracks), indexing="ij")
    n = tt.size
    return {
        "track_id": kk.ravel().astype(np.int64), "time_s": tt.ravel(),
        "x_m": rng.normal(0, 1000, n), "y_m": rng.normal(0, 1000, n),
        "vx_mps": rng.normal(0, 10, n), "vy_mps": rng.normal(0, 10, n),
        "cov_xx_m2": rng.uniform(10, 100, n), "cov_xy_m2": rng.uniform(-5, 5, n),
        "cov_yy_m2": rng.uniform(10, 100, n), "range_rate_mps": rng.normal(0, 10, n),
        "confirmed": rng.uniform(size=n) < 0.7,
    }
