"""STANAG 4607 reader: a packet stream into tables, and those tables back into the same bytes
(:mod:`formats.stanag4607` documents both)."""
from __future__ import annotations

from datetime import date
from typing import Mapping

import numpy as np

from .._io import n_rows, parse_epoch
from ..errors import FormatError, where
from .dwell import decode_dwells, encode_dwell_packets, read_dwell_segments
from .layout import (DWELL, FREE_TEXT, JOB_DEFINITION, MISSION, PLATFORM_LOCATION,
                     TEST_STATUS, dec_text_array, enc_ba16, enc_text, sat)
from .packet import PACKET_HEADER, frame, gather, open_source
from .segments import (JOB_BODY, MISSION_BODY, PLATFORM_BODY, TEST_STATUS_BODY,
                       decode_free_text, decode_jobs, decode_missions, decode_platform,
                       decode_test_status, encode_jobs, encode_test_status, free_text_body,
                       mission_body, platform_records)
from .writer import DEFAULT_META, attach_detections


# ---------------------------------------------------------------------------------------------
# Re-encoding tables read from 4607 (lossless)
# ---------------------------------------------------------------------------------------------

READ_TABLES = ("packets", "segments", "missions", "jobs", "dwells", "detections",
               "platform_locations", "free_texts", "test_status")


def encode_read_tables(tables: Mapping[str, Mapping[str, np.ndarray]]) -> bytes:
    """Re-encode the tables :func:`read_4607` returned (possibly stored and read back).

    Packet order, packet headers, every Mission, Job Definition, Free Text, Platform Location,
    Test and Status and Dwell segment, each dwell's existence mask, its split into packets and
    every field are kept, so a valid file comes back byte for byte.  HRR, processing history,
    tasking and unknown segment types are not read and are left out (their packets shrink).
    """
    missing = [t for t in READ_TABLES if t not in tables]
    if missing:
        raise ValueError(f"4607 re-encoding needs the tables {list(READ_TABLES)}; missing "
                         f"{missing}")
    pk = {k: np.asarray(v) for k, v in tables["packets"].items()}
    sg = {k: np.asarray(v) for k, v in tables["segments"].items()}
    dw = {k: np.asarray(v) for k, v in tables["dwells"].items()}
    det = {k: np.asarray(v) for k, v in tables["detections"].items()}
    nd = n_rows(dw, "dwells")
    nt = n_rows(det, "detections")
    bodies: dict = {}
    # small segments
    mi = tables["missions"]
    for r in range(len(mi["packet"])):
        bodies[(MISSION, r)] = mission_body(
            mi["mission_plan"][r], mi["flight_plan"][r], int(mi["platform_type"][r]),
            mi["platform_configuration"][r], date.fromisoformat(str(mi["reference_date"][r])))
    jb = encode_jobs(tables["jobs"], np.arange(len(tables["jobs"]["packet"])))
    for r in range(len(jb)):
        bodies[(JOB_DEFINITION, r)] = jb[r:r + 1].tobytes()
    ft = tables["free_texts"]
    for r in range(len(ft["packet"])):
        bodies[(FREE_TEXT, r)] = free_text_body(ft["originator"][r], ft["recipient"][r],
                                                ft["text"][r])
    pl = tables["platform_locations"]
    if len(pl["packet"]):
        track, speed = np.asarray(pl["track_rad"], float), np.asarray(pl["speed_mps"], float)
        rec = platform_records(pl["time_ms"], pl["lat_deg"], pl["lon_deg"], pl["height_m"],
                               speed * np.sin(track), speed * np.cos(track), pl["vz_mps"])
        rec["track"] = enc_ba16(np.degrees(track))
        rec["speed_mmps"] = sat(speed * 1000.0, 0, 2**32 - 1)
        for r in range(len(rec)):
            bodies[(PLATFORM_LOCATION, r)] = rec[r:r + 1].tobytes()
    ts = tables["test_status"]
    rec = encode_test_status(ts, np.arange(len(ts["packet"])))
    for r in range(len(rec)):
        bodies[(TEST_STATUS, r)] = rec[r:r + 1].tobytes()
    # dwell pieces, as read
    seg_type = np.asarray(sg["seg_type"], np.int64)
    dseg = np.flatnonzero(seg_type == DWELL)
    seg_dwell = np.asarray(sg["dwell_row"], np.int64)[dseg]
    piece_counts = [[] for _ in range(nd)]
    piece_last = [[] for _ in range(nd)]
    for d, c, last in zip(seg_dwell.tolist(), np.asarray(sg["target_count"])[dseg].tolist(),
                          np.asarray(sg["last_dwell"])[dseg].tolist()):
        piece_counts[d].append(c)
        piece_last[d].append(last)
    if nd:
        d_ids = np.asarray(dw["dwell_id"], np.int64)
        row, det = attach_detections(dw, det, nd, nt)
        m = dict(DEFAULT_META, sensor_position_sigma_m=(0.0, 0.0, 0.0))
        parts, p_dwell, _ = encode_dwell_packets(
            dw, det, row, np.asarray(dw["existence_mask"], np.uint64),
            np.zeros(nd, PACKET_HEADER), m, 0.0, piece_counts=piece_counts,
            piece_last=piece_last)
        del d_ids
        for j, (seg_row, part) in enumerate(zip(np.flatnonzero(seg_type[dseg] >= 0), parts)):
            bodies[(DWELL, j)] = (part[0][32 + 5:], part[1])
    # the packets
    out = []
    seg_packet = np.asarray(sg["packet"], np.int64)
    seg_row = np.asarray(sg["row"], np.int64)
    starts = np.searchsorted(seg_packet, np.arange(len(pk["offset"])), side="left")
    ends = np.searchsorted(seg_packet, np.arange(len(pk["offset"])), side="right")
    dwell_piece = np.full(len(seg_type), -1, np.int64)
    dwell_piece[dseg] = np.arange(len(dseg))
    for p in range(len(pk["offset"])):
        segs = []
        for j in range(starts[p], ends[p]):
            t = int(seg_type[j])
            if t == DWELL:
                body = b"".join(bodies[(DWELL, int(dwell_piece[j]))])
            elif (t, int(seg_row[j])) in bodies:
                body = bodies[(t, int(seg_row[j]))]
            else:
                continue
            segs.append(bytes([t]) + (5 + len(body)).to_bytes(4, "big") + body)
        payload = b"".join(segs)
        h = np.zeros(1, PACKET_HEADER)
        h["version"] = str(pk["version"][p]).encode("ascii")
        h["size"] = 32 + len(payload)
        h["nationality"] = enc_text(pk["nationality"][p], 2)
        h["classification"] = pk["classification"][p]
        h["class_system"] = enc_text(pk["classification_system"][p], 2)
        h["security_codes"] = pk["security_codes"][p]
        h["exercise"] = pk["exercise_indicator"][p]
        h["platform_id"] = enc_text(pk["platform_id"][p], 10)
        h["mission_id"] = pk["mission_id"][p]
        h["job_id"] = pk["job_id"][p]
        out.append(h.tobytes() + payload)
    return b"".join(out)


# ---------------------------------------------------------------------------------------------
# Reader
# ---------------------------------------------------------------------------------------------

def read_4607(source, *, epoch_utc: str | None = None,
              max_packet_size: int | None = None) -> dict:
    """Read a 4607 file into tables (dicts of numpy columns).

    Returns a dict with the tables ``packets``, ``segments``, ``missions``, ``jobs``,
    ``dwells``, ``detections``, ``platform_locations``, ``free_texts``, ``test_status`` and
    ``attrs`` (a plain dict: ``scene_epoch_utc``, ``time_origin``).  ``time_s`` columns count
    from ``epoch_utc`` if given, else from the ``scene_epoch_utc=`` Free Text a gmtiflow file
    carries, else from 00:00 UTC of the first Mission segment's reference date.

    ``dwells`` has one row per dwell (pieces of a dwell split over several packets are merged:
    consecutive Dwell segments with equal job, revisit index, dwell index, dwell time and mask),
    with its ``existence_mask``, ``platform_id``, ``mission_id`` and ``sensor_id`` (the platform
    and mission pairs numbered in order of appearance).  ``detections`` uses the /detections
    column names where 4607 carries the quantity; ``los_velocity_mps`` is D32.7 (LOS velocity
    corrected for platform motion); absent fields are NaN (floats) or -1 (ids).
    ``range_m``/``azimuth_rad`` are derived from the sensor and target positions (azimuth in
    the sensor's local ENU), and ``sigma_azimuth_rad`` = cross-range sigma / ``range_m``.
    An empty source (0 bytes) is a FormatError: it holds no packet.
    """
    f, close, name = open_source(source)
    try:
        data = f.read()
    finally:
        if close:
            f.close()
    if not isinstance(data, (bytes, bytearray)):
        raise FormatError(f"{where(name)}source is not a binary file (open it with 'rb')")
    if len(data) == 0:
        raise FormatError(f"{where(name)}empty (0 bytes): a 4607 file holds at least one "
                          "32-byte packet")
    return decode_4607(data, name, epoch_utc=epoch_utc, max_packet_size=max_packet_size)


def decode_4607(data: bytes, name=None, *, epoch_utc: str | None = None,
                max_packet_size: int | None = None) -> dict:
    """:func:`read_4607` of a byte string (0 bytes give empty tables)."""
    fr = frame(data, name, max_packet_size=max_packet_size)
    buf = np.frombuffer(data, np.uint8)
    npk = len(fr.packet_offset)
    hdr = np.frombuffer(gather(buf, fr.packet_offset, 32).tobytes(), PACKET_HEADER)
    packets = {
        "offset": fr.packet_offset, "version": dec_text_array(hdr["version"]),
        "size": fr.packet_size,
        "nationality": dec_text_array(hdr["nationality"]),
        "classification": hdr["classification"].astype(np.uint8),
        "classification_system": dec_text_array(hdr["class_system"]),
        "security_codes": hdr["security_codes"].astype(np.int64),
        "exercise_indicator": hdr["exercise"].astype(np.uint8),
        "platform_id": dec_text_array(hdr["platform_id"]),
        "mission_id": hdr["mission_id"].astype(np.int64),
        "job_id": hdr["job_id"].astype(np.int64),
        "n_segments": np.bincount(fr.segment_packet, minlength=npk).astype(np.int64),
    }
    st, so, ss, sp = fr.segment_type, fr.segment_offset, fr.segment_size, fr.segment_packet
    nseg = len(st)
    seg_row = np.full(nseg, -1, np.int64)

    def of_type(t):
        idx = np.flatnonzero(st == t)
        seg_row[idx] = np.arange(len(idx))
        return idx

    # Missions and the reference day in force at every segment
    mi = of_type(MISSION)
    mt = decode_missions(gather(buf, so[mi] + 5, MISSION_BODY.itemsize))
    ymd = mt["year"] * 10000 + mt["month"] * 100 + mt["day"]
    uniq, first, inv = np.unique(ymd, return_index=True, return_inverse=True)
    u_days = np.zeros(len(uniq), np.int64)
    u_text = []
    for u, (r, v) in enumerate(zip(first.tolist(), uniq.tolist())):
        y, mo, d = v // 10000, v // 100 % 100, v % 100
        try:
            ref = date(y, mo, d)
        except ValueError as exc:
            bad = int(np.flatnonzero(ymd == v)[0])
            raise FormatError(f"{where(name)}byte offset {int(so[mi[bad]]) + 5 + 36}: mission "
                              f"reference date {y}-{mo}-{d} is not a date ({exc})") from None
        u_days[u] = (ref - date(1970, 1, 1)).days
        u_text.append(ref.isoformat())
    inv = inv.reshape(-1)
    ref_days = u_days[inv] if len(mi) else np.zeros(0, np.int64)
    ref_dates = np.array(u_text, dtype=str)[inv] if len(mi) else np.zeros(0, dtype=str)
    k = np.searchsorted(mi, np.arange(nseg), side="right") - 1
    seg_ref = np.where(k >= 0, ref_days[np.maximum(k, 0)] if len(mi) else -1, -1)
    missions = {"packet": sp[mi], "mission_plan": mt["mission_plan"],
                "flight_plan": mt["flight_plan"], "platform_type": mt["platform_type"],
                "platform_configuration": mt["platform_configuration"],
                "reference_date": ref_dates}

    # Free texts (the epoch text)
    fi = of_type(FREE_TEXT)
    texts = []
    epoch_text = None
    for j in fi.tolist():
        body = data[so[j] + 5:so[j] + ss[j]]
        if len(body) < 20:
            raise FormatError(f"{where(name)}byte offset {int(so[j]) + 1}: free text segment "
                              f"body of {len(body)} bytes, expected >= 20")
        orig, recip, text = decode_free_text(body)
        texts.append((int(sp[j]), orig, recip, text))
        if text.startswith("scene_epoch_utc=") and epoch_text is None:
            epoch_text = text.split("=", 1)[1].strip()

    # Time origin
    epoch_str = epoch_utc if epoch_utc is not None else epoch_text
    first_ref = next((int(r) for r in seg_ref if r >= 0), None)
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

    def time_s(ref_days_, ms):
        ref_days_ = np.asarray(ref_days_, dtype=np.float64)
        base = np.where(ref_days_ >= 0, ref_days_, first_ref or 0) * 86400.0 - epoch_posix
        return base + np.asarray(ms, dtype=np.float64) / 1000.0

    out: dict = {"packets": packets, "missions": missions}
    ji = of_type(JOB_DEFINITION)
    out["jobs"] = dict({"packet": sp[ji]}, **decode_jobs(gather(buf, so[ji] + 5,
                                                                JOB_BODY.itemsize)))
    li = of_type(PLATFORM_LOCATION)
    plat = decode_platform(gather(buf, so[li] + 5, PLATFORM_BODY.itemsize))
    out["platform_locations"] = dict({"packet": sp[li], "time_s": time_s(seg_ref[li],
                                                                         plat["time_ms"])}, **plat)
    out["free_texts"] = {
        "packet": np.array([t[0] for t in texts], np.int64),
        "originator": np.array([t[1] for t in texts], dtype=str),
        "recipient": np.array([t[2] for t in texts], dtype=str),
        "text": np.array([t[3] for t in texts], dtype=str)}
    ti = of_type(TEST_STATUS)
    tst = decode_test_status(gather(buf, so[ti] + 5, TEST_STATUS_BODY.itemsize))
    out["test_status"] = dict({"packet": sp[ti], "time_s": time_s(seg_ref[ti], tst["time_ms"])},
                              **tst)

    # Dwells
    di = of_type(DWELL)
    masks, counts, dcols, tcols = read_dwell_segments(buf, so[di], ss[di], name)
    seg_job = packets["job_id"][sp[di]]
    dwells, dets, seg_dwell = decode_dwells(so[di], seg_job, seg_ref[di], masks, counts, dcols,
                                            tcols, time_s, name)
    first_seg = di[np.flatnonzero(np.r_[True, seg_dwell[1:] != seg_dwell[:-1]])] if len(di) \
        else np.zeros(0, np.int64)
    d_pkt = sp[first_seg]
    dwells["platform_id"] = packets["platform_id"][d_pkt]
    dwells["mission_id"] = packets["mission_id"][d_pkt]
    dwells["sensor_id"] = _sensor_numbers(dwells["platform_id"], dwells["mission_id"])
    out["dwells"] = dwells
    out["detections"] = dets
    dwell_row = np.full(nseg, -1, np.int64)
    dwell_row[di] = seg_dwell
    tcount = np.zeros(nseg, np.int64)
    tcount[di] = counts
    last = np.full(nseg, -1, np.int8)
    last[di] = dcols.raw("last")[0]
    out["segments"] = {"packet": sp, "seg_type": st, "offset": so, "size": ss, "row": seg_row,
                       "dwell_row": dwell_row, "target_count": tcount, "last_dwell": last}
    out["attrs"] = {"scene_epoch_utc": epoch_str, "time_origin": origin}
    return out


def _sensor_numbers(platform_id: np.ndarray, mission_id: np.ndarray) -> np.ndarray:
    """0, 1, ... for the distinct (platform id, mission id) pairs, in order of appearance."""
    if len(platform_id) == 0:
        return np.zeros(0, np.int64)
    key = np.char.add(np.char.add(platform_id.astype(str), "\x1f"), mission_id.astype(str))
    uniq, first, inv = np.unique(key, return_index=True, return_inverse=True)
    rank = np.empty(len(uniq), np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(len(uniq))
    return rank[inv.reshape(-1)]
