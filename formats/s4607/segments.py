"""Mission, Job Definition, Free Text, Platform Location and Test and Status segments.

Encoders take engineering values (a resolved meta dict or table rows); decoders take the
bodies of every segment of one type at once (a uint8 array of fixed-size records) and return
table columns.  Job Definition "No Statement" sentinels (65535, 255, BA16 0x8000) read as NaN
and NaN is written as the sentinel, so the round trip keeps them.
"""
from __future__ import annotations

import math

import numpy as np

from .layout import (dec_ba, dec_sa, dec_text, dec_text_array, enc_ba32, enc_sa32, enc_ba16,
                     enc_text, lon_180, sat)

MISSION_BODY = np.dtype([
    ("mission_plan", "S12"), ("flight_plan", "S12"), ("platform_type", "u1"),
    ("platform_configuration", "S10"), ("year", ">u2"), ("month", "u1"), ("day", "u1")])
JOB_BODY = np.dtype([
    ("job_id", ">u4"), ("sensor_type", "u1"), ("sensor_model", "S6"), ("target_filtering", "u1"),
    ("priority", "u1"),
    ("a_lat", ">i4"), ("a_lon", ">u4"), ("b_lat", ">i4"), ("b_lon", ">u4"),
    ("c_lat", ">i4"), ("c_lon", ">u4"), ("d_lat", ">i4"), ("d_lon", ">u4"),
    ("radar_mode", "u1"), ("revisit_ds", ">u2"), ("along_dm", ">u2"), ("cross_dm", ">u2"),
    ("alt_dm", ">u2"), ("track_deg", "u1"), ("speed_mmps", ">u2"), ("slant_cm", ">u2"),
    ("cross_ba16", ">u2"), ("los_cmps", ">u2"), ("mdv_dmps", "u1"), ("pd_pct", "u1"),
    ("fa_db", "u1"), ("terrain_model", "u1"), ("geoid_model", "u1")])
PLATFORM_BODY = np.dtype([
    ("time_ms", ">u4"), ("lat", ">i4"), ("lon", ">u4"), ("alt_cm", ">i4"), ("track", ">u2"),
    ("speed_mmps", ">u4"), ("vvel_dmps", "i1")])
TEST_STATUS_BODY = np.dtype([
    ("job_id", ">u4"), ("revisit", ">u2"), ("dwell", ">u2"), ("time_ms", ">u4"),
    ("hardware", "u1"), ("mode", "u1")])
assert (MISSION_BODY.itemsize, JOB_BODY.itemsize, PLATFORM_BODY.itemsize,
        TEST_STATUS_BODY.itemsize) == (39, 68, 23, 14)

# Job Definition nominal accuracies: column, raw field, scale (raw per unit), max written,
# No-Statement sentinel.
JOB_ACCURACIES = (
    ("sigma_along_track_m", "along_dm", 10.0, 65534, 65535),
    ("sigma_cross_track_m", "cross_dm", 10.0, 65534, 65535),
    ("sigma_altitude_m", "alt_dm", 10.0, 65534, 65535),
    ("sigma_track_deg", "track_deg", 1.0, 254, 255),
    ("sigma_speed_mps", "speed_mmps", 1000.0, 65534, 65535),
    ("sigma_slant_range_m", "slant_cm", 100.0, 65534, 65535),
    ("sigma_range_rate_mps", "los_cmps", 100.0, 65534, 65535),
    ("mdv_mps", "mdv_dmps", 10.0, 254, 255),
    ("pd", "pd_pct", 100.0, 254, 255),
)


# ---------------------------------------------------------------------------------------------
# Mission (type 1)
# ---------------------------------------------------------------------------------------------

def mission_body(mission_plan, flight_plan, platform_type, platform_configuration,
                 ref_date) -> bytes:
    b = np.zeros(1, MISSION_BODY)
    b["mission_plan"] = enc_text(mission_plan, 12)
    b["flight_plan"] = enc_text(flight_plan, 12)
    b["platform_type"] = platform_type
    b["platform_configuration"] = enc_text(platform_configuration, 10)
    b["year"], b["month"], b["day"] = ref_date.year, ref_date.month, ref_date.day
    return b.tobytes()


def decode_missions(bodies: np.ndarray) -> dict:
    raw = np.frombuffer(bodies.tobytes(), MISSION_BODY)
    return {"mission_plan": dec_text_array(raw["mission_plan"]),
            "flight_plan": dec_text_array(raw["flight_plan"]),
            "platform_type": raw["platform_type"].astype(np.uint8),
            "platform_configuration": dec_text_array(raw["platform_configuration"]),
            "year": raw["year"].astype(np.int64), "month": raw["month"].astype(np.int64),
            "day": raw["day"].astype(np.int64)}


# ---------------------------------------------------------------------------------------------
# Job Definition (type 5)
# ---------------------------------------------------------------------------------------------

def job_body(m: dict) -> bytes:
    """Job Definition body from a resolved meta dict (``formats.stanag4607.resolve_meta``)."""
    b = np.zeros(1, JOB_BODY)
    b["job_id"] = m["job_id"]
    b["sensor_type"] = m["sensor_type"]
    b["sensor_model"] = enc_text(m["sensor_model"], 6)
    b["target_filtering"] = m["target_filtering"]
    b["priority"] = m["priority"]
    area = m["bounding_area"]
    if len(area) != 4:
        raise ValueError(f"4607 meta: bounding_area needs 4 (lat, lon) corners, got {len(area)}")
    for corner, (lat, lon) in zip("abcd", area):
        b[f"{corner}_lat"] = enc_sa32(lat)
        b[f"{corner}_lon"] = enc_ba32(lon)
    b["radar_mode"] = m["radar_mode"]
    b["revisit_ds"] = int(sat(m["revisit_interval_s"] * 10.0, 0, 65535))
    along, cross, alt = m["sensor_position_sigma_m"]
    b["along_dm"] = _nostat(along, 10.0, 10000, 65535)
    b["cross_dm"] = _nostat(cross, 10.0, 10000, 65535)
    b["alt_dm"] = _nostat(alt, 10.0, 20000, 65535)
    b["track_deg"] = _nostat(m["nominal_track_sigma_deg"], 1.0, 45, 255)
    b["speed_mmps"] = _nostat(m["nominal_speed_sigma_mps"], 1000.0, 65534, 65535)
    b["slant_cm"] = _nostat(m["nominal_slant_range_sigma_m"], 100.0, 65534, 65535)
    cr = m["nominal_cross_range_sigma_deg"]
    b["cross_ba16"] = 0x8000 if cr is None else int(sat(cr * 2.0**16 / 360.0, 0, 0x7FFF))
    b["los_cmps"] = _nostat(m["nominal_range_rate_sigma_mps"], 100.0, 5000, 65535)
    b["mdv_dmps"] = _nostat(m["mdv_mps"], 10.0, 254, 255)
    b["pd_pct"] = _nostat(m["pd"], 100.0, 100, 255)
    fa = m["false_alarm_density_per_m2"]
    b["fa_db"] = 255 if fa is None or not fa > 0 else int(sat(-10.0 * math.log10(fa), 0, 254))
    b["terrain_model"] = m["terrain_model"]
    b["geoid_model"] = m["geoid_model"]
    return b.tobytes()


def _nostat(value, scale, hi, nostat):
    if value is None or not np.isfinite(value):
        return nostat
    return int(sat(value * scale, 0, hi))


def decode_jobs(bodies: np.ndarray) -> dict:
    raw = np.frombuffer(bodies.tobytes(), JOB_BODY)
    t = {"job_id": raw["job_id"].astype(np.int64),
         "sensor_type": raw["sensor_type"].astype(np.uint8),
         "sensor_model": dec_text_array(raw["sensor_model"]),
         "target_filtering": raw["target_filtering"].astype(np.uint8),
         "priority": raw["priority"].astype(np.uint8)}
    for c in "abcd":
        t[f"{c}_lat_deg"] = dec_sa(raw[f"{c}_lat"], 32)
        t[f"{c}_lon_deg"] = lon_180(dec_ba(raw[f"{c}_lon"], 32))
    t["radar_mode"] = raw["radar_mode"].astype(np.uint8)
    t["revisit_interval_s"] = raw["revisit_ds"] / 10.0
    for col, field, scale, _, sentinel in JOB_ACCURACIES:
        v = raw[field].astype(np.float64)
        t[col] = np.where(v == sentinel, np.nan, v / scale)
    t["sigma_cross_range_deg"] = np.where(raw["cross_ba16"] == 0x8000, np.nan,
                                          dec_ba(raw["cross_ba16"], 16))
    fa = raw["fa_db"].astype(np.float64)
    t["false_alarm_density_per_m2"] = np.where(fa == 255, np.nan, 10.0 ** (-fa / 10.0))
    t["terrain_model"] = raw["terrain_model"].astype(np.uint8)
    t["geoid_model"] = raw["geoid_model"].astype(np.uint8)
    return t


def encode_jobs(jobs: dict, rows: np.ndarray) -> np.ndarray:
    """Job Definition bodies (structured array) of ``rows`` of a table read by
    :func:`decode_jobs`: the inverse of the decoder, raw for raw on what it decoded."""
    n = len(rows)
    b = np.zeros(n, JOB_BODY)

    def col(name):
        return np.asarray(jobs[name])[rows]

    b["job_id"] = col("job_id")
    b["sensor_type"] = col("sensor_type")
    b["sensor_model"] = [enc_text(s, 6) for s in col("sensor_model")]
    b["target_filtering"] = col("target_filtering")
    b["priority"] = col("priority")
    for c in "abcd":
        b[f"{c}_lat"] = enc_sa32(col(f"{c}_lat_deg"))
        b[f"{c}_lon"] = enc_ba32(col(f"{c}_lon_deg"))
    b["radar_mode"] = col("radar_mode")
    b["revisit_ds"] = sat(np.asarray(col("revisit_interval_s"), float) * 10.0, 0, 65535)
    for name, field, scale, _, sentinel in JOB_ACCURACIES:
        v = np.asarray(col(name), float)
        b[field] = np.where(np.isfinite(v), sat(v * scale, 0, sentinel), sentinel)
    cr = np.asarray(col("sigma_cross_range_deg"), float)
    b["cross_ba16"] = np.where(np.isfinite(cr), enc_ba16(cr), 0x8000)
    fa = np.asarray(col("false_alarm_density_per_m2"), float)
    with np.errstate(divide="ignore", invalid="ignore"):
        b["fa_db"] = np.where(fa > 0, sat(-10.0 * np.log10(fa), 0, 255), 255)
    b["terrain_model"] = col("terrain_model")
    b["geoid_model"] = col("geoid_model")
    return b


# ---------------------------------------------------------------------------------------------
# Free Text (type 6)
# ---------------------------------------------------------------------------------------------

def free_text_body(originator: str, recipient: str, text: str) -> bytes:
    return enc_text(originator, 10) + enc_text(recipient, 10) + str(text).encode("latin-1",
                                                                                   "replace")


def decode_free_text(body: bytes) -> tuple:
    """(originator, recipient, text): the text up to a NUL (real recorders send C strings)."""
    return dec_text(body[:10]), dec_text(body[10:20]), body[20:].split(b"\x00", 1)[0].decode(
        "latin-1")


# ---------------------------------------------------------------------------------------------
# Platform Location (type 13) and Test and Status (type 10)
# ---------------------------------------------------------------------------------------------

def platform_records(time_ms, lat_deg, lon_deg, height_m, vx_mps, vy_mps, vz_mps) -> np.ndarray:
    """Platform Location bodies: track and speed of the horizontal velocity (vx east, vy north)."""
    n = len(np.atleast_1d(time_ms))
    a = np.zeros(n, PLATFORM_BODY)
    a["time_ms"] = sat(time_ms, 0, 2**32 - 1)
    a["lat"] = enc_sa32(lat_deg)
    a["lon"] = enc_ba32(lon_deg)
    a["alt_cm"] = sat(np.asarray(height_m, float) * 100.0, -2**31, 2**31 - 1)
    vx, vy, vz = (np.asarray(v, float) for v in (vx_mps, vy_mps, vz_mps))
    a["track"] = enc_ba16(np.degrees(np.arctan2(vx, vy)))
    a["speed_mmps"] = sat(np.hypot(vx, vy) * 1000.0, 0, 2**32 - 1)
    a["vvel_dmps"] = sat(vz * 10.0, -128, 127)
    return a


def decode_platform(bodies: np.ndarray) -> dict:
    raw = np.frombuffer(bodies.tobytes(), PLATFORM_BODY)
    speed = raw["speed_mmps"] / 1000.0
    track = np.radians(dec_ba(raw["track"], 16))
    return {"time_ms": raw["time_ms"].astype(np.int64),
            "lat_deg": dec_sa(raw["lat"], 32), "lon_deg": lon_180(dec_ba(raw["lon"], 32)),
            "height_m": raw["alt_cm"] / 100.0, "track_rad": track, "speed_mps": speed,
            "vx_mps": speed * np.sin(track), "vy_mps": speed * np.cos(track),
            "vz_mps": raw["vvel_dmps"] / 10.0}


def decode_test_status(bodies: np.ndarray) -> dict:
    raw = np.frombuffer(bodies.tobytes(), TEST_STATUS_BODY)
    return {"job_id": raw["job_id"].astype(np.int64), "revisit_id": raw["revisit"].astype(np.int64),
            "dwell_index": raw["dwell"].astype(np.int64), "time_ms": raw["time_ms"].astype(np.int64),
            "hardware_status": raw["hardware"].astype(np.uint8),
            "mode_status": raw["mode"].astype(np.uint8)}


def encode_test_status(t: dict, rows) -> np.ndarray:
    a = np.zeros(len(rows), TEST_STATUS_BODY)
    for col, field in (("job_id", "job_id"), ("revisit_id", "revisit"), ("dwell_index", "dwell"),
                       ("time_ms", "time_ms"), ("hardware_status", "hardware"),
                       ("mode_status", "mode")):
        a[field] = np.asarray(t[col])[rows]
    return a
