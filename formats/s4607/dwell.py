"""The Dwell segment (type 2): existence masks, per-mask encoding into packets, decoding.

Encoding (:func:`encode_dwell_packets`) takes the dwell rows in stream order, the detection
rows grouped by dwell and one 64-bit existence mask per dwell (D1: dwell fields in bits 63..34,
target fields in bits 33..16).  Dwells are encoded per distinct mask, all at once (structured
numpy arrays); a dwell whose reports do not fit one packet is split into pieces that repeat the
dwell fields, carry on D32.1 and set D4 only on the last piece (GUIDE Annex D).

Decoding (:func:`decode_dwells`) takes the Dwell segments' bodies found by
:func:`..packet.frame` and decodes every dwell and target record of one mask in one
``np.frombuffer``.  Absent fields are NaN (floats) or -1 (ids); the mask is kept per dwell
(``existence_mask``) so that a re-encoding writes exactly the fields that were sent.

Wireshark's dissector (4.0) reads some fields only as groups: D10-D11, D12-D14, D15-D17,
D18-D20, D21-D23, D28-D30, D32.2-D32.3 (else D32.4-D32.5), D32.7-D32.8, D32.12-D32.15 and
D32.16-D32.17.  :func:`tshark_safe_mask` completes a mask to whole groups.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..errors import FormatError, where
from .layout import (DWELL, DWELL_FIELDS, MANDATORY_DWELL, MAX_PACKET_BYTES, TARGET_FIELDS,
                     dec_b16, dec_ba, dec_sa, dwell_mask_bit, enc_b16, enc_ba16, enc_ba32,
                     enc_sa16, enc_sa32, lon_180, record_dtype, sat, target_mask_bit)
from .packet import PACKET_HEADER, SEGMENT_HEADER, gather, gather_var

DWELL_GROUPS = ((10, 11), (12, 13, 14), (15, 16, 17), (18, 19, 20), (21, 22, 23), (28, 29, 30))
TARGET_GROUPS = ((2, 3), (4, 5), (7, 8), (12, 13, 14, 15), (16, 17))
WRITE_DWELL_FIELDS = (2, 3, 4, 5, 6, 7, 8, 9, 12, 13, 14, 15, 16, 17, 21, 22, 23, 24, 25, 26,
                      27, 31)
WRITE_DWELL_MASK = sum(dwell_mask_bit(n) for n in WRITE_DWELL_FIELDS)


def mask_of(dwell_fields=(), target_fields=()) -> int:
    return sum(dwell_mask_bit(n) for n in dwell_fields) + sum(target_mask_bit(k)
                                                              for k in target_fields)


@lru_cache(maxsize=256)
def mask_layout(mask: int):
    """(dwell dtype, target dtype, dwell field numbers, target field numbers) for a D1 mask."""
    dfields = tuple(f for f in DWELL_FIELDS if mask & dwell_mask_bit(f[0]))
    tfields = tuple(f for f in TARGET_FIELDS if mask & target_mask_bit(f[0]))
    return (record_dtype(dfields), record_dtype(tfields),
            tuple(f[0] for f in dfields), tuple(f[0] for f in tfields))


def tshark_safe_mask(mask: int) -> int:
    """``mask`` with every partly present Wireshark group completed (see the module doc)."""
    for group in DWELL_GROUPS:
        if any(mask & dwell_mask_bit(n) for n in group):
            mask |= mask_of(dwell_fields=group)
    for group in TARGET_GROUPS:
        if any(mask & target_mask_bit(k) for k in group):
            mask |= mask_of(target_fields=group)
    return mask


# ---------------------------------------------------------------------------------------------
# Encoding
# ---------------------------------------------------------------------------------------------

def _col(table, name, n, default=np.nan):
    if name in table:
        return np.asarray(table[name])
    return np.full(n, default)


def _f(table, name, n, default=np.nan):
    return np.asarray(_col(table, name, n, default), dtype=np.float64)


def dwell_raw(dw: dict, n: int, epoch_sod: float, sensor_position_sigma_m) -> dict:
    """Raw D2..D31 values (int64 columns) of ``n`` dwell rows; D4 and D5 are set per piece."""
    r = {}
    r["revisit"] = np.asarray(_col(dw, "revisit_id", n, 0), np.int64) % 65536
    r["dwell"] = np.asarray(_col(dw, "dwell_index", n, 0), np.int64) % 65536
    if "dwell_time_ms" in dw:
        r["time_ms"] = np.asarray(dw["dwell_time_ms"], np.int64)
    else:
        r["time_ms"] = sat((epoch_sod + _f(dw, "time_s", n)) * 1000.0, 0, 2**32 - 1)
    r["lat"] = enc_sa32(_f(dw, "platform_lat_deg", n))
    r["lon"] = enc_ba32(_f(dw, "platform_lon_deg", n))
    r["alt_cm"] = sat(_f(dw, "platform_height_m", n) * 100.0, -2**31, 2**31 - 1)
    r["lat_scale"] = enc_sa32(_f(dw, "lat_scale_deg", n, 0.0))
    r["lon_scale"] = enc_ba32(_f(dw, "lon_scale_deg", n, 0.0))
    along, cross, alt = sensor_position_sigma_m
    r["unc_along_cm"] = sat(_f(dw, "sigma_along_track_m", n, along) * 100.0, 0, 2**32 - 1)
    r["unc_cross_cm"] = sat(_f(dw, "sigma_cross_track_m", n, cross) * 100.0, 0, 2**32 - 1)
    r["unc_alt_cm"] = sat(_f(dw, "sigma_altitude_m", n, alt) * 100.0, 0, 65535)
    vx, vy, vz = (_f(dw, c, n, 0.0) for c in ("platform_vx_mps", "platform_vy_mps",
                                              "platform_vz_mps"))
    track = np.degrees(np.arctan2(vx, vy))
    speed = np.hypot(vx, vy)
    if "sensor_track_rad" in dw:       # D15/D16 as read: exact even at zero speed
        t = np.degrees(_f(dw, "sensor_track_rad", n))
        track = np.where(np.isfinite(t), t, track)
    if "sensor_speed_mps" in dw:
        s = _f(dw, "sensor_speed_mps", n)
        speed = np.where(np.isfinite(s), s, speed)
    r["track"] = enc_ba16(track)
    r["speed_mmps"] = sat(speed * 1000.0, 0, 2**32 - 1)
    r["vvel_dmps"] = sat(vz * 10.0, -128, 127)
    r["unc_track_deg"] = sat(np.degrees(_f(dw, "sigma_track_rad", n, 0.0)), 0, 255)
    r["unc_speed_mmps"] = sat(_f(dw, "sigma_speed_mps", n, 0.0) * 1000.0, 0, 65535)
    r["unc_vvel_cmps"] = sat(_f(dw, "sigma_vz_mps", n, 0.0) * 100.0, 0, 65535)
    r["heading"] = enc_ba16(np.degrees(_f(dw, "platform_heading_rad", n, 0.0)))
    r["pitch"] = enc_sa16(np.degrees(_f(dw, "platform_pitch_rad", n, 0.0)))
    r["roll"] = enc_sa16(np.degrees(_f(dw, "platform_bank_rad", n, 0.0)))
    r["area_lat"] = enc_sa32(_f(dw, "area_lat_deg", n))
    r["area_lon"] = enc_ba32(_f(dw, "area_lon_deg", n))
    r["range_half"] = enc_b16(_f(dw, "range_half_extent_m", n) / 1000.0)
    r["angle_half"] = enc_ba16(np.degrees(_f(dw, "angle_half_extent_rad", n)))
    r["sensor_heading"] = enc_ba16(np.degrees(_f(dw, "sensor_heading_rad", n, 0.0)))
    r["sensor_pitch"] = enc_sa16(np.degrees(_f(dw, "sensor_pitch_rad", n, 0.0)))
    r["sensor_roll"] = enc_sa16(np.degrees(_f(dw, "sensor_roll_rad", n, 0.0)))
    r["mdv_dmps"] = sat(_f(dw, "mdv_mps", n, 0.0) * 10.0, 0, 255)
    return r


def cross_range_sigma_m(det: dict):
    """D32.13 source: ``sigma_cross_range_m``, else ``range_m * sigma_azimuth_rad``, else None."""
    if "sigma_cross_range_m" in det:
        return np.asarray(det["sigma_cross_range_m"], float)
    if "range_m" in det and "sigma_azimuth_rad" in det:
        return np.asarray(det["range_m"], float) * np.asarray(det["sigma_azimuth_rad"], float)
    return None


def height_sigma_m(det: dict, dw: dict, row: np.ndarray) -> np.ndarray:
    """D32.14 source: ``sigma_height_m``, else the vertical part of the slant-range error.

    A report placed on the terrain by range and azimuth has a height error of at least the
    slant-range σ times the sine of the depression angle, σ_h = σ_r (h_sensor − h_target) / r.
    The derived σ is at least the field's 1 m quantum: a present zero σ would make a tracker's
    covariance singular (the floor is 1.0, not 0.5: the writer rounds half to even, and 0.5
    gives 0).  A given ``sigma_height_m`` is written as it is (a table read from 4607 comes
    back byte for byte, also one whose D32.14 is 0).
    """
    if "sigma_height_m" in det:
        return np.asarray(det["sigma_height_m"], float)
    sh = np.asarray(dw["platform_height_m"], float)[row]
    th = np.asarray(det.get("height_m", np.zeros(len(row))), float)
    th = np.where(np.isfinite(th), th, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        if "range_m" in det:            # the measured slant range
            rng = np.asarray(det["range_m"], float)
        else:
            rng = slant_range(np.asarray(dw["platform_lat_deg"], float)[row],
                              np.asarray(dw["platform_lon_deg"], float)[row], sh,
                              np.asarray(det["lat_deg"], float),
                              np.asarray(det["lon_deg"], float), th)
        sin_dep = np.clip((sh - th) / rng, 0.0, 1.0)
    s = np.asarray(det["sigma_range_m"], float) * sin_dep
    return np.where(np.isfinite(s), np.maximum(s, 1.0), s)


def target_raw(det: dict, n: int, row: np.ndarray, dw: dict, draw: dict, m: dict,
               needed=None) -> dict:
    """Raw D32.1..D32.18 values (int64 columns) of ``n`` detections; ``row`` = dwell row
    (non-decreasing).  ``needed``: the field keys to compute (default: all)."""
    need = (lambda k: True) if needed is None else (lambda k: k in needed)
    r = {}
    nd = len(draw["revisit"])
    counts = np.bincount(row, minlength=nd) if n else np.zeros(nd, np.int64)
    mti = np.arange(n) - (np.cumsum(counts) - counts)[row] if n else np.zeros(0, np.int64)
    if "mti_report_index" in det:
        given = np.asarray(det["mti_report_index"], np.int64)
        mti = np.where(given >= 0, given, mti)
    if np.any(mti > 65535):
        raise ValueError("4607 writer: a dwell has more than 65,536 reports; D32.1 would wrap")
    r["mti_index"] = mti
    lat, lon = _f(det, "lat_deg", n), _f(det, "lon_deg", n)
    r["hr_lat"] = enc_sa32(lat)
    r["hr_lon"] = enc_ba32(lon)
    # reduced resolution (GUIDE Annex E): lat = D24 + D32.4 x D10, lon = D25 + D32.5 x D11 mod 2^32
    if need("d_lat") or need("d_lon"):
        lsc, osc = draw["lat_scale"][row], draw["lon_scale"][row]
        dlat = r["hr_lat"] - draw["area_lat"][row]
        dlon = (r["hr_lon"] - draw["area_lon"][row] + 2**31) % 2**32 - 2**31
        with np.errstate(divide="ignore", invalid="ignore"):
            r["d_lat"] = sat(np.where(lsc != 0, dlat / np.where(lsc != 0, lsc, 1), 0),
                             -32768, 32767)
            r["d_lon"] = sat(np.where(osc != 0, dlon / np.where(osc != 0, osc, 1), 0),
                             -32768, 32767)
    r["height_m"] = sat(_f(det, "height_m", n), -1000, 32767)
    r["los_cmps"] = sat(_f(det, "los_velocity_mps", n) * 100.0, -32768, 32767)
    wrap = det.get("wrap_velocity_mps")
    if wrap is None:
        wrap = _f(dw, "wrap_velocity_mps", len(draw["revisit"]))[row]
    r["wrap_cmps"] = sat(np.asarray(wrap, float) * 100.0, 0, 65535)
    r["snr_db"] = sat(_f(det, "snr_db", n), -128, 127)
    r["class"] = np.asarray(_col(det, "classification", n, m["target_classification"]), np.int64)
    r["class_prob"] = sat(_f(det, "classification_probability", n) * 100.0, 0, 255)
    r["sr_cm"] = sat(_f(det, "sigma_range_m", n) * 100.0, 0, 65535)
    cr = cross_range_sigma_m(det)
    r["cr_dm"] = sat((cr if cr is not None else np.full(n, np.nan)) * 10.0, 0, 65535)
    r["h_m"] = (sat(height_sigma_m(det, dw, row), 0, 255)
                if n and "sigma_range_m" in det and need("h_m") else np.zeros(n, np.int64))
    r["rv_cmps"] = sat(_f(det, "sigma_range_rate_mps", n) * 100.0, 0, 65535)
    app = np.full(n, int(m["truth_tag_application"]) & 0xFF, np.int64)
    if "truth_application" in det:
        given = np.asarray(det["truth_application"], np.int64)
        app = np.where(given >= 0, given & 0xFF, app)
    r["tt_app"] = app
    tid = np.asarray(_col(det, "truth_id", n, -1), dtype=np.int64)
    if np.any((tid < -1) | (tid > 2**32 - 2)):
        raise ValueError("4607 writer: truth_id must be -1 (false alarm) or 0..2^32-2")
    r["tt_entity"] = np.where(tid < 0, 0xFFFFFFFF, tid)
    r["rcs_hdb"] = sat(_f(det, "rcs_dbsm", n) * 2.0, -128, 127)
    return r


def generated_masks(dw: dict, det: dict, row: np.ndarray, nd: int) -> np.ndarray:
    """One existence mask per dwell for tables that carry no ``existence_mask``.

    Dwell part: D2-D9, D12-D17, D21-D27, D31, plus D18-D20 and D28-D30 when the table has
    those columns.  Target part: D32.1-D32.3 and D32.10 always, D32.16/17 with ``truth_id``;
    every other field only in dwells where at least one report has a finite value (absent
    stays absent).  D32.12-D32.15 are written as one group (Wireshark reads them so), only
    with D32.6 and D32.7 and when the slant-range, cross-range and range-rate σ are known;
    D32.14 then comes from ``sigma_height_m`` or :func:`height_sigma_m`.  A dwell without
    reports gets the file's target mask, so the mask stays constant (SPEC 3.4.1).
    """
    n = len(row)
    dmask = WRITE_DWELL_MASK
    if all(c in dw for c in ("sigma_track_rad", "sigma_speed_mps", "sigma_vz_mps")):
        dmask |= mask_of(dwell_fields=(18, 19, 20))
    if any(c in dw for c in ("sensor_heading_rad", "sensor_pitch_rad", "sensor_roll_rad")):
        dmask |= mask_of(dwell_fields=(28, 29, 30))

    counts_ = np.bincount(row, minlength=nd) if nd else np.zeros(0, np.int64)
    nonempty = np.flatnonzero(counts_ > 0)
    starts = (np.cumsum(counts_) - counts_)[nonempty]

    def avail(values):
        out = np.zeros(nd, bool)
        if values is None:
            return out, False
        ok = np.isfinite(np.asarray(values, float))
        if len(ok):          # rows are grouped by dwell: one reduceat over the groups
            out[nonempty] = np.logical_or.reduceat(ok, starts)
        return out, bool(out.any())

    per = {}
    file_level = {}
    for key, values in (("h", det.get("height_m")), ("los", det.get("los_velocity_mps")),
                        ("snr", det.get("snr_db")),
                        ("prob", det.get("classification_probability")),
                        ("sr", det.get("sigma_range_m")), ("cr", cross_range_sigma_m(det)),
                        ("rv", det.get("sigma_range_rate_mps")), ("rcs", det.get("rcs_dbsm"))):
        per[key], file_level[key] = avail(values)
    tm = np.full(nd, mask_of(target_fields=(1, 2, 3, 10)), dtype=np.uint64)
    base = mask_of(target_fields=(1, 2, 3, 10))

    def add(cond, fields, cond_file):
        nonlocal base
        bits = np.uint64(mask_of(target_fields=fields))
        tm[cond] |= bits
        if cond_file:
            base |= int(bits)

    add(per["h"], (6,), file_level["h"])
    add(per["los"], (7, 8), file_level["los"])
    add(per["snr"], (9,), file_level["snr"])
    add(per["prob"], (11,), file_level["prob"])
    sig = per["sr"] & per["cr"] & per["rv"] & per["h"] & per["los"]
    sig_file = all(file_level[k] for k in ("sr", "cr", "rv", "h", "los"))
    add(sig, (12, 13, 14, 15), sig_file)
    if "truth_id" in det:
        add(np.ones(nd, bool), (16, 17), True)
    add(per["rcs"], (18,), file_level["rcs"])
    counts = np.bincount(row, minlength=nd)
    tm[counts == 0] = np.uint64(base)
    return tm | np.uint64(dmask)


def encode_dwell_packets(dw: dict, det: dict, row: np.ndarray, masks: np.ndarray,
                         headers: np.ndarray, m: dict, epoch_sod: float,
                         piece_counts=None, piece_last=None,
                         max_packet_bytes: int = MAX_PACKET_BYTES):
    """Dwell packets of every dwell, in dwell order, as (parts, piece_dwell, piece_k).

    ``dw``: dwell columns (``nd`` rows in stream order); ``det``: detection columns grouped by
    dwell, ``row`` the dwell row of each (non-decreasing); ``masks``: the D1 mask of each dwell;
    ``headers``: a PACKET_HEADER record per dwell (P2 is filled in here).  ``piece_counts``
    (optional, per dwell a list of report counts) fixes how a dwell is split, as read;
    ``piece_last`` (optional, per dwell a list of D4 flags) likewise.  ``parts[i]`` is a tuple
    of byte strings that make up packet i.
    """
    nd = len(masks)
    nt = len(row)
    draw = dwell_raw(dw, nd, epoch_sod, m["sensor_position_sigma_m"])
    needed = set()
    for mask in np.unique(np.asarray(masks, dtype=np.uint64)).tolist():
        needed |= set(mask_layout(int(mask))[1].names)
    traw = target_raw(det, nt, row, dw, draw, m, needed)
    counts = np.bincount(row, minlength=nd) if nd else np.zeros(0, np.int64)
    first = np.concatenate([[0], np.cumsum(counts)[:-1]]) if nd else np.zeros(0, np.int64)
    last = np.asarray(_col(dw, "last_dwell", nd, False), dtype=bool)
    masks = np.asarray(masks, dtype=np.uint64)
    out_parts: list = [None] * 0
    piece_dwell: list = []
    piece_k: list = []
    per_dwell_parts: list = [None] * nd
    for mask in np.unique(masks).tolist():
        sel = np.flatnonzero(masks == np.uint64(mask))
        ddt, tdt, dnums, tnums = mask_layout(int(mask))
        if any(n not in dnums for n in MANDATORY_DWELL):
            raise ValueError(f"4607 writer: existence mask 0x{int(mask):016X} lacks mandatory "
                             "dwell fields")
        tlen = tdt.itemsize
        piece_dtype = np.dtype(PACKET_HEADER.descr + SEGMENT_HEADER.descr + [("mask", ">u8")]
                               + ddt.descr)
        fixed = piece_dtype.itemsize
        per_packet = (max_packet_bytes - fixed) // tlen if tlen else 2**31
        c = counts[sel]
        if piece_counts is None:
            n_pieces = np.maximum(1, -(-c // per_packet))
        else:
            n_pieces = np.array([len(piece_counts[i]) for i in sel], dtype=np.int64)
        p_sel = np.repeat(np.arange(len(sel)), n_pieces)
        p_dw = sel[p_sel]
        p_k = np.arange(len(p_sel)) - np.repeat(np.cumsum(n_pieces) - n_pieces, n_pieces)
        if piece_counts is None:
            p_count = np.clip(counts[p_dw] - p_k * per_packet, 0, per_packet)
            p_start = first[p_dw] + p_k * per_packet
            p_last = last[p_dw] & (p_k == n_pieces[p_sel] - 1)
        else:
            p_count = np.array([piece_counts[d][k] for d, k in zip(p_dw, p_k)], np.int64)
            p_start = first[p_dw] + np.array(
                [sum(piece_counts[d][:k]) for d, k in zip(p_dw, p_k)], np.int64)
            p_last = np.array([bool(piece_last[d][k]) for d, k in zip(p_dw, p_k)], bool)
        pk = np.zeros(len(p_dw), piece_dtype)
        for name in PACKET_HEADER.names:
            pk[name] = headers[name][p_dw]
        pk["size"] = fixed + p_count * tlen
        pk["seg_type"] = DWELL
        pk["seg_size"] = fixed - 32 + p_count * tlen
        pk["mask"] = mask
        for name in ddt.names:
            if name == "count":
                pk[name] = p_count
            elif name == "last":
                pk[name] = p_last
            else:
                pk[name] = draw[name][p_dw]
        pkb = pk.tobytes()
        # targets of this mask's dwells, in dwell order
        if len(sel) == nd:
            t_idx = np.arange(nt)
            tg = np.zeros(nt, tdt)
            for name in tdt.names:
                tg[name] = traw[name]
        else:
            t_idx = np.flatnonzero(np.isin(row, sel)) if nt else np.zeros(0, np.int64)
            tg = np.zeros(len(t_idx), tdt)
            for name in tdt.names:
                tg[name] = traw[name][t_idx]
        tgb = tg.tobytes()
        # position of each target of this mask in tgb: targets are in dwell order
        pos_in_group = np.full(nt, -1, np.int64)
        pos_in_group[t_idx] = np.arange(len(t_idx))
        starts = (pos_in_group[np.minimum(p_start, nt - 1)] if len(t_idx)
                  else np.zeros(len(p_dw), np.int64))
        starts = np.where(p_count > 0, starts, 0)
        for i, (d, a, cnt) in enumerate(zip(p_dw.tolist(), starts.tolist(), p_count.tolist())):
            part = (pkb[i * fixed:(i + 1) * fixed], tgb[a * tlen:(a + cnt) * tlen])
            if per_dwell_parts[d] is None:
                per_dwell_parts[d] = [part]
            else:
                per_dwell_parts[d].append(part)
    for d in range(nd):
        for k, part in enumerate(per_dwell_parts[d]):
            out_parts.append(part)
            piece_dwell.append(d)
            piece_k.append(k)
    return out_parts, np.array(piece_dwell, np.int64), np.array(piece_k, np.int64)


# ---------------------------------------------------------------------------------------------
# Decoding
# ---------------------------------------------------------------------------------------------

_WGS84_A = 6378137.0
_WGS84_E2 = 6.69437999014e-3


def _ecef(lat_deg, lon_deg, h_m):
    lat, lon = np.radians(lat_deg), np.radians(lon_deg)
    n = _WGS84_A / np.sqrt(1.0 - _WGS84_E2 * np.sin(lat) ** 2)
    return ((n + h_m) * np.cos(lat) * np.cos(lon), (n + h_m) * np.cos(lat) * np.sin(lon),
            (n * (1.0 - _WGS84_E2) + h_m) * np.sin(lat))


def slant_range(slat, slon, sh, tlat, tlon, th):
    """Slant range (m) between geodetic points (WGS-84 ECEF distance)."""
    sx, sy, sz = _ecef(slat, slon, sh)
    tx, ty, tz = _ecef(tlat, tlon, th)
    return np.sqrt((tx - sx) ** 2 + (ty - sy) ** 2 + (tz - sz) ** 2)


def range_azimuth(slat, slon, sh, tlat, tlon, th):
    """Slant range (m) and azimuth (rad, clockwise from north in the sensor's local ENU)."""
    sx, sy, sz = _ecef(slat, slon, sh)
    tx, ty, tz = _ecef(tlat, tlon, th)
    dx, dy, dz = tx - sx, ty - sy, tz - sz
    lat, lon = np.radians(slat), np.radians(slon)
    east = -np.sin(lon) * dx + np.cos(lon) * dy
    north = -np.sin(lat) * np.cos(lon) * dx - np.sin(lat) * np.sin(lon) * dy + np.cos(lat) * dz
    return np.sqrt(dx * dx + dy * dy + dz * dz), np.mod(np.arctan2(east, north), 2 * np.pi)


class MaskedColumns:
    """Raw fields of many records decoded under different existence masks, scattered into
    full-length int64 columns, each with a mask of the records that carried the field."""

    def __init__(self, n: int):
        self.n = n
        self._raw: dict[str, np.ndarray] = {}
        self._present: dict[str, np.ndarray] = {}

    def scatter(self, decoded: np.ndarray, rows: np.ndarray) -> None:
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


def read_dwell_segments(buf: np.ndarray, seg_off: np.ndarray, seg_size: np.ndarray, name):
    """Masks, counts and per-mask record bytes of Dwell segments (validated).

    Returns (mask uint64 per segment, count per segment, dwell fields MaskedColumns,
    target fields MaskedColumns).
    """
    ns = len(seg_off)
    body = seg_off + 5
    blen = seg_size - 5
    short = np.flatnonzero(blen < 8)
    if len(short):
        i = short[0]
        raise FormatError(f"{where(name)}byte offset {int(body[i])}: dwell segment body of "
                          f"{int(blen[i])} bytes, too short for the 8-byte D1 mask")
    masks = gather(buf, body, 8).view(">u8").astype(np.uint64) if ns else np.zeros(0, np.uint64)
    dlen = np.zeros(ns, np.int64)
    tlen = np.zeros(ns, np.int64)
    uniq = np.unique(masks).tolist()
    for mask in uniq:
        ddt, tdt, dnums, _ = mask_layout(int(mask))
        sel = masks == np.uint64(mask)
        missing = [n for n in MANDATORY_DWELL if n not in dnums]
        if missing:
            i = int(np.flatnonzero(sel)[0])
            raise FormatError(f"{where(name)}byte offset {int(body[i])}: dwell existence mask "
                              f"0x{int(mask):016X} lacks mandatory fields "
                              f"{', '.join('D%d' % n for n in missing)}")
        dlen[sel] = ddt.itemsize
        tlen[sel] = tdt.itemsize
    short = np.flatnonzero(blen < 8 + dlen)
    if len(short):
        i = short[0]
        raise FormatError(f"{where(name)}byte offset {int(body[i])}: dwell body of "
                          f"{int(blen[i])} bytes, mask 0x{int(masks[i]):016X} needs "
                          f"{int(8 + dlen[i])} before the target reports")
    # D5 sits after D2, D3, D4: body offset 8 + 2 + 2 + 1
    count = gather(buf, body + 13, 2).view(">u2").astype(np.int64) if ns else np.zeros(0, np.int64)
    expect = 8 + dlen + count * tlen
    bad = np.flatnonzero(blen != expect)
    if len(bad):
        i = bad[0]
        raise FormatError(f"{where(name)}byte offset {int(seg_off[i]) + 1}: dwell segment size "
                          f"{int(seg_size[i])} but mask 0x{int(masks[i]):016X} with D5 = "
                          f"{int(count[i])} target reports of {int(tlen[i])} bytes needs "
                          f"{int(expect[i]) + 5}")
    nt = int(count.sum())
    dcols = MaskedColumns(ns)
    tcols = MaskedColumns(nt)
    seg_tfirst = np.concatenate([[0], np.cumsum(count)[:-1]]) if ns else np.zeros(0, np.int64)
    for mask in uniq:
        ddt, tdt, _, _ = mask_layout(int(mask))
        segs = np.flatnonzero(masks == np.uint64(mask))
        dcols.scatter(np.frombuffer(gather(buf, body[segs] + 8, ddt.itemsize).tobytes(), ddt),
                      segs)
        c = count[segs]
        if tdt.itemsize and c.sum():
            raw = gather_var(buf, body[segs] + 8 + ddt.itemsize, c * tdt.itemsize)
            pos = np.repeat(seg_tfirst[segs] - (np.cumsum(c) - c), c) + np.arange(int(c.sum()))
            tcols.scatter(np.frombuffer(raw.tobytes(), tdt), pos)
    return masks, count, dcols, tcols


def decode_dwells(seg_off, seg_job, seg_ref, masks, counts, dcols: MaskedColumns,
                  tcols: MaskedColumns, time_s, name):
    """(dwells, detections, seg_dwell) tables from the decoded Dwell segments.

    Pieces of one dwell split over several packets (consecutive segments with equal job, D2,
    D3, D6 and reference day, the earlier one not marked last) are merged into one dwell.
    """
    ns = len(masks)
    rcol, fcol = dcols.raw, dcols.value
    rev, _ = rcol("revisit")
    dwi, _ = rcol("dwell")
    tms, _ = rcol("time_ms")
    last, _ = rcol("last")
    if np.any(last > 1):
        bad = int(np.flatnonzero(last > 1)[0])
        raise FormatError(f"{where(name)}byte offset {int(seg_off[bad]) + 5 + 8 + 4}: D4 "
                          f"last-dwell flag {int(last[bad])}, expected 0 or 1")
    key_change = np.ones(ns, dtype=bool)
    if ns > 1:
        key_change[1:] = ((seg_job[1:] != seg_job[:-1]) | (rev[1:] != rev[:-1])
                          | (dwi[1:] != dwi[:-1]) | (tms[1:] != tms[:-1])
                          | (seg_ref[1:] != seg_ref[:-1]) | (last[:-1] == 1)
                          | (masks[1:] != masks[:-1]))
    seg_dwell = np.cumsum(key_change) - 1
    nd = int(seg_dwell[-1]) + 1 if ns else 0
    firsts = np.flatnonzero(key_change)

    def first(x):
        return x[firsts]

    dw_counts = np.bincount(seg_dwell, weights=counts, minlength=nd).astype(np.int64)
    dw_last = np.bincount(seg_dwell, weights=last, minlength=nd) > 0
    t_s = time_s(seg_ref, tms)
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
        "existence_mask": first(masks).astype(np.uint64),
        "dwell_time_ms": first(tms),
        "time_s": first(t_s),
        "platform_lat_deg": first(fcol("lat", lambda r: dec_sa(r, 32))),
        "platform_lon_deg": first(fcol("lon", lambda r: lon_180(dec_ba(r, 32)))),
        "platform_height_m": first(fcol("alt_cm", lambda r: r / 100.0)),
        "lat_scale_deg": first(fcol("lat_scale", lambda r: dec_sa(r, 32))),
        "lon_scale_deg": first(fcol("lon_scale", lambda r: dec_ba(r, 32))),
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
        "sensor_heading_rad": first(_sensor_angle(rcol, "sensor_heading", True)),
        "sensor_pitch_rad": first(_sensor_angle(rcol, "sensor_pitch", False)),
        "sensor_roll_rad": first(_sensor_angle(rcol, "sensor_roll", False)),
        "mdv_mps": first(fcol("mdv_dmps", lambda r: r / 10.0)),
    }

    nt = int(counts.sum())
    t_seg = np.repeat(np.arange(ns), counts)
    tr, tf = tcols.raw, tcols.value
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
        raise FormatError(f"{where(name)}byte offset {int(seg_off[bad]) + 5}: dwell sends delta "
                          "positions D32.4/D32.5 without the scale factors D10/D11")
    lat_raw = np.where(hr_ok, hr_lat, area_lat_raw[t_seg] + d_lat * lsc_raw[t_seg])
    out_of_range = use_delta & ((lat_raw < -2**31) | (lat_raw >= 2**31))
    if np.any(out_of_range):
        bad = int(t_seg[np.flatnonzero(out_of_range)[0]])
        raise FormatError(f"{where(name)}byte offset {int(seg_off[bad]) + 5}: a delta latitude "
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
    with np.errstate(invalid="ignore", divide="ignore"):
        rng, az = range_azimuth(slat, slon, sh, lat, lon,
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
        "los_velocity_mps": tf("los_cmps", lambda r: r / 100.0),
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
    return dwells, dets, seg_dwell


def _sensor_angle(rcol, fname, unsigned):
    """D28-D30: if any of them is present an absent one means 0 deg (SPEC 3.4.28)."""
    r, ok = rcol(fname)
    any_ok = rcol("sensor_heading")[1] | rcol("sensor_pitch")[1] | rcol("sensor_roll")[1]
    deg = dec_ba(r, 16) if unsigned else dec_sa(r, 16)
    return np.where(any_ok, np.radians(np.where(ok, deg, 0.0)), np.nan)
