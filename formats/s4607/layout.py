"""STANAG 4607 field tables, existence-mask bits, scalings and text fields.

Layout and scalings follow AEDP-4607 Ed. A v1 (= STANAG 4607 Ed. 3 layout); every multi-byte
field is big-endian.  ``enc_*``: engineering value -> raw integer, rounded to the nearest quantum
and saturated to the field range (NaN -> 0); ``dec_*``: raw -> float64.
"""
from __future__ import annotations

import numpy as np

MAX_PACKET_BYTES = 65_535

MISSION, DWELL, HRR, JOB_DEFINITION, FREE_TEXT, TEST_STATUS, PROC_HISTORY, PLATFORM_LOCATION = (
    1, 2, 3, 5, 6, 10, 12, 13)

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


def record_dtype(fields) -> np.dtype:
    return np.dtype([(name, fmt) for _, name, fmt in fields])


# ---------------------------------------------------------------------------------------------
# Scalings (reference §1.1)
# ---------------------------------------------------------------------------------------------

def sat(x, lo, hi, nan=0):
    """Round to the nearest integer and clip to [lo, hi]; NaN -> ``nan``."""
    y = np.rint(np.asarray(x, dtype=np.float64))
    if not y.ndim:                          # a scalar: the plain path
        return np.clip(np.where(np.isfinite(y), y, nan), lo, hi).astype(np.int64)
    bad = ~np.isfinite(y)                   # arrays: in place, NaN/inf patched only if any
    if bad.any():
        y[bad] = nan
    np.clip(y, lo, hi, out=y)
    return y.astype(np.int64)


def enc_ba32(deg):
    d = np.asarray(deg, dtype=np.float64)
    return (sat(np.mod(np.where(np.isfinite(d), d, 0.0), 360.0) * (2.0**32 / 360.0), 0, 2**32)
            % 2**32)


def enc_sa32(deg):
    return sat(np.asarray(deg, dtype=np.float64) * (2.0**32 / 180.0), -2**31, 2**31 - 1)


def enc_ba16(deg):
    d = np.asarray(deg, dtype=np.float64)
    return sat(np.mod(np.where(np.isfinite(d), d, 0.0), 360.0) * (2.0**16 / 360.0), 0, 2**16) % 2**16


def enc_sa16(deg):
    return sat(np.asarray(deg, dtype=np.float64) * (2.0**16 / 180.0), -2**15, 2**15 - 1)


def enc_b16(x):
    """B16 sign-magnitude (1 sign, 8 integer, 7 fraction bits)."""
    x = np.asarray(x, dtype=np.float64)
    mag = sat(np.abs(x) * 128.0, 0, 0x7FFF)
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
# Text fields (A n)
# ---------------------------------------------------------------------------------------------

def enc_text(s, n: int) -> bytes:
    """A(n) field: ASCII, space-padded (as the standard asks), truncated to n bytes."""
    b = str(s if s is not None else "").encode("ascii", "replace")[:n]
    return b.ljust(n, b" ")


def dec_text(b: bytes) -> str:
    """An A(n) field as text: up to the first NUL, trailing spaces removed.

    The standard pads with spaces; real recorders often pad with NULs (C strings), sometimes
    with stale bytes after the terminating NUL.  Both read as the same text, so the text never
    holds a NUL (HDF5 variable-length strings cannot).
    """
    cut = b.find(b"\x00")
    if cut >= 0:
        b = b[:cut]
    return b.decode("latin-1").rstrip(" ")


def dec_text_array(a: np.ndarray) -> np.ndarray:
    """:func:`dec_text` of every element of a fixed-width bytes array (decoded once per value)."""
    if len(a) == 0:
        return np.zeros(0, dtype=str)
    if np.all(a == a[0]):                     # the usual case: one platform, one mission
        return np.full(len(a), dec_text(bytes(a[0])))
    uniq, inv = np.unique(a, return_inverse=True)
    text = np.array([dec_text(bytes(u).ljust(a.dtype.itemsize, b"\x00")) for u in uniq],
                    dtype=str)
    return text[inv.reshape(-1)]
