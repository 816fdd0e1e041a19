"""STANAG 4607 / AEDP-4607 (GMTIF) writer and reader.

Layout, scalings and rules follow ``shared/reference/stanag4607.md`` (AEDP-4607 Ed. A v1, whose
field layout equals STANAG 4607 Ed. 3).  All multi-byte fields are big-endian.

Writer (:func:`write_4607`, :func:`encode_4607`)
------------------------------------------------
One segment per packet, every packet <= 65,535 bytes (AEDP-4607.1 G.7.3 minimum capability).
Stream: ``Mission, Job Definition, [Free Text with the scene epoch, first time only]``, then the
Dwell packets; Mission + Job Definition are repeated at the start of every revisit and before any
dwell that comes >= 30 s after the last repetition (SPEC 3.3: Mission every 2 min; 3.7: Job
Definition every 30 s).  Mission, Job Definition, Free Text and Platform Location packets carry
P10 = 0 and Dwell packets P10 = job id (SPEC 3.1.10).  Every dwell is sent, even without targets.

A dwell with more reports than fit in one packet is split into several Dwell packets that repeat
the dwell fields and the dwell index, carry on the D32.1 MTI report index (GUIDE Annex D), and set
D4 (last dwell of revisit) only on the final piece, so a streaming consumer never sees "revisit
complete" before the revisit's last report.

Dwell mask written: D2-D9, D12-D17, D21-D27, D31 (sensor position sigma D12-D14 are sent because
D32.12-D32.15 may only be sent with them).  Target mask: D32.1, D32.2/3 (hi-res position) and,
for each optional detection column present, its field: D32.6 ``height_m``, D32.7/8
``range_rate_mps`` (+ ``wrap_velocity_mps`` from the detection or its dwell; NaN -> 0 = unknown),
D32.9 ``snr_db``, D32.10 classification (``meta['target_classification']``, default 255 =
Unknown-simulated), D32.12 ``sigma_range_m``, D32.13 cross-range sigma = ``range_m *
sigma_azimuth_rad`` (or ``sigma_cross_range_m``), D32.14 ``sigma_height_m``, D32.15
``sigma_range_rate_mps``, D32.16/17 truth tag from ``truth_id``, D32.18 ``rcs_dbsm``.

Truth tag: D32.16 = ``meta['truth_tag_application']`` (default 1), D32.17 = ``truth_id``;
a false alarm (``truth_id == -1``) is sent as entity 0xFFFFFFFF, i.e. -1 read as a two's
complement I32.  Every value is rounded to the field's quantum and saturated to the field's range
(the ranges in the reference tables; NaN -> 0 except where noted), see ``docs/formats.md``.

Reader (:func:`iter_packets`, :func:`read_4607`)
------------------------------------------------
Parses any conforming file: every segment is framed by its S2 size, unknown types are skipped,
dwells are decoded for any existence mask (per-mask structured dtypes, targets decoded
vectorised), hi-res or reduced-resolution (D10/D11 + D32.4/5) positions, D5 = 0 with D32 bits
set.  Malformed input raises :class:`~formats.errors.FormatError` naming the byte offset.
The file is read in bounded chunks, so a lying P2/S2 never makes the reader allocate more than
the file holds.
"""
from __future__ import annotations

import io
import math
import os
from dataclasses import dataclass
from datetime import date, datetime, timedelta, timezone
from functools import lru_cache
from typing import Iterator, Mapping

import numpy as np

from ._io import n_rows, parse_epoch, source_name, write_atomic
from .errors import FormatError, where

__all__ = [
    "write_4607", "encode_4607", "resolve_meta", "platform_location_packets", "iter_packets", "read_4607",
    "Packet", "Segment", "DEFAULT_META", "MAX_PACKET_BYTES",
    "dwell_mask_bit", "target_mask_bit",
]

MAX_PACKET_BYTES = 65_535
PACKET_HEADER = np.dtype([
    ("version", "S2"), ("size", ">u4"), ("nationality", "S2"), ("classification", "u1"),
    ("class_system", "S2"), ("security_codes", ">u2"), ("exercise", "u1"),
    ("platform_id", "S10"), ("mission_id", ">u4"), ("job_id", ">u4"),
])
SEGMENT_HEADER = np.dtype([("seg_type", "u1"), ("seg_size", ">u4")])
assert PACKET_HEADER.itemsize == 32 and SEGMENT_HEADER.itemsize == 5

MISSION, DWELL, HRR, JOB_DEFINITION, FREE_TEXT, TEST_STATUS, PROC_HISTORY, PLATFORM_LOCATION = (
    1, 2, 3, 5, 6, 10, 12, 13)

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
assert (MISSION_BODY.itemsize, JOB_BODY.itemsize, PLATFORM_BODY.itemsize) == (39, 68, 23)
FIXED_BODY_SIZES = {MISSION: 39, JOB_DEFINITION: 68, PLATFORM_LOCATION: 23, TEST_STATUS: 14}

# D2..D31: (field number, key, wire dtype)
DWELL_FIELDS = (
    (2, "revisit", ">u2"), (3, "dwell", ">u2"), (4, "last", "u1"), (5, "count", ">u2"),
    (6, "time_ms", ">u4"), (7, "lat", ">i4"), (8, "lon", ">u4"), (9, "alt_cm", ">i4"),
    (10, "lat_scale", ">i4"), (11, "lon_scale", ">u4"), (12, "unc_along_cm", ">u4"),
    (13, "unc_cross_cm", ">u4"), (14, "unc_alt_cm", ">u2"), (15, "track", ">u2"),
    (16, "speed_mmps", ">u4"), (17, "vvel_dmps", "i1"), (18, "unc_track_deg", "u1"),
    (19, "unc_speed_mmps", ">u2"), (20, "unc_vvel_cmps", ">u2"), (21, "heading", ">u2"),
    (22, "pitch", ">i2"), (23, "roll", ">i2"), (24, "area_lat", ">i4"), (25, "area_lon", ">u4"),
    (26, "range_half", ">u2"), (27, "angle_half", ">u2"), (28, "sensor_heading", ">u2"),
    (29, "sensor_pitch", ">i2"), (30, "sensor_roll", ">i2"), (31, "mdv_dmps", "u1"),
)
# D32.1..D32.18
TARGET_FIELDS = (
    (1, "mti_index", ">u2"), (2, "hr_lat", ">i4"), (3, "hr_lon", ">u4"), (4, "d_lat", ">i2"),
    (5, "d_lon", ">i2"), (6, "height_m", ">i2"), (7, "los_cmps", ">i2"), (8, "wrap_cmps", ">u2"),
    (9, "snr_db", "i1"), (10, "class", "u1"), (11, "class_prob", "u1"), (12, "sr_cm", ">u2"),
    (13, "cr_dm", ">u2"), (14, "h_m", "u1"), (15, "rv_cmps", ">u2"), (16, "tt_app", "u1"),
    (17, "tt_entity", ">u4"), (18, "rcs_hdb", "i1"),
)
MANDATORY_DWELL = (2, 3, 4, 5, 6, 7, 8, 9, 24, 25, 26, 27)


def dwell_mask_bit(n: int) -> int:
    """Existence-mask bit of dwell field Dn (n = 2..31)."""
    return 1 << (65 - n)


def target_mask_bit(k: int) -> int:
    """Existence-mask bit of target field D32.k (k = 1..18)."""
    return 1 << (34 - k)


# ---------------------------------------------------------------------------------------------
# Scalings (reference §1.1).  enc_*: engineering value -> raw integer array, rounded to the
# nearest quantum and saturated to the field range; dec_*: raw -> float64.
# ---------------------------------------------------------------------------------------------

def _sat(x, lo, hi, nan=0):
    x = np.asarray(x, dtype=np.float64)
    return np.clip(np.rint(np.where(np.isfinite(x), x, nan)), lo, hi).astype(np.int64)


def enc_ba32(deg):
    d = np.asarray(deg, dtype=np.float64)
    return (_sat(np.mod(np.where(np.isfinite(d), d, 0.0), 360.0) * (2.0**32 / 360.0), 0, 2**32)
            % 2**32)


def enc_sa32(deg):
    return _sat(np.asarray(deg, dtype=np.float64) * (2.0**32 / 180.0), -2**31, 2**31 - 1)


def enc_ba16(deg):
    d = np.asarray(deg, dtype=np.float64)
    return _sat(np.mod(np.where(np.isfinite(d), d, 0.0), 360.0) * (2.0**16 / 360.0), 0, 2**16) % 2**16


def enc_sa16(deg):
    return _sat(np.asarray(deg, dtype=np.float64) * (2.0**16 / 180.0), -2**15, 2**15 - 1)


def enc_b16(x):
    """B16 sign-magnitude (1 sign, 8 integer, 7 fraction bits)."""
    x = np.asarray(x, dtype=np.float64)
    mag = _sat(np.abs(x) * 128.0, 0, 0x7FFF)
    return np.where((x < 0) & (mag > 0), mag | 0x8000, mag)


def dec_ba(raw, bits):
    return np.asarray(raw, dtype=np.float64) * (360.0 / 2.0**bits)


def dec_sa(raw, bits):
    return np.asarray(raw, dtype=np.float64) * (180.0 / 2.0**bits)


def dec_b16(raw):
    raw = np.asarray(raw, dtype=np.int64)
    mag = (raw & 0x7FFF) / 128.0
    return np.where(raw & 0x8000, -mag, mag)


def lon_180(deg):
    """Longitude in [-180, 180) from a BA value in [0, 360)."""
    deg = np.asarray(deg, dtype=np.float64)
    return np.where(deg >= 180.0, deg - 360.0, deg)


# ---------------------------------------------------------------------------------------------
# Writer
# ---------------------------------------------------------------------------------------------

DEFAULT_META: dict = {
    # Packet header
    "nationality": "XN",                # P3 digraph
    "classification": 5,                # P4: 5 = UNCLASSIFIED
    "classification_system": "XN",      # P5
    "security_codes": 0,                # P6
    "exercise_indicator": 129,          # P7: Exercise, Simulated
    "platform_id": "GMTIFLOW",          # P8 (A10)
    "mission_id": 1,                    # P9
    "job_id": 1,                        # P10 on dwell packets, J1
    # Mission
    "mission_plan": "SIMULATION",       # M1 (A12)
    "flight_plan": "",                  # M2 (A12)
    "platform_type": 255,               # M3: 255 = Other
    "platform_configuration": "",       # M4 (A10)
    # Job definition
    "sensor_type": 255,                 # J2: 255 = No Statement
    "sensor_model": "GMTIFL",           # J3 (A6)
    "target_filtering": 0,              # J4
    "priority": 1,                      # J5
    "bounding_area": None,              # J6-J13: 4 (lat, lon) deg clockwise; None = box around dwells
    "radar_mode": 1,                    # J14: 1 = generic MTI
    "revisit_interval_s": None,         # J15: None = median revisit period of the dwells (0 if one)
    "sensor_position_sigma_m": (0.0, 0.0, 0.0),  # along, cross, alt: D12-D14 and J16-J18
    "nominal_track_sigma_deg": None,    # J19   (None = No Statement)
    "nominal_speed_sigma_mps": None,    # J20
    "nominal_slant_range_sigma_m": None,  # J21
    "nominal_cross_range_sigma_deg": None,  # J22
    "nominal_range_rate_sigma_mps": None,   # J23
    "mdv_mps": None,                    # J24 (None = median of the dwells' mdv_mps)
    "pd": None,                         # J25, probability 0..1 for a 10 m^2 target
    "false_alarm_density_per_m2": None,  # J26 = -10 log10(density)
    "terrain_model": 0,                 # J27: 0 = none
    "geoid_model": 0,                   # J28: 0 = none (heights are WGS-84 ellipsoidal)
    # Targets
    "target_classification": 255,       # D32.10: 255 = Unknown, simulated
    "truth_tag_application": 1,         # D32.16
    # Free text
    "write_epoch_text": True,           # a Free Text segment "scene_epoch_utc=<ISO>" after the first Job
}
REQUIRED_META = ("epoch_utc",)
JOB_RESEND_S = 30.0


def _meta(meta: Mapping) -> dict:
    unknown = set(meta) - set(DEFAULT_META) - set(REQUIRED_META)
    if unknown:
        raise ValueError(f"4607 meta: unknown keys {sorted(unknown)}; known: "
                         f"{sorted(set(DEFAULT_META) | set(REQUIRED_META))}")
    if "epoch_utc" not in meta:
        raise ValueError("4607 meta: 'epoch_utc' (ISO-8601 UTC scene start) is required: "
                         "dwell times are counted from 00:00 UTC of its date")
    m = dict(DEFAULT_META)
    m.update(meta)
    m["epoch"] = parse_epoch(m["epoch_utc"])
    if not 1 <= int(m["job_id"]) <= 2**32 - 1:
        raise ValueError(f"4607 meta: job_id must be in 1..2^32-1, got {m['job_id']}")
    return m


def _text(s, n: int) -> bytes:
    """A(n) field: ASCII, space-padded, truncated to n bytes."""
    b = str(s if s is not None else "").encode("ascii", "replace")[:n]
    return b.ljust(n, b" ")


def _nostat(value, scale, hi, nostat):
    if value is None or not np.isfinite(value):
        return nostat
    return int(_sat(value * scale, 0, hi))


def _packet_header(m: dict, edition: str, size: int, job_id: int) -> np.ndarray:
    h = np.zeros(1, PACKET_HEADER)
    h["version"] = edition.encode("ascii")
    h["size"] = size
    h["nationality"] = _text(m["nationality"], 2)
    h["classification"] = m["classification"]
    h["class_system"] = _text(m["classification_system"], 2)
    h["security_codes"] = m["security_codes"]
    h["exercise"] = m["exercise_indicator"]
    h["platform_id"] = _text(m["platform_id"], 10)
    h["mission_id"] = m["mission_id"]
    h["job_id"] = job_id
    return h


def _single_segment_packet(m, edition, seg_type, body: bytes, job_id=0) -> bytes:
    size = 32 + 5 + len(body)
    seg = np.zeros(1, SEGMENT_HEADER)
    seg["seg_type"], seg["seg_size"] = seg_type, 5 + len(body)
    return _packet_header(m, edition, size, job_id).tobytes() + seg.tobytes() + body


def _mission_body(m: dict) -> bytes:
    b = np.zeros(1, MISSION_BODY)
    ref = m["epoch"].date()
    b["mission_plan"] = _text(m["mission_plan"], 12)
    b["flight_plan"] = _text(m["flight_plan"], 12)
    b["platform_type"] = m["platform_type"]
    b["platform_configuration"] = _text(m["platform_configuration"], 10)
    b["year"], b["month"], b["day"] = ref.year, ref.month, ref.day
    return b.tobytes()


def resolve_meta(meta: Mapping, dwells: Mapping, detections: Mapping) -> dict:
    """The meta dict with defaults applied and the data-derived defaults filled in.

    ``bounding_area`` None -> the box (clockwise from the north-west corner) around the dwell
    area centres, platform positions and detections; ``revisit_interval_s`` None -> median time
    between revisit starts (0 for a single revisit); ``mdv_mps`` None -> median of the dwells'
    ``mdv_mps`` (No Statement if they have none).  Adds ``epoch`` (aware datetime).
    """
    m = _meta(meta)
    if m["bounding_area"] is None:
        lats = np.concatenate([np.asarray(dwells.get("area_lat_deg", []), float),
                               np.asarray(dwells.get("platform_lat_deg", []), float),
                               np.asarray(detections.get("lat_deg", []), float)])
        lons = np.concatenate([np.asarray(dwells.get("area_lon_deg", []), float),
                               np.asarray(dwells.get("platform_lon_deg", []), float),
                               np.asarray(detections.get("lon_deg", []), float)])
        ok = np.isfinite(lats) & np.isfinite(lons)
        if ok.any():
            s, n = float(lats[ok].min()), float(lats[ok].max())
            w, e = float(lons[ok].min()), float(lons[ok].max())
        else:
            s = n = w = e = 0.0
        m["bounding_area"] = [(n, w), (n, e), (s, e), (s, w)]
    if m["revisit_interval_s"] is None:
        m["revisit_interval_s"] = _median_revisit_s(dwells)
    if m["mdv_mps"] is None and "mdv_mps" in dwells and len(dwells["mdv_mps"]):
        mdv = np.asarray(dwells["mdv_mps"], float)
        m["mdv_mps"] = float(np.median(mdv[np.isfinite(mdv)])) if np.isfinite(mdv).any() else None
    return m


def _job_body(m: dict) -> bytes:
    b = np.zeros(1, JOB_BODY)
    b["job_id"] = m["job_id"]
    b["sensor_type"] = m["sensor_type"]
    b["sensor_model"] = _text(m["sensor_model"], 6)
    b["target_filtering"] = m["target_filtering"]
    b["priority"] = m["priority"]
    area = m["bounding_area"]
    if len(area) != 4:
        raise ValueError(f"4607 meta: bounding_area needs 4 (lat, lon) corners, got {len(area)}")
    for corner, (lat, lon) in zip("abcd", area):
        b[f"{corner}_lat"] = enc_sa32(lat)
        b[f"{corner}_lon"] = enc_ba32(lon)
    b["radar_mode"] = m["radar_mode"]
    b["revisit_ds"] = int(_sat(m["revisit_interval_s"] * 10.0, 0, 65535))
    along, cross, alt = m["sensor_position_sigma_m"]
    b["along_dm"] = _nostat(along, 10.0, 10000, 65535)
    b["cross_dm"] = _nostat(cross, 10.0, 10000, 65535)
    b["alt_dm"] = _nostat(alt, 10.0, 20000, 65535)
    b["track_deg"] = _nostat(m["nominal_track_sigma_deg"], 1.0, 45, 255)
    b["speed_mmps"] = _nostat(m["nominal_speed_sigma_mps"], 1000.0, 65534, 65535)
    b["slant_cm"] = _nostat(m["nominal_slant_range_sigma_m"], 100.0, 65534, 65535)
    cr = m["nominal_cross_range_sigma_deg"]
    b["cross_ba16"] = 0x8000 if cr is None else int(_sat(cr * 2.0**16 / 360.0, 0, 0x7FFF))
    b["los_cmps"] = _nostat(m["nominal_range_rate_sigma_mps"], 100.0, 5000, 65535)
    b["mdv_dmps"] = _nostat(m["mdv_mps"], 10.0, 254, 255)
    b["pd_pct"] = _nostat(m["pd"], 100.0, 100, 255)
    fa = m["false_alarm_density_per_m2"]
    b["fa_db"] = 255 if fa is None or not fa > 0 else int(_sat(-10.0 * math.log10(fa), 0, 254))
    b["terrain_model"] = m["terrain_model"]
    b["geoid_model"] = m["geoid_model"]
    return b.tobytes()


def _median_revisit_s(dwells) -> float:
    if "revisit_id" not in dwells or len(dwells["revisit_id"]) == 0:
        return 0.0
    rev = np.asarray(dwells["revisit_id"])
    t = np.asarray(dwells["time_s"], dtype=np.float64)
    starts = np.flatnonzero(np.r_[True, rev[1:] != rev[:-1]])
    if len(starts) < 2:
        return 0.0
    return float(np.median(np.diff(t[starts])))


def _free_text_body(text: str) -> bytes:
    return _text("GMTIFLOW", 10) + _text("ALL", 10) + text.encode("ascii", "replace")


def _col(table, name, n, default=np.nan):
    if name in table:
        return np.asarray(table[name])
    return np.full(n, default)


def _dwell_dtype(fields) -> np.dtype:
    return np.dtype([(name, fmt) for _, name, fmt in fields])


WRITE_DWELL_FIELDS = tuple(f for f in DWELL_FIELDS
                           if f[0] in (2, 3, 4, 5, 6, 7, 8, 9, 12, 13, 14, 15, 16, 17,
                                       21, 22, 23, 24, 25, 26, 27, 31))
WRITE_DWELL_MASK = sum(dwell_mask_bit(n) for n, _, _ in WRITE_DWELL_FIELDS)


def _target_columns(detections, dwells) -> list[int]:
    """D32 fields written for the columns this detection table has."""
    have = set(detections)
    fields = [1, 2, 3]
    if "height_m" in have:
        fields.append(6)
    if "range_rate_mps" in have:
        fields += [7, 8]
    if "snr_db" in have:
        fields.append(9)
    fields.append(10)
    if "sigma_range_m" in have:
        fields.append(12)
    if "sigma_cross_range_m" in have or {"range_m", "sigma_azimuth_rad"} <= have:
        fields.append(13)
    if "sigma_height_m" in have and "height_m" in have:
        fields.append(14)
    if "sigma_range_rate_mps" in have and "range_rate_mps" in have:
        fields.append(15)
    if "truth_id" in have:
        fields += [16, 17]
    if "rcs_dbsm" in have:
        fields.append(18)
    return fields


def encode_4607(dwells: Mapping[str, np.ndarray], detections: Mapping[str, np.ndarray],
                meta: Mapping, *, edition: str = "30",
                platform: Mapping[str, np.ndarray] | None = None) -> bytes:
    """The bytes of a 4607 file for these tables (see the module docstring and docs/formats.md).

    ``dwells`` needs ``dwell_id revisit_id dwell_index last_dwell time_s platform_lat_deg
    platform_lon_deg platform_height_m area_lat_deg area_lon_deg range_half_extent_m
    angle_half_extent_rad``; ``platform_vx_mps ... platform_bank_rad mdv_mps`` are used when
    present (0 otherwise).  ``detections`` needs ``dwell_id lat_deg lon_deg``; the optional
    columns each add their D32 field.  ``platform`` (a /platform table) adds Platform Location
    packets, interleaved by time.
    """
    if edition not in ("30", "41"):
        raise ValueError(f"4607 edition must be '30' (STANAG 4607 Ed. 3) or '41' (AEDP-4607 Ed. A "
                         f"v1), got {edition!r}")
    m = resolve_meta(meta, dwells, detections)
    nd = n_rows(dwells, "dwells")
    nt = n_rows(detections, "detections")
    for col in ("dwell_id", "revisit_id", "dwell_index", "last_dwell", "time_s",
                "platform_lat_deg", "platform_lon_deg", "platform_height_m", "area_lat_deg",
                "area_lon_deg", "range_half_extent_m", "angle_half_extent_rad"):
        if col not in dwells and nd:
            raise ValueError(f"4607 writer: dwells table lacks column {col!r}")
    for col in ("dwell_id", "lat_deg", "lon_deg"):
        if col not in detections and nt:
            raise ValueError(f"4607 writer: detections table lacks column {col!r}")

    epoch = m["epoch"]
    midnight = datetime(epoch.year, epoch.month, epoch.day, tzinfo=timezone.utc)
    epoch_sod = (epoch - midnight) / timedelta(seconds=1)

    # --- order the dwells by time (stable) and attach every detection to its dwell row -------
    d_time = np.asarray(_col(dwells, "time_s", nd), dtype=np.float64)
    d_order = np.argsort(d_time, kind="stable")
    d_ids = np.asarray(_col(dwells, "dwell_id", nd, 0), dtype=np.int64)[d_order]
    dw = {k: np.asarray(v)[d_order] for k, v in dwells.items()}
    if nt:
        sorter = np.argsort(d_ids, kind="stable")
        t_dwell = np.asarray(detections["dwell_id"], dtype=np.int64)
        pos = np.searchsorted(d_ids[sorter], t_dwell)
        pos = np.minimum(pos, max(nd - 1, 0))
        if nd == 0 or np.any(d_ids[sorter][pos] != t_dwell):
            bad = t_dwell[(nd == 0) | (d_ids[sorter][pos] != t_dwell)][0]
            raise ValueError(f"4607 writer: detection dwell_id {bad} is not in the dwells table")
        row = sorter[pos]
        tie = np.asarray(detections["det_id"]) if "det_id" in detections else np.arange(nt)
        t_order = np.lexsort((tie, row))
        row = row[t_order]
        det = {k: np.asarray(v)[t_order] for k, v in detections.items()}
    else:
        row = np.zeros(0, np.int64)
        det = {k: np.asarray(v)[:0] for k, v in detections.items()}
    counts = np.bincount(row, minlength=nd)
    first = np.concatenate([[0], np.cumsum(counts)[:-1]]) if nd else np.zeros(0, np.int64)

    # --- target reports: one structured array for the whole file -----------------------------
    tfields = _target_columns(det, dw)
    tdesc = [f for f in TARGET_FIELDS if f[0] in tfields]
    tdtype = _dwell_dtype(tdesc)
    tmask = sum(target_mask_bit(k) for k in tfields)
    tg = np.zeros(nt, tdtype)
    mti = np.arange(nt) - first[row] if nt else np.zeros(0, np.int64)
    if np.any(mti > 65535):
        raise ValueError("4607 writer: a dwell has more than 65,536 reports; D32.1 would wrap")
    tg["mti_index"] = mti
    tg["hr_lat"] = enc_sa32(det["lat_deg"]) if nt else 0
    tg["hr_lon"] = enc_ba32(det["lon_deg"]) if nt else 0
    if 6 in tfields:
        tg["height_m"] = _sat(det["height_m"], -1000, 32767)
    if 7 in tfields:
        tg["los_cmps"] = _sat(np.asarray(det["range_rate_mps"], float) * 100.0, -32768, 32767)
        wrap = det.get("wrap_velocity_mps")
        if wrap is None:
            wrap = _col(dw, "wrap_velocity_mps", nd)[row]
        tg["wrap_cmps"] = _sat(np.asarray(wrap, float) * 100.0, 0, 65535)
    if 9 in tfields:
        tg["snr_db"] = _sat(det["snr_db"], -128, 127)
    tg["class"] = m["target_classification"]
    if 12 in tfields:
        tg["sr_cm"] = _sat(np.asarray(det["sigma_range_m"], float) * 100.0, 0, 65535)
    if 13 in tfields:
        if "sigma_cross_range_m" in det:
            cr = np.asarray(det["sigma_cross_range_m"], float)
        else:
            cr = np.asarray(det["range_m"], float) * np.asarray(det["sigma_azimuth_rad"], float)
        tg["cr_dm"] = _sat(cr * 10.0, 0, 65535)
    if 14 in tfields:
        tg["h_m"] = _sat(det["sigma_height_m"], 0, 255)
    if 15 in tfields:
        tg["rv_cmps"] = _sat(np.asarray(det["sigma_range_rate_mps"], float) * 100.0, 0, 5000)
    if 16 in tfields:
        tid = np.asarray(det["truth_id"], dtype=np.int64)
        if np.any((tid < -1) | (tid > 2**32 - 2)):
            raise ValueError("4607 writer: truth_id must be -1 (false alarm) or 0..2^32-2")
        tg["tt_app"] = int(m["truth_tag_application"]) & 0xFF
        tg["tt_entity"] = np.where(tid < 0, 0xFFFFFFFF, tid)
    if 18 in tfields:
        tg["rcs_hdb"] = _sat(np.asarray(det["rcs_dbsm"], float) * 2.0, -128, 127)
    tbytes = memoryview(tg.tobytes())
    tlen = tdtype.itemsize

    # --- dwell pieces: split dwells whose reports do not fit one packet ----------------------
    ddtype = _dwell_dtype(WRITE_DWELL_FIELDS)
    piece_dtype = np.dtype(PACKET_HEADER.descr + SEGMENT_HEADER.descr + [("mask", ">u8")]
                           + ddtype.descr)
    fixed = piece_dtype.itemsize
    per_packet = (MAX_PACKET_BYTES - fixed) // tlen
    n_pieces = np.maximum(1, -(-counts // per_packet)) if nd else np.zeros(0, np.int64)
    p_dwell = np.repeat(np.arange(nd), n_pieces)
    p_k = np.arange(len(p_dwell)) - np.repeat(np.cumsum(n_pieces) - n_pieces, n_pieces)
    p_first = first[p_dwell] + p_k * per_packet
    p_count = np.clip(counts[p_dwell] - p_k * per_packet, 0, per_packet)
    p_last_piece = p_k == n_pieces[p_dwell] - 1

    pk = np.zeros(len(p_dwell), piece_dtype)
    hdr = _packet_header(m, edition, 0, int(m["job_id"]))
    for name in PACKET_HEADER.names:
        pk[name] = hdr[name][0]
    pk["size"] = fixed + p_count * tlen
    pk["seg_type"] = DWELL
    pk["seg_size"] = fixed - 32 + p_count * tlen
    pk["mask"] = WRITE_DWELL_MASK | tmask

    def d(name, default=np.nan):
        return np.asarray(_col(dw, name, nd, default))[p_dwell]

    pk["revisit"] = np.asarray(d("revisit_id", 0), dtype=np.int64) % 65536
    pk["dwell"] = np.asarray(d("dwell_index", 0), dtype=np.int64) % 65536
    pk["last"] = np.asarray(d("last_dwell", False), dtype=bool) & p_last_piece
    pk["count"] = p_count
    pk["time_ms"] = _sat((epoch_sod + np.asarray(d("time_s"), float)) * 1000.0, 0, 2**32 - 1)
    pk["lat"] = enc_sa32(d("platform_lat_deg"))
    pk["lon"] = enc_ba32(d("platform_lon_deg"))
    pk["alt_cm"] = _sat(np.asarray(d("platform_height_m"), float) * 100.0, -50_000, 2**31 - 1)
    along, cross, alt = m["sensor_position_sigma_m"]
    pk["unc_along_cm"] = int(_sat(along * 100.0, 0, 1_000_000))
    pk["unc_cross_cm"] = int(_sat(cross * 100.0, 0, 1_000_000))
    pk["unc_alt_cm"] = int(_sat(alt * 100.0, 0, 65535))
    vx, vy, vz = (np.asarray(d(c, 0.0), float) for c in
                  ("platform_vx_mps", "platform_vy_mps", "platform_vz_mps"))
    pk["track"] = enc_ba16(np.degrees(np.arctan2(vx, vy)))
    pk["speed_mmps"] = _sat(np.hypot(vx, vy) * 1000.0, 0, 8_000_000)
    pk["vvel_dmps"] = _sat(vz * 10.0, -128, 127)
    pk["heading"] = enc_ba16(np.degrees(np.asarray(d("platform_heading_rad", 0.0), float)))
    pk["pitch"] = enc_sa16(np.degrees(np.asarray(d("platform_pitch_rad", 0.0), float)))
    pk["roll"] = enc_sa16(np.degrees(np.asarray(d("platform_bank_rad", 0.0), float)))
    pk["area_lat"] = enc_sa32(d("area_lat_deg"))
    pk["area_lon"] = enc_ba32(d("area_lon_deg"))
    pk["range_half"] = enc_b16(np.asarray(d("range_half_extent_m"), float) / 1000.0)
    pk["angle_half"] = enc_ba16(np.degrees(np.asarray(d("angle_half_extent_rad"), float)))
    pk["mdv_dmps"] = _sat(np.asarray(d("mdv_mps", 0.0), float) * 10.0, 0, 255)
    pkbytes = memoryview(pk.tobytes())

    # --- the stream ------------------------------------------------------------------------
    mission_pkt = _single_segment_packet(m, edition, MISSION, _mission_body(m))
    job_pkt = _single_segment_packet(m, edition, JOB_DEFINITION, _job_body(m))
    head = [mission_pkt, job_pkt]
    if m["write_epoch_text"]:
        iso = epoch.strftime("%Y-%m-%dT%H:%M:%S.%fZ")
        head.append(_single_segment_packet(m, edition, FREE_TEXT,
                                           _free_text_body(f"scene_epoch_utc={iso}")))
    parts: list = list(head)

    plat_times = np.zeros(0)
    plat_bytes = None
    if platform is not None and n_rows(platform, "platform"):
        plat_bytes = memoryview(platform_location_packets(platform, meta, edition=edition))
        plat_times = np.asarray(platform["time_s"], dtype=np.float64)
    pl_len = 32 + 5 + PLATFORM_BODY.itemsize
    piece_time = d_time[d_order][p_dwell] if nd else np.zeros(0)
    # Merge dwell pieces and platform locations by time (platform first on ties).
    kinds = np.concatenate([np.zeros(len(plat_times), np.int8), np.ones(len(p_dwell), np.int8)])
    idx = np.concatenate([np.arange(len(plat_times)), np.arange(len(p_dwell))])
    order = np.lexsort((kinds, np.concatenate([plat_times, piece_time])))
    last_header_t = piece_time[0] if len(piece_time) else 0.0
    prev_rev = pk["revisit"][0] if len(pk) else None
    revs = pk["revisit"].tolist()
    p_first_l = p_first.tolist()
    p_count_l = p_count.tolist()
    p_k_l = p_k.tolist()
    piece_time_l = piece_time.tolist()
    kinds_l = kinds[order].tolist()
    idx_l = idx[order].tolist()
    for kind, i in zip(kinds_l, idx_l):
        if kind == 0:
            parts.append(plat_bytes[i * pl_len:(i + 1) * pl_len])
            continue
        if p_k_l[i] == 0 and (revs[i] != prev_rev or piece_time_l[i] - last_header_t >= JOB_RESEND_S):
            parts.append(mission_pkt)
            parts.append(job_pkt)
            last_header_t = piece_time_l[i]
        prev_rev = revs[i]
        parts.append(pkbytes[i * fixed:(i + 1) * fixed])
        a = p_first_l[i]
        parts.append(tbytes[a * tlen:(a + p_count_l[i]) * tlen])
    return b"".join(parts)


def platform_location_packets(platform: Mapping[str, np.ndarray], meta: Mapping, *,
                              edition: str = "30") -> bytes:
    """Platform Location packets (segment 13, one per row) for a /platform table.

    Uses ``time_s lat_deg lon_deg height_m vx_mps vy_mps vz_mps``; track and speed are those of
    the horizontal velocity (vx east, vy north), vertical velocity in dm/s (S8, saturated).
    """
    m = _meta(meta)
    n = n_rows(platform, "platform")
    epoch = m["epoch"]
    midnight = datetime(epoch.year, epoch.month, epoch.day, tzinfo=timezone.utc)
    epoch_sod = (epoch - midnight) / timedelta(seconds=1)
    dt = np.dtype(PACKET_HEADER.descr + SEGMENT_HEADER.descr + PLATFORM_BODY.descr)
    a = np.zeros(n, dt)
    hdr = _packet_header(m, edition, dt.itemsize, 0)
    for name in PACKET_HEADER.names:
        a[name] = hdr[name][0]
    a["seg_type"], a["seg_size"] = PLATFORM_LOCATION, 5 + PLATFORM_BODY.itemsize
    a["time_ms"] = _sat((epoch_sod + np.asarray(platform["time_s"], float)) * 1000.0, 0, 2**32 - 1)
    a["lat"] = enc_sa32(platform["lat_deg"])
    a["lon"] = enc_ba32(platform["lon_deg"])
    a["alt_cm"] = _sat(np.asarray(platform["height_m"], float) * 100.0, -50_000, 2**31 - 1)
    vx, vy, vz = (np.asarray(_col(platform, c, n, 0.0), float) for c in ("vx_mps", "vy_mps", "vz_mps"))
    a["track"] = enc_ba16(np.degrees(np.arctan2(vx, vy)))
    a["speed_mmps"] = _sat(np.hypot(vx, vy) * 1000.0, 0, 2**32 - 1)
    a["vvel_dmps"] = _sat(vz * 10.0, -128, 127)
    return a.tobytes()


def write_4607(dest, dwells: Mapping[str, np.ndarray], detections: Mapping[str, np.ndarray],
               meta: Mapping, *, edition: str = "30",
               platform: Mapping[str, np.ndarray] | None = None) -> None:
    """Write a STANAG 4607 file (path, written atomically, or binary file object).

    See :func:`encode_4607` for the tables and ``DEFAULT_META`` for the meta keys;
    ``meta['epoch_utc']`` is required.
    """
    write_atomic(dest, encode_4607(dwells, detections, meta, edition=edition, platform=platform))


# ---------------------------------------------------------------------------------------------
# Reader: framing
# ---------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Segment:
    """One segment: its type, the file offset of its 5-byte header, and its body bytes."""
    type: int
    offset: int
    body: bytes


@dataclass(frozen=True)
class Packet:
    """One packet: file offset, decoded packet header fields and its segments."""
    offset: int
    version: str
    size: int
    nationality: str
    classification: int
    classification_system: str
    security_codes: int
    exercise_indicator: int
    platform_id: str
    mission_id: int
    job_id: int
    segments: tuple


_CHUNK = 1 << 20


def _open(source):
    """(binary file object, close-when-done, name) for a path, bytes or a binary file object."""
    if isinstance(source, (bytes, bytearray, memoryview)):
        return io.BytesIO(bytes(source)), True, None
    if isinstance(source, (str, os.PathLike)):
        try:
            return open(source, "rb"), True, str(source)
        except OSError as exc:
            raise FormatError(f"{source}: cannot open: {exc.strerror}") from exc
    if hasattr(source, "read"):
        return source, False, source_name(source)
    raise TypeError(f"4607 reader: source must be a path, bytes or a binary file, not {type(source)}")


def _read_exact(f, n: int, offset: int, name, what: str) -> bytes:
    """Read n bytes in bounded chunks; FormatError naming the offset if the file ends first."""
    if n <= _CHUNK:
        b = f.read(n)
    else:
        pieces, got = [], 0
        while got < n:
            c = f.read(min(_CHUNK, n - got))
            if not c:
                break
            pieces.append(c)
            got += len(c)
        b = b"".join(pieces)
    if not isinstance(b, (bytes, bytearray)):
        raise FormatError(f"{where(name)}source is not a binary file")
    if len(b) != n:
        raise FormatError(f"{where(name)}truncated {what} at byte offset {offset}: expected "
                          f"{n} bytes, the file holds {len(b)}")
    return bytes(b)


def _ascii(b: bytes) -> str:
    return b.decode("latin-1").rstrip(" \x00")


def iter_packets(source, *, max_packet_size: int | None = None) -> Iterator[Packet]:
    """Yield the packets of a 4607 stream one at a time (files larger than memory work).

    ``max_packet_size`` (default: none beyond P2's 2^32-1) rejects larger packets early.
    Raises FormatError naming the byte offset for a bad version id, a packet size below 32 or
    above the limit, a segment that overruns its packet, or a file that ends inside a packet.
    """
    f, close, name = _open(source)
    offset = 0
    try:
        while True:
            head = f.read(32)
            if not isinstance(head, (bytes, bytearray)):
                raise FormatError(f"{where(name)}source is not a binary file (open it with 'rb')")
            if not head:
                return
            if len(head) < 32:
                raise FormatError(f"{where(name)}truncated packet header at byte offset {offset}: "
                                  f"expected 32 bytes, the file holds {len(head)}")
            h = np.frombuffer(head, PACKET_HEADER)[0]
            version = bytes(h["version"])
            if not (len(version) == 2 and version.isdigit()):
                raise FormatError(f"{where(name)}byte offset {offset}: P1 version id {head[:2]!r} "
                                  "is not two ASCII digits (e.g. b'30', b'41'); not a 4607 packet")
            size = int(h["size"])
            if size < 32 or (max_packet_size is not None and size > max_packet_size):
                raise FormatError(f"{where(name)}byte offset {offset + 2}: P2 packet size {size} "
                                  f"outside 32..{max_packet_size or 2**32 - 1}")
            body = _read_exact(f, size - 32, offset + 32, name, "packet body")
            segs = []
            pos = 0
            while pos < len(body):
                so = offset + 32 + pos
                if len(body) - pos < 5:
                    raise FormatError(f"{where(name)}byte offset {so}: {len(body) - pos} bytes left "
                                      "in the packet, too few for a 5-byte segment header")
                stype = body[pos]
                ssize = int.from_bytes(body[pos + 1:pos + 5], "big")
                if ssize < 5 or pos + ssize > len(body):
                    raise FormatError(f"{where(name)}byte offset {so + 1}: S2 segment size {ssize} "
                                      f"(type {stype}) does not fit the packet: expected 5.."
                                      f"{len(body) - pos}")
                fixed = FIXED_BODY_SIZES.get(stype)
                if fixed is not None and ssize - 5 != fixed:
                    raise FormatError(f"{where(name)}byte offset {so + 1}: segment type {stype} "
                                      f"has size {ssize}, expected {fixed + 5}")
                segs.append(Segment(stype, so, body[pos + 5:pos + ssize]))
                pos += ssize
            yield Packet(offset, version.decode("ascii"), size, _ascii(bytes(h["nationality"])),
                         int(h["classification"]), _ascii(bytes(h["class_system"])),
                         int(h["security_codes"]), int(h["exercise"]),
                         _ascii(bytes(h["platform_id"])), int(h["mission_id"]), int(h["job_id"]),
                         tuple(segs))
            offset += size
    finally:
        if close:
            f.close()


# ---------------------------------------------------------------------------------------------
# Reader: segments -> tables
# ---------------------------------------------------------------------------------------------

@lru_cache(maxsize=256)
def _mask_layout(mask: int):
    """(dwell dtype, target dtype, dwell field numbers, target field numbers) for a D1 mask."""
    dfields = tuple(f for f in DWELL_FIELDS if mask & dwell_mask_bit(f[0]))
    tfields = tuple(f for f in TARGET_FIELDS if mask & target_mask_bit(f[0]))
    return (_dwell_dtype(dfields), _dwell_dtype(tfields),
            tuple(f[0] for f in dfields), tuple(f[0] for f in tfields))


_WGS84_A = 6378137.0
_WGS84_E2 = 6.69437999014e-3


def _ecef(lat_deg, lon_deg, h_m):
    lat, lon = np.radians(lat_deg), np.radians(lon_deg)
    n = _WGS84_A / np.sqrt(1.0 - _WGS84_E2 * np.sin(lat) ** 2)
    return ((n + h_m) * np.cos(lat) * np.cos(lon), (n + h_m) * np.cos(lat) * np.sin(lon),
            (n * (1.0 - _WGS84_E2) + h_m) * np.sin(lat))


def _range_azimuth(slat, slon, sh, tlat, tlon, th):
    """Slant range (m) and azimuth (rad, clockwise from north in the sensor's local ENU)."""
    sx, sy, sz = _ecef(slat, slon, sh)
    tx, ty, tz = _ecef(tlat, tlon, th)
    dx, dy, dz = tx - sx, ty - sy, tz - sz
    lat, lon = np.radians(slat), np.radians(slon)
    east = -np.sin(lon) * dx + np.cos(lon) * dy
    north = -np.sin(lat) * np.cos(lon) * dx - np.sin(lat) * np.sin(lon) * dy + np.cos(lat) * dz
    return np.sqrt(dx * dx + dy * dy + dz * dz), np.mod(np.arctan2(east, north), 2 * np.pi)


class _MaskedColumns:
    """Raw fields of many records decoded under different existence masks, scattered into
    full-length int64 columns, each with a mask of the records that carried the field."""

    def __init__(self, n: int):
        self.n = n
        self._raw: dict[str, np.ndarray] = {}
        self._present: dict[str, np.ndarray] = {}

    def scatter(self, decoded: np.ndarray, rows: np.ndarray) -> None:
        """Put the fields of ``decoded`` (a structured array) at ``rows``."""
        for name in decoded.dtype.names:
            if name not in self._raw:
                self._raw[name] = np.zeros(self.n, dtype=np.int64)
                self._present[name] = np.zeros(self.n, dtype=bool)
            self._raw[name][rows] = decoded[name]
            self._present[name][rows] = True

    def raw(self, name: str):
        """(raw values, present) of a field; zeros and False where no record carried it."""
        return (self._raw.get(name, np.zeros(self.n, np.int64)),
                self._present.get(name, np.zeros(self.n, bool)))

    def value(self, name: str, conv) -> np.ndarray:
        """``conv(raw)`` where the field is present, NaN elsewhere."""
        r, ok = self.raw(name)
        return np.where(ok, conv(r), np.nan)


def read_4607(source, *, epoch_utc: str | None = None,
              max_packet_size: int | None = None) -> dict:
    """Read a 4607 file into tables (dicts of numpy columns).

    Returns a dict with the tables ``packets``, ``missions``, ``jobs``, ``dwells``,
    ``detections``, ``platform_locations``, ``free_texts``, ``test_status`` and ``attrs`` (a
    plain dict: ``scene_epoch_utc``, ``time_origin``).  ``time_s`` columns count from
    ``epoch_utc`` if given, else from the ``scene_epoch_utc=`` Free Text a gmtiflow file carries,
    else from 00:00 UTC of the first Mission segment's reference date.

    ``dwells`` has one row per dwell (pieces of a dwell split over several packets are merged:
    consecutive Dwell segments with equal job, revisit index, dwell index and dwell time).
    ``detections`` uses the /detections column names where 4607 carries the quantity; absent
    fields are NaN (floats) or -1 (ids).  ``range_m``/``azimuth_rad`` are derived from the
    sensor and target positions (azimuth in the sensor's local ENU), and ``sigma_azimuth_rad`` =
    cross-range sigma / ``range_m``.
    """
    f, close, name = _open(source)
    try:
        return _read(f, name, epoch_utc, max_packet_size)
    finally:
        if close:
            f.close()


def _read(f, name, epoch_utc, max_packet_size) -> dict:
    pk_rows = []
    missions, jobs, plats, texts, tests = [], [], [], [], []
    # per dwell segment
    seg_pkt, seg_job, seg_ref, seg_mask, seg_off = [], [], [], [], []
    dwell_bytes: dict[int, list] = {}
    dwell_seg_idx: dict[int, list] = {}
    target_bytes: dict[int, list] = {}
    target_seg_idx: dict[int, list] = {}
    seg_counts = []
    ref_day = None  # days since 1970-01-01 of the current mission's reference date
    epoch_text = None

    for pi, p in enumerate(iter_packets(f, max_packet_size=max_packet_size)):
        pk_rows.append((p.offset, p.version, p.size, p.nationality, p.classification,
                        p.classification_system, p.security_codes, p.exercise_indicator,
                        p.platform_id, p.mission_id, p.job_id, len(p.segments)))
        for s in p.segments:
            t = s.type
            if t == MISSION:
                b = np.frombuffer(s.body, MISSION_BODY)[0]
                try:
                    ref = date(int(b["year"]), int(b["month"]), int(b["day"]))
                except ValueError as exc:
                    raise FormatError(f"{where(name)}byte offset {s.offset + 5 + 36}: mission "
                                      f"reference date {int(b['year'])}-{int(b['month'])}-"
                                      f"{int(b['day'])} is not a date ({exc})") from None
                ref_day = (ref - date(1970, 1, 1)).days
                missions.append((pi, _ascii(bytes(b["mission_plan"])), _ascii(bytes(b["flight_plan"])),
                                 int(b["platform_type"]), _ascii(bytes(b["platform_configuration"])),
                                 ref.isoformat()))
            elif t == JOB_DEFINITION:
                jobs.append((pi, s.body))
            elif t == PLATFORM_LOCATION:
                plats.append((pi, -1 if ref_day is None else ref_day, s.body))
            elif t == TEST_STATUS:
                tests.append((pi, -1 if ref_day is None else ref_day, s.body))
            elif t == FREE_TEXT:
                if len(s.body) < 20:
                    raise FormatError(f"{where(name)}byte offset {s.offset + 1}: free text segment "
                                      f"body of {len(s.body)} bytes, expected >= 20")
                text = s.body[20:].decode("latin-1")
                texts.append((pi, _ascii(s.body[:10]), _ascii(s.body[10:20]), text))
                if text.startswith("scene_epoch_utc=") and epoch_text is None:
                    epoch_text = text.split("=", 1)[1].strip()
            elif t == DWELL:
                body = s.body
                if len(body) < 8:
                    raise FormatError(f"{where(name)}byte offset {s.offset + 5}: dwell segment body "
                                      f"of {len(body)} bytes, too short for the 8-byte D1 mask")
                mask = int.from_bytes(body[:8], "big")
                ddt, tdt, dnums, _ = _mask_layout(mask)
                missing = [n for n in MANDATORY_DWELL if n not in dnums]
                if missing:
                    raise FormatError(f"{where(name)}byte offset {s.offset + 5}: dwell existence mask "
                                      f"0x{mask:016X} lacks mandatory fields "
                                      f"{', '.join('D%d' % n for n in missing)}")
                dl = ddt.itemsize
                if len(body) < 8 + dl:
                    raise FormatError(f"{where(name)}byte offset {s.offset + 5}: dwell body of "
                                      f"{len(body)} bytes, mask 0x{mask:016X} needs {8 + dl} "
                                      "before the target reports")
                # D5 sits after D2, D3, D4: offset 8 + 2 + 2 + 1
                count = int.from_bytes(body[13:15], "big")
                expect = 8 + dl + count * tdt.itemsize
                if len(body) != expect:
                    raise FormatError(f"{where(name)}byte offset {s.offset + 1}: dwell segment size "
                                      f"{len(body) + 5} but mask 0x{mask:016X} with D5 = {count} "
                                      f"target reports of {tdt.itemsize} bytes needs {expect + 5}")
                si = len(seg_mask)
                seg_pkt.append(pi)
                seg_job.append(p.job_id)
                seg_ref.append(-1 if ref_day is None else ref_day)
                seg_mask.append(mask)
                seg_off.append(s.offset)
                seg_counts.append(count)
                dwell_bytes.setdefault(mask, []).append(body[8:8 + dl])
                dwell_seg_idx.setdefault(mask, []).append(si)
                if count:
                    target_bytes.setdefault(mask, []).append(body[8 + dl:])
                    target_seg_idx.setdefault(mask, []).append(si)
            # HRR, processing history, tasking, unknown types: framed and skipped.

    # --- time origin ------------------------------------------------------------------------
    epoch_str = epoch_utc if epoch_utc is not None else epoch_text
    first_ref = next((r for r in seg_ref if r >= 0), None)
    if first_ref is None and missions:
        first_ref = (date.fromisoformat(missions[0][-1]) - date(1970, 1, 1)).days
    if epoch_str is not None:
        try:
            ep = parse_epoch(epoch_str)
        except ValueError:
            raise FormatError(f"{where(name)}scene epoch {epoch_str!r} is not an ISO-8601 "
                              "instant") from None
        epoch_posix = ep.timestamp()
        origin = "scene_epoch"
    else:
        epoch_posix = (first_ref or 0) * 86400.0
        origin = "reference_day"

    def time_s(ref_days, ms):
        ref_days = np.asarray(ref_days, dtype=np.float64)
        base = np.where(ref_days >= 0, ref_days, first_ref or 0) * 86400.0 - epoch_posix
        return base + np.asarray(ms, dtype=np.float64) / 1000.0

    out: dict = {}
    out["packets"] = _table(pk_rows, [
        ("offset", np.int64), ("version", str), ("size", np.int64), ("nationality", str),
        ("classification", np.uint8), ("classification_system", str),
        ("security_codes", np.int64), ("exercise_indicator", np.uint8), ("platform_id", str),
        ("mission_id", np.int64), ("job_id", np.int64), ("n_segments", np.int64)])
    out["missions"] = _table(missions, [
        ("packet", np.int64), ("mission_plan", str), ("flight_plan", str),
        ("platform_type", np.uint8), ("platform_configuration", str), ("reference_date", str)])
    out["jobs"] = _jobs_table(jobs)
    out["platform_locations"] = _platform_table(plats, time_s)
    out["free_texts"] = _table(texts, [("packet", np.int64), ("originator", str),
                                       ("recipient", str), ("text", str)])
    out["test_status"] = _test_table(tests, time_s)
    dwells, dets = _dwell_tables(seg_pkt, seg_job, seg_ref, seg_mask, seg_off, seg_counts,
                                 dwell_bytes, dwell_seg_idx, target_bytes, target_seg_idx,
                                 time_s, name)
    out["dwells"] = dwells
    out["detections"] = dets
    out["attrs"] = {"scene_epoch_utc": epoch_str, "time_origin": origin}
    return out


def _table(rows, cols) -> dict:
    out = {}
    for i, (c, dt) in enumerate(cols):
        vals = [r[i] for r in rows]
        out[c] = np.array(vals, dtype=dt) if vals else np.zeros(0, dtype=dt)
    return out


def _jobs_table(jobs) -> dict:
    raw = np.frombuffer(b"".join(b for _, b in jobs), JOB_BODY)
    t = {"packet": np.array([p for p, _ in jobs], dtype=np.int64)}
    t["job_id"] = raw["job_id"].astype(np.int64)
    t["sensor_type"] = raw["sensor_type"].astype(np.uint8)
    t["sensor_model"] = np.array([_ascii(bytes(x)) for x in raw["sensor_model"]], dtype=str)
    t["target_filtering"] = raw["target_filtering"].astype(np.uint8)
    t["priority"] = raw["priority"].astype(np.uint8)
    for c in "abcd":
        t[f"{c}_lat_deg"] = dec_sa(raw[f"{c}_lat"], 32)
        t[f"{c}_lon_deg"] = lon_180(dec_ba(raw[f"{c}_lon"], 32))
    t["radar_mode"] = raw["radar_mode"].astype(np.uint8)
    t["revisit_interval_s"] = raw["revisit_ds"] / 10.0

    def ns(col, scale, sentinel):
        v = raw[col].astype(np.float64)
        return np.where(v == sentinel, np.nan, v * scale)

    t["sigma_along_track_m"] = ns("along_dm", 0.1, 65535)
    t["sigma_cross_track_m"] = ns("cross_dm", 0.1, 65535)
    t["sigma_altitude_m"] = ns("alt_dm", 0.1, 65535)
    t["sigma_track_deg"] = ns("track_deg", 1.0, 255)
    t["sigma_speed_mps"] = ns("speed_mmps", 1e-3, 65535)
    t["sigma_slant_range_m"] = ns("slant_cm", 0.01, 65535)
    t["sigma_cross_range_deg"] = np.where(raw["cross_ba16"] == 0x8000, np.nan,
                                          dec_ba(raw["cross_ba16"], 16))
    t["sigma_range_rate_mps"] = ns("los_cmps", 0.01, 65535)
    t["mdv_mps"] = ns("mdv_dmps", 0.1, 255)
    t["pd"] = ns("pd_pct", 0.01, 255)
    fa = raw["fa_db"].astype(np.float64)
    t["false_alarm_density_per_m2"] = np.where(fa == 255, np.nan, 10.0 ** (-fa / 10.0))
    t["terrain_model"] = raw["terrain_model"].astype(np.uint8)
    t["geoid_model"] = raw["geoid_model"].astype(np.uint8)
    return t


def _platform_table(plats, time_s) -> dict:
    raw = np.frombuffer(b"".join(b for _, _, b in plats), PLATFORM_BODY)
    ref = np.array([r for _, r, _ in plats], dtype=np.int64)
    speed = raw["speed_mmps"] / 1000.0
    track = np.radians(dec_ba(raw["track"], 16))
    return {
        "packet": np.array([p for p, _, _ in plats], dtype=np.int64),
        "time_ms": raw["time_ms"].astype(np.int64),
        "time_s": time_s(ref, raw["time_ms"]),
        "lat_deg": dec_sa(raw["lat"], 32), "lon_deg": lon_180(dec_ba(raw["lon"], 32)),
        "height_m": raw["alt_cm"] / 100.0, "track_rad": track, "speed_mps": speed,
        "vx_mps": speed * np.sin(track), "vy_mps": speed * np.cos(track),
        "vz_mps": raw["vvel_dmps"] / 10.0,
    }


def _test_table(tests, time_s) -> dict:
    raw = np.frombuffer(b"".join(b for _, _, b in tests), TEST_STATUS_BODY)
    ref = np.array([r for _, r, _ in tests], dtype=np.int64)
    return {
        "packet": np.array([p for p, _, _ in tests], dtype=np.int64),
        "job_id": raw["job_id"].astype(np.int64), "revisit_id": raw["revisit"].astype(np.int64),
        "dwell_index": raw["dwell"].astype(np.int64), "time_ms": raw["time_ms"].astype(np.int64),
        "time_s": time_s(ref, raw["time_ms"]),
        "hardware_status": raw["hardware"].astype(np.uint8),
        "mode_status": raw["mode"].astype(np.uint8),
    }


def _dwell_tables(seg_pkt, seg_job, seg_ref, seg_mask, seg_off, seg_counts, dwell_bytes,
                  dwell_seg_idx, target_bytes, target_seg_idx, time_s, name):
    ns = len(seg_mask)
    counts = np.array(seg_counts, dtype=np.int64)

    # Dwell fields of every segment, decoded per mask into full-length raw columns.
    dwell_fields = _MaskedColumns(ns)
    for mask, chunks in dwell_bytes.items():
        dwell_fields.scatter(np.frombuffer(b"".join(chunks), _mask_layout(mask)[0]),
                             np.array(dwell_seg_idx[mask], dtype=np.int64))
    rcol, fcol = dwell_fields.raw, dwell_fields.value

    seg_job = np.array(seg_job, dtype=np.int64)
    seg_ref = np.array(seg_ref, dtype=np.int64)
    rev, _ = rcol("revisit")
    dwi, _ = rcol("dwell")
    tms, _ = rcol("time_ms")
    last, _ = rcol("last")
    if np.any(last > 1):
        bad = int(np.flatnonzero(last > 1)[0])
        raise FormatError(f"{where(name)}byte offset {seg_off[bad] + 5 + 8 + 4}: D4 last-dwell "
                          f"flag {int(last[bad])}, expected 0 or 1")
    # Pieces of one dwell split over several packets: consecutive, same key.
    key_change = np.ones(ns, dtype=bool)
    if ns > 1:
        key_change[1:] = ((seg_job[1:] != seg_job[:-1]) | (rev[1:] != rev[:-1])
                          | (dwi[1:] != dwi[:-1]) | (tms[1:] != tms[:-1])
                          | (seg_ref[1:] != seg_ref[:-1]) | (last[:-1] == 1))
    seg_dwell = np.cumsum(key_change) - 1
    nd = int(seg_dwell[-1]) + 1 if ns else 0
    firsts = np.flatnonzero(key_change)

    def first(x):
        return x[firsts]

    dw_counts = np.bincount(seg_dwell, weights=counts, minlength=nd).astype(np.int64)
    dw_last = np.bincount(seg_dwell, weights=last, minlength=nd) > 0
    t_s = time_s(seg_ref, tms)

    lat_scale = fcol("lat_scale", lambda r: dec_sa(r, 32))
    lon_scale = fcol("lon_scale", lambda r: dec_ba(r, 32))
    speed = fcol("speed_mmps", lambda r: r / 1000.0)
    track = fcol("track", lambda r: np.radians(dec_ba(r, 16)))
    dwells = {
        "dwell_id": np.arange(nd, dtype=np.int64),
        "job_id": first(seg_job),
        "revisit_id": first(rev),
        "dwell_index": first(dwi),
        "last_dwell": dw_last,
        "target_count": dw_counts,
        "n_packets": np.bincount(seg_dwell, minlength=nd).astype(np.int64),
        "dwell_time_ms": first(tms),
        "time_s": first(t_s),
        "platform_lat_deg": first(fcol("lat", lambda r: dec_sa(r, 32))),
        "platform_lon_deg": first(fcol("lon", lambda r: lon_180(dec_ba(r, 32)))),
        "platform_height_m": first(fcol("alt_cm", lambda r: r / 100.0)),
        "lat_scale_deg": first(lat_scale),
        "lon_scale_deg": first(lon_scale),
        "sigma_along_track_m": first(fcol("unc_along_cm", lambda r: r / 100.0)),
        "sigma_cross_track_m": first(fcol("unc_cross_cm", lambda r: r / 100.0)),
        "sigma_altitude_m": first(fcol("unc_alt_cm", lambda r: r / 100.0)),
        "sensor_track_rad": first(track),
        "sensor_speed_mps": first(speed),
        "platform_vx_mps": first(speed * np.sin(track)),
        "platform_vy_mps": first(speed * np.cos(track)),
        "platform_vz_mps": first(fcol("vvel_dmps", lambda r: r / 10.0)),
        "sigma_track_rad": first(fcol("unc_track_deg", lambda r: np.radians(r * 1.0))),
        "sigma_speed_mps": first(fcol("unc_speed_mmps", lambda r: r / 1000.0)),
        "sigma_vz_mps": first(fcol("unc_vvel_cmps", lambda r: r / 100.0)),
        "platform_heading_rad": first(fcol("heading", lambda r: np.radians(dec_ba(r, 16)))),
        "platform_pitch_rad": first(fcol("pitch", lambda r: np.radians(dec_sa(r, 16)))),
        "platform_bank_rad": first(fcol("roll", lambda r: np.radians(dec_sa(r, 16)))),
        "area_lat_deg": first(fcol("area_lat", lambda r: dec_sa(r, 32))),
        "area_lon_deg": first(fcol("area_lon", lambda r: lon_180(dec_ba(r, 32)))),
        "range_half_extent_m": first(fcol("range_half", lambda r: dec_b16(r) * 1000.0)),
        "angle_half_extent_rad": first(fcol("angle_half", lambda r: np.radians(dec_ba(r, 16)))),
        "sensor_heading_rad": first(_sensor_angle(rcol, "sensor_heading", 16, True)),
        "sensor_pitch_rad": first(_sensor_angle(rcol, "sensor_pitch", 16, False)),
        "sensor_roll_rad": first(_sensor_angle(rcol, "sensor_roll", 16, False)),
        "mdv_mps": first(fcol("mdv_dmps", lambda r: r / 10.0)),
    }

    # Target reports: per mask, all at once.
    nt = int(counts.sum())
    seg_tfirst = np.concatenate([[0], np.cumsum(counts)[:-1]]) if ns else np.zeros(0, np.int64)
    t_seg = np.repeat(np.arange(ns), counts)
    target_fields = _MaskedColumns(nt)
    for mask, chunks in target_bytes.items():
        segs = np.array(target_seg_idx[mask], dtype=np.int64)
        c = counts[segs]
        pos = (np.repeat(seg_tfirst[segs] - (np.cumsum(c) - c), c) + np.arange(int(c.sum())))
        target_fields.scatter(np.frombuffer(b"".join(chunks), _mask_layout(mask)[1]), pos)
    tr, tf = target_fields.raw, target_fields.value

    # Position: hi-res, else reduced resolution from D24/D25 + delta x scale (GUIDE Annex E).
    hr_lat, hr_ok = tr("hr_lat")
    hr_lon, _ = tr("hr_lon")
    d_lat, dl_ok = tr("d_lat")
    d_lon, _ = tr("d_lon")
    area_lat_raw, _ = rcol("area_lat")
    area_lon_raw, _ = rcol("area_lon")
    lsc_raw, lsc_ok = rcol("lat_scale")
    osc_raw, _ = rcol("lon_scale")
    use_delta = dl_ok & ~hr_ok
    if np.any(use_delta & ~lsc_ok[t_seg]):
        bad = int(t_seg[np.flatnonzero(use_delta & ~lsc_ok[t_seg])[0]])
        raise FormatError(f"{where(name)}byte offset {seg_off[bad] + 5}: dwell sends delta "
                          "positions D32.4/D32.5 without the scale factors D10/D11")
    lat_raw = np.where(hr_ok, hr_lat, area_lat_raw[t_seg] + d_lat * lsc_raw[t_seg])
    out_of_range = use_delta & ((lat_raw < -2**31) | (lat_raw >= 2**31))
    if np.any(out_of_range):
        bad = int(t_seg[np.flatnonzero(out_of_range)[0]])
        raise FormatError(f"{where(name)}byte offset {seg_off[bad] + 5}: a delta latitude "
                          "D24 + D32.4 x D10 falls outside the SA32 range +-90 deg (the scale "
                          "factor D10 does not fit the dwell)")
    lon_raw = np.where(hr_ok, hr_lon, (area_lon_raw[t_seg] + d_lon * osc_raw[t_seg]) % 2**32)
    pos_ok = hr_ok | use_delta
    lat = np.where(pos_ok, dec_sa(lat_raw, 32), np.nan)
    lon = np.where(pos_ok, lon_180(dec_ba(lon_raw, 32)), np.nan)
    height = tf("height_m", lambda r: r * 1.0)
    ent, ent_ok = tr("tt_entity")
    truth = np.where(ent_ok, np.where(ent >= 2**31, ent - 2**32, ent), -1).astype(np.int64)
    seg_dwell_t = seg_dwell[t_seg]
    slat = dwells["platform_lat_deg"][seg_dwell_t]
    slon = dwells["platform_lon_deg"][seg_dwell_t]
    sh = dwells["platform_height_m"][seg_dwell_t]
    # Height absent: the target lies on the earth model; use 0 m HAE for the geometry only.
    with np.errstate(invalid="ignore", divide="ignore"):
        rng, az = _range_azimuth(slat, slon, sh, lat, lon,
                                 np.where(np.isfinite(height), height, 0.0))
        cross = tf("cr_dm", lambda r: r / 10.0)
        sigma_az = np.where(rng > 0, cross / rng, np.nan)
    wrap = tf("wrap_cmps", lambda r: r / 100.0)
    mti, mti_ok = tr("mti_index")
    cls, cls_ok = tr("class")
    dets = {
        "det_id": np.arange(nt, dtype=np.int64),
        "dwell_id": seg_dwell_t.astype(np.int64),
        "time_s": t_s[t_seg] if nt else np.zeros(0),
        "mti_report_index": np.where(mti_ok, mti, -1).astype(np.int64),
        "lat_deg": lat, "lon_deg": lon, "height_m": height,
        "range_m": rng, "azimuth_rad": az,
        "range_rate_mps": tf("los_cmps", lambda r: r / 100.0),
        "wrap_velocity_mps": np.where(wrap == 0, np.nan, wrap),
        "snr_db": tf("snr_db", lambda r: r * 1.0),
        "classification": np.where(cls_ok, cls, 0).astype(np.uint8),
        "classification_probability": tf("class_prob", lambda r: r / 100.0),
        "sigma_range_m": tf("sr_cm", lambda r: r / 100.0),
        "sigma_cross_range_m": cross,
        "sigma_azimuth_rad": sigma_az,
        "sigma_height_m": tf("h_m", lambda r: r * 1.0),
        "sigma_range_rate_mps": tf("rv_cmps", lambda r: r / 100.0),
        "truth_application": np.where(ent_ok, tr("tt_app")[0], -1).astype(np.int64),
        "truth_id": truth,
        "rcs_dbsm": tf("rcs_hdb", lambda r: r / 2.0),
    }
    return dwells, dets


def _sensor_angle(rcol, fname, bits, unsigned):
    """D28-D30: if any of them is present an absent one means 0 deg (SPEC 3.4.28)."""
    r, ok = rcol(fname)
    any_ok = rcol("sensor_heading")[1] | rcol("sensor_pitch")[1] | rcol("sensor_roll")[1]
    deg = dec_ba(r, bits) if unsigned else dec_sa(r, bits)
    return np.where(any_ok, np.radians(np.where(ok, deg, 0.0)), np.nan)
