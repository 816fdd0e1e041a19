"""STANAG 4607 writer: the meta dict (packet header, Mission, Job Definition defaults) and
the encoding of a run's dwell and detection tables into a packet stream
(:mod:`formats.stanag4607` documents the stream; this module holds its code)."""
from __future__ import annotations

from datetime import datetime, timedelta, timezone
from typing import Mapping

import numpy as np

from .._io import n_rows, parse_epoch, write_atomic
from .dwell import encode_dwell_packets, generated_masks
from .layout import (FREE_TEXT, JOB_DEFINITION, MAX_PACKET_BYTES, MISSION,
                     PLATFORM_LOCATION, enc_text, sat)
from .packet import PACKET_HEADER, SEGMENT_HEADER
from .segments import PLATFORM_BODY, free_text_body, job_body, mission_body, platform_records


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
    "nominal_sigmas_from_reports": False,  # J21-J23 left None: medians of the (sensor's) reports
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
    area centres, platform positions and detections (ValueError when there is none: the
    caller states the area of a run without dwells); ``revisit_interval_s`` None -> median time
    between revisit starts (0 for a single revisit); ``mdv_mps`` None -> median of the dwells'
    ``mdv_mps`` (No Statement if they have none); with ``nominal_sigmas_from_reports``, J21-J23
    left None -> medians of the reports' ``sigma_range_m``, ``sigma_azimuth_rad`` (in degrees)
    and ``sigma_range_rate_mps`` (each sensor's own in a multi-sensor 4607 file).  Adds
    ``epoch`` (aware datetime).
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
        if not ok.any():
            # 0 deg N 0 deg E would be a real place (the Gulf of Guinea) to every consumer
            raise ValueError("4607 meta: bounding_area is None and the tables have no dwell, "
                             "platform or detection position to put the box around (a run "
                             "without dwells?): pass meta['bounding_area'], the job's area as "
                             "4 (lat, lon) corners")
        s, n = float(lats[ok].min()), float(lats[ok].max())
        w, e = float(lons[ok].min()), float(lons[ok].max())
        m["bounding_area"] = [(n, w), (n, e), (s, e), (s, w)]
    if m["revisit_interval_s"] is None:
        m["revisit_interval_s"] = _median_revisit_s(dwells)
    if m["nominal_sigmas_from_reports"]:
        for key, col, in_deg in (("nominal_slant_range_sigma_m", "sigma_range_m", False),
                                 ("nominal_cross_range_sigma_deg", "sigma_azimuth_rad", True),
                                 ("nominal_range_rate_sigma_mps", "sigma_range_rate_mps", False)):
            x = np.asarray(detections.get(col, []), float)
            x = x[np.isfinite(x)]
            if m[key] is None and len(x):
                med = float(np.median(x))
                m[key] = float(np.degrees(med)) if in_deg else med
    if m["mdv_mps"] is None and "mdv_mps" in dwells and len(dwells["mdv_mps"]):
        mdv = np.asarray(dwells["mdv_mps"], float)
        m["mdv_mps"] = float(np.median(mdv[np.isfinite(mdv)])) if np.isfinite(mdv).any() else None
    return m


def _median_revisit_s(dwells) -> float:
    """Median time between revisit starts, each sensor's dwells on their own (``sensor_id``;
    the intervals of all sensors pooled): in a stream of interleaved sensors every dwell of
    the other sensor would otherwise look like a new revisit."""
    if "revisit_id" not in dwells or len(dwells["revisit_id"]) == 0:
        return 0.0
    rev = np.asarray(dwells["revisit_id"])
    t = np.asarray(dwells["time_s"], dtype=np.float64)
    sensor = np.asarray(dwells.get("sensor_id", np.zeros(len(rev), np.int64)))
    gaps = []
    for s in np.unique(sensor):
        sel = np.flatnonzero(sensor == s)
        r, ts = rev[sel], t[sel]
        starts = np.flatnonzero(np.r_[True, r[1:] != r[:-1]])
        gaps.append(np.diff(ts[starts]))
    gaps = np.concatenate(gaps)
    return float(np.median(gaps)) if len(gaps) else 0.0


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
    row, det = attach_detections(dw, detections, nd, nt)
    sensor = _sensor_ids(dw, nd)
    n_sensors = int(sensor.max()) + 1 if nd else 1
    if platform is not None and "sensor_id" in platform and n_rows(platform, "platform"):
        # a sensor may have platform rows and no dwell (a run shorter than its first scan)
        n_sensors = max(n_sensors, int(np.max(np.asarray(platform["sensor_id"]))) + 1)
    metas = []
    for s in range(n_sensors):
        if n_sensors == 1:
            metas.append(m)
            continue
        sel = sensor == s
        # a sensor without dwells sends no packet; its area is the file's, not made up
        ms = resolve_meta(meta if sel.any() else dict(meta, bounding_area=m["bounding_area"]),
                          {k: v[sel] for k, v in dw.items()},
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
    if n_sensors == 1:
        out += heads[0]
    elif not nd:                            # no dwell to send them before: every platform's now
        out += [p for pair in heads for p in pair]
    if m["write_epoch_text"] and (n_sensors == 1 or not nd):
        out.append(_epoch_text_packet(metas[0], edition))

    plat_times = np.zeros(0)
    plat_bytes = None
    if platform is not None and n_rows(platform, "platform"):
        plat_bytes = memoryview(platform_location_packets(platform, meta, edition=edition,
                                                          n_sensors=n_sensors))
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


def attach_detections(dw: dict, detections: Mapping, nd: int, nt: int):
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
                              edition: str = "30", n_sensors: int | None = None) -> bytes:
    """Platform Location packets (segment 13, one per row) for a /platform table.

    Uses ``time_s lat_deg lon_deg height_m vx_mps vy_mps vz_mps``; track and speed are those of
    the horizontal velocity (vx east, vy north), vertical velocity in dm/s (S8, saturated).
    With a ``sensor_id`` column and several sensors (``n_sensors``, default: from that column)
    each row is sent as its sensor's platform (P8, P9 of :func:`sensor_meta`), as its Dwell
    packets are.
    """
    m = _meta(meta)
    n = n_rows(platform, "platform")
    sensor = (np.asarray(platform["sensor_id"], np.int64) if "sensor_id" in platform and n
              else np.zeros(n, np.int64))
    if n_sensors is None:
        n_sensors = int(sensor.max()) + 1 if n else 1
    epoch_sod = _epoch_sod(m["epoch"])

    def col(c):
        return np.asarray(platform[c], float) if c in platform else np.zeros(n)

    body = platform_records((epoch_sod + col("time_s")) * 1000.0, col("lat_deg"),
                            col("lon_deg"), col("height_m"), col("vx_mps"), col("vy_mps"),
                            col("vz_mps"))
    dt = np.dtype(PACKET_HEADER.descr + SEGMENT_HEADER.descr + PLATFORM_BODY.descr)
    a = np.zeros(n, dt)
    for s in (np.unique(sensor).tolist() if n_sensors > 1 else [0]):
        hdr = _packet_header(sensor_meta(m, s, n_sensors), edition, dt.itemsize, 0)
        rows = sensor == s if n_sensors > 1 else slice(None)
        for name in PACKET_HEADER.names:
            a[name][rows] = hdr[name][0]
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


