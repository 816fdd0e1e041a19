"""STANAG 4607 / AEDP-4607 (GMTIF) writer and reader: the public API.

Layout, scalings and rules follow AEDP-4607 Ed. A v1, whose field layout equals STANAG 4607
Ed. 3.  All multi-byte fields are big-endian.  The codec lives in :mod:`formats.s4607`, split
along its seams (layout and scalings, packet framing, the small segments, the Dwell segment);
this module composes them.

Writer (:func:`write_4607`, :func:`encode_4607`)
------------------------------------------------
One segment per packet, every packet <= 65,535 bytes (AEDP-4607.1 G.7.3 minimum capability).
Stream: ``Mission, Job Definition, [Free Text with the scene epoch, first time only]``, then the
Dwell packets; Mission + Job Definition are repeated at the start of every revisit and before any
dwell that comes >= 30 s after the last repetition (SPEC 3.3: Mission every 2 min; 3.7: Job
Definition every 30 s).  Mission, Job Definition, Free Text and Platform Location packets carry
P10 = 0 and Dwell packets P10 = job id (SPEC 3.1.10).  Every dwell is sent, even without targets.

Several sensors (a ``sensor_id`` column on the dwells, 0..S-1): each sensor is its own platform
(P8 ``platform_id`` + sensor number, its own P9 mission id and job id), with its own Mission
and Job Definition packets, and the dwells of all sensors are interleaved in time order, as a
recording of several aircraft would be.

Existence masks: one per dwell (:func:`formats.s4607.dwell.generated_masks`; absent stays
absent), or the ``existence_mask`` column of tables read from 4607, which makes
:func:`encode_read_tables` re-create a file read by :func:`read_4607` byte for byte.

Reader (:func:`iter_packets`, :func:`read_4607`)
------------------------------------------------
Parses any conforming file: every segment is framed by its S2 size, unknown types are skipped,
dwells are decoded for any existence mask (per-mask structured dtypes, targets decoded
vectorised), hi-res or reduced-resolution (D10/D11 + D32.4/5) positions, D5 = 0 with D32 bits
set.  :func:`read_4607` frames the whole buffer in one linear pass and decodes every segment
type vectorised.  Malformed input raises :class:`~formats.errors.FormatError` naming the byte
offset.
"""
from __future__ import annotations

from datetime import date, datetime, timedelta, timezone
from typing import Iterator, Mapping

import numpy as np

from ._io import n_rows, parse_epoch, write_atomic
from .errors import FormatError, where
from .s4607.dwell import (WRITE_DWELL_MASK, decode_dwells, encode_dwell_packets,
                          generated_masks, mask_layout, read_dwell_segments, tshark_safe_mask)
from .s4607.layout import (DWELL, DWELL_FIELDS, FREE_TEXT, HRR, JOB_DEFINITION, MANDATORY_DWELL,
                           MAX_PACKET_BYTES, MISSION, PLATFORM_LOCATION, PROC_HISTORY,
                           TARGET_FIELDS, TEST_STATUS, dec_b16, dec_ba, dec_sa, dec_text,
                           dec_text_array, dwell_mask_bit, enc_b16, enc_ba16, enc_ba32, enc_sa16,
                           enc_sa32, enc_text, lon_180, sat, target_mask_bit)
from .s4607.packet import (FIXED_BODY_SIZES, PACKET_HEADER, SEGMENT_HEADER, Packet, Segment,
                           frame, gather, iter_packets, open_source)
from .s4607.segments import (JOB_BODY, MISSION_BODY, PLATFORM_BODY, TEST_STATUS_BODY,
                             decode_free_text, decode_jobs, decode_missions, decode_platform,
                             decode_test_status, encode_jobs, encode_test_status, free_text_body,
                             job_body, mission_body, platform_records)

__all__ = [
    "write_4607", "encode_4607", "encode_read_tables", "resolve_meta",
    "platform_location_packets", "iter_packets", "read_4607", "Packet", "Segment",
    "DEFAULT_META", "MAX_PACKET_BYTES", "dwell_mask_bit", "target_mask_bit", "tshark_safe_mask",
]
_sat = sat


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


def _median_revisit_s(dwells) -> float:
    if "revisit_id" not in dwells or len(dwells["revisit_id"]) == 0:
        return 0.0
    rev = np.asarray(dwells["revisit_id"])
    t = np.asarray(dwells["time_s"], dtype=np.float64)
    starts = np.flatnonzero(np.r_[True, rev[1:] != rev[:-1]])
    if len(starts) < 2:
        return 0.0
    return float(np.median(np.diff(t[starts])))


# ---------------------------------------------------------------------------------------------
# Writer
# ---------------------------------------------------------------------------------------------

def _packet_header(m: dict, edition: str, size: int, job_id: int) -> np.ndarray:
    h = np.zeros(1, PACKET_HEADER)
    h["version"] = edition.encode("ascii")
    h["size"] = size
    h["nationality"] = enc_text(m["nationality"], 2)
    h["classification"] = m["classification"]
    h["class_system"] = enc_text(m["classification_system"], 2)
    h["security_codes"] = m["security_codes"]
    h["exercise"] = m["exercise_indicator"]
    h["platform_id"] = enc_text(m["platform_id"], 10)
    h["mission_id"] = m["mission_id"]
    h["job_id"] = job_id
    return h


def _single_segment_packet(m, edition, seg_type, body: bytes, job_id=0) -> bytes:
    size = 32 + 5 + len(body)
    seg = np.zeros(1, SEGMENT_HEADER)
    seg["seg_type"], seg["seg_size"] = seg_type, 5 + len(body)
    return _packet_header(m, edition, size, job_id).tobytes() + seg.tobytes() + body


def _mission_body(m: dict) -> bytes:
    return mission_body(m["mission_plan"], m["flight_plan"], m["platform_type"],
                        m["platform_configuration"], m["epoch"].date())


def _epoch_sod(epoch: datetime) -> float:
    midnight = datetime(epoch.year, epoch.month, epoch.day, tzinfo=timezone.utc)
    return (epoch - midnight) / timedelta(seconds=1)


def sensor_meta(m: dict, sensor: int, n_sensors: int) -> dict:
    """The meta of one sensor of a multi-sensor run: P8 = platform id + sensor number (within
    10 characters), P9 = mission id + sensor, job id + sensor.  One sensor: ``m`` unchanged."""
    if n_sensors <= 1:
        return m
    suffix = str(sensor)
    out = dict(m)
    out["platform_id"] = str(m["platform_id"])[:10 - len(suffix)] + suffix
    out["mission_id"] = int(m["mission_id"]) + sensor
    out["job_id"] = int(m["job_id"]) + sensor
    return out


def _sensor_ids(dwells: Mapping, nd: int) -> np.ndarray:
    if "sensor_id" not in dwells:
        return np.zeros(nd, np.int64)
    s = np.asarray(dwells["sensor_id"], np.int64)
    if nd and (s.min() < 0):
        raise ValueError("4607 writer: dwells sensor_id must be >= 0")
    return s


def encode_4607(dwells: Mapping[str, np.ndarray], detections: Mapping[str, np.ndarray],
                meta: Mapping, *, edition: str = "30",
                platform: Mapping[str, np.ndarray] | None = None,
                max_packet_bytes: int = MAX_PACKET_BYTES) -> bytes:
    """The bytes of a 4607 file for these tables (see the module docstring and docs/formats.md).

    ``dwells`` needs ``dwell_id revisit_id dwell_index last_dwell time_s platform_lat_deg
    platform_lon_deg platform_height_m area_lat_deg area_lon_deg range_half_extent_m
    angle_half_extent_rad``; ``platform_vx_mps ... platform_bank_rad mdv_mps sensor_id`` are
    used when present (0 otherwise).  ``detections`` needs ``dwell_id lat_deg lon_deg``; the
    optional columns each add their D32 field (D32.7 from ``los_velocity_mps``: the LOS velocity
    corrected for platform motion).  ``platform`` (a /platform table) adds Platform Location
    packets, interleaved by time.  ``max_packet_bytes`` (default 65,535) splits dwells into
    smaller packets, e.g. 65,507 to fit UDP datagrams.
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
    epoch_sod = _epoch_sod(epoch)

    # --- order the dwells by time (stable) and attach every detection to its dwell row -------
    d_time = np.asarray(dwells["time_s"], dtype=np.float64) if nd else np.zeros(0)
    if _increasing(d_time):                 # already in time order: no copy
        d_order = np.arange(nd)
        dw = {k: np.asarray(v) for k, v in dwells.items()}
    else:
        d_order = np.argsort(d_time, kind="stable")
        dw = {k: np.asarray(v)[d_order] for k, v in dwells.items()}
    row, det = _attach(dw, detections, nd, nt)
    sensor = _sensor_ids(dw, nd)
    n_sensors = int(sensor.max()) + 1 if nd else 1
    metas = []
    for s in range(n_sensors):
        if n_sensors == 1:
            metas.append(m)
            continue
        sel = sensor == s
        ms = resolve_meta(meta, {k: v[sel] for k, v in dw.items()},
                          {k: v[sel[row]] for k, v in det.items()})
        metas.append(sensor_meta(ms, s, n_sensors))

    masks = (np.asarray(dw["existence_mask"], np.uint64) if "existence_mask" in dw
             else generated_masks(dw, det, row, nd))
    headers = np.zeros(nd, PACKET_HEADER)
    for s, ms in enumerate(metas):
        h = _packet_header(ms, edition, 0, int(ms["job_id"]))
        for name in PACKET_HEADER.names:
            headers[name][sensor == s] = h[name][0]
    parts, p_dwell, p_k = encode_dwell_packets(dw, det, row, masks, headers, m, epoch_sod,
                                               max_packet_bytes=max_packet_bytes)

    # --- the stream ------------------------------------------------------------------------
    heads = [(_single_segment_packet(ms, edition, MISSION, _mission_body(ms)),
              _single_segment_packet(ms, edition, JOB_DEFINITION, job_body(ms))) for ms in metas]
    out: list = []
    if n_sensors == 1 or not nd:
        out += heads[0]
    if m["write_epoch_text"] and (n_sensors == 1 or not nd):
        out.append(_epoch_text_packet(m, edition))

    plat_times = np.zeros(0)
    plat_bytes = None
    if platform is not None and n_rows(platform, "platform"):
        plat_bytes = memoryview(platform_location_packets(platform, meta, edition=edition))
        plat_times = np.asarray(platform["time_s"], dtype=np.float64)
    pl_len = 32 + 5 + PLATFORM_BODY.itemsize
    piece_time = d_time[d_order][p_dwell] if nd else np.zeros(0)
    kinds = np.concatenate([np.zeros(len(plat_times), np.int8), np.ones(len(p_dwell), np.int8)])
    idx = np.concatenate([np.arange(len(plat_times)), np.arange(len(p_dwell))])
    order = np.lexsort((kinds, np.concatenate([plat_times, piece_time])))
    revs = (np.asarray(dw.get("revisit_id", np.zeros(nd)), np.int64)[p_dwell]).tolist()
    p_sensor = sensor[p_dwell].tolist()
    p_k_l = p_k.tolist()
    piece_time_l = piece_time.tolist()
    last_header_t = [None] * n_sensors
    prev_rev = [None] * n_sensors
    if n_sensors == 1 and nd:
        last_header_t[0], prev_rev[0] = piece_time_l[0], revs[0]
    epoch_sent = n_sensors == 1 or not nd
    for kind, i in zip(kinds[order].tolist(), idx[order].tolist()):
        if kind == 0:
            out.append(plat_bytes[i * pl_len:(i + 1) * pl_len])
            continue
        s = p_sensor[i]
        if p_k_l[i] == 0 and (last_header_t[s] is None or revs[i] != prev_rev[s]
                              or piece_time_l[i] - last_header_t[s] >= JOB_RESEND_S):
            out += heads[s]
            last_header_t[s] = piece_time_l[i]
            if not epoch_sent and m["write_epoch_text"]:
                out.append(_epoch_text_packet(metas[s], edition))
            epoch_sent = True
        prev_rev[s] = revs[i]
        out += parts[i]
    return b"".join(out)


def _epoch_text_packet(m: dict, edition: str) -> bytes:
    iso = m["epoch"].strftime("%Y-%m-%dT%H:%M:%S.%fZ")
    return _single_segment_packet(m, edition, FREE_TEXT,
                                  free_text_body("GMTIFLOW", "ALL", f"scene_epoch_utc={iso}"))


def _attach(dw: dict, detections: Mapping, nd: int, nt: int):
    """(dwell row of each detection, detections grouped by dwell row in det_id order).

    Run tables come in that order already (dwell ids increasing in time, detections by dwell
    and det_id): then no search and no copy is made; any other order is sorted here."""
    if not nt:
        return np.zeros(0, np.int64), {k: np.asarray(v)[:0] for k, v in detections.items()}
    d_ids = np.asarray(dw.get("dwell_id", np.zeros(nd)), dtype=np.int64)
    t_dwell = np.asarray(detections["dwell_id"], dtype=np.int64)
    if nd and d_ids[-1] - d_ids[0] == nd - 1 and _increasing(d_ids, strict=True):
        row = t_dwell - d_ids[0]            # consecutive ids: the row is the id's offset
        bad = (row < 0) | (row >= nd)
        if bad.any():
            raise ValueError(f"4607 writer: detection dwell_id {t_dwell[bad][0]} is not in the "
                             "dwells table")
    else:
        sorter = np.argsort(d_ids, kind="stable")
        pos = np.minimum(np.searchsorted(d_ids[sorter], t_dwell), max(nd - 1, 0))
        if nd == 0 or np.any(d_ids[sorter][pos] != t_dwell):
            bad = t_dwell[(nd == 0) | (d_ids[sorter][pos] != t_dwell)][0]
            raise ValueError(f"4607 writer: detection dwell_id {bad} is not in the dwells table")
        row = sorter[pos]
    tie = np.asarray(detections["det_id"]) if "det_id" in detections else np.arange(nt)
    step = np.diff(row)
    if np.all(step >= 0) and np.all((step > 0) | (np.diff(tie) > 0)):
        return row, {k: np.asarray(v) for k, v in detections.items()}
    t_order = np.lexsort((tie, row))
    return row[t_order], {k: np.asarray(v)[t_order] for k, v in detections.items()}


def _increasing(x: np.ndarray, strict: bool = False) -> bool:
    return bool(np.all(x[1:] > x[:-1]) if strict else np.all(x[1:] >= x[:-1]))


def platform_location_packets(platform: Mapping[str, np.ndarray], meta: Mapping, *,
                              edition: str = "30") -> bytes:
    """Platform Location packets (segment 13, one per row) for a /platform table.

    Uses ``time_s lat_deg lon_deg height_m vx_mps vy_mps vz_mps``; track and speed are those of
    the horizontal velocity (vx east, vy north), vertical velocity in dm/s (S8, saturated).
    """
    m = _meta(meta)
    n = n_rows(platform, "platform")
    epoch_sod = _epoch_sod(m["epoch"])

    def col(c):
        return np.asarray(platform[c], float) if c in platform else np.zeros(n)

    body = platform_records((epoch_sod + col("time_s")) * 1000.0, col("lat_deg"),
                            col("lon_deg"), col("height_m"), col("vx_mps"), col("vy_mps"),
                            col("vz_mps"))
    dt = np.dtype(PACKET_HEADER.descr + SEGMENT_HEADER.descr + PLATFORM_BODY.descr)
    a = np.zeros(n, dt)
    hdr = _packet_header(m, edition, dt.itemsize, 0)
    for name in PACKET_HEADER.names:
        a[name] = hdr[name][0]
    a["seg_type"], a["seg_size"] = PLATFORM_LOCATION, 5 + PLATFORM_BODY.itemsize
    for name in PLATFORM_BODY.names:
        a[name] = body[name]
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
        row, det = _attach(dw, det, nd, nt)
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
