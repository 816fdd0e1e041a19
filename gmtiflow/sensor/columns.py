"""The columns of the sensor's tables, ``/dwells``, ``/detections`` and ``/looks``
(docs/tables.md), with their dtypes.

A module of its own, importing numpy only: readers of a run file (the store's column check,
the report) need the lists without the sensor model, whose merge step imports
``scipy.spatial`` (~0.2 s in a fresh process).  :mod:`gmtiflow.sensor.model` re-exports them.
"""
from __future__ import annotations

import numpy as np

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
