"""GMTI XML: the STANAG 4607 structure in engineering units, valid against ``formats/gmti.xsd``.

Document::

    <GmtiDocument xmlns="urn:gmtiflow:gmti:1" formatVersion="1" edition="30"
                  sceneEpochUtc="2026-11-21T13:00:00.250000Z">
      <PacketHeader nationality="XN" classification="5" .../>     P3-P9
      <Mission missionPlan="SIMULATION" ... referenceDate="2026-11-21"/>   M1-M7
      <JobDefinition jobId="1" ... revisitInterval_s="3.5">       J1-J28
        <BoundingArea><Point lat_deg=".." lon_deg=".."/> x4 </BoundingArea>
      </JobDefinition>
      <Columns dwell="dwell_id time_s ..." targetReport="det_id lat_deg ..."/>  the columns written
      <Dwell dwell_id="0" time_s="0.013" timeUtc="..." revisit_id="0" ...>   D2-D31 + /dwells
        <TargetReport det_id="0" lat_deg=".." lon_deg=".." range_m=".." .../>  D32 + /detections
      </Dwell>
    </GmtiDocument>

Attribute names of Dwell and TargetReport are the table column names (docs/tables.md); an absent
attribute is NaN (float) or -1 (ids).  ``Columns`` lists the columns written, so a column with
no known value (absent on every element) and the columns of an empty table read back too.
Doubles are written column-wise by :mod:`formats._text` in digits that read back exactly, so the
XML form is lossless for every float64 column (quantum: none); the document is written a block
of dwells at a time (:func:`iter_xml`).  The meta keys are those of
:data:`formats.stanag4607.DEFAULT_META` (``epoch_utc`` required).

The reader parses with a hardened lxml parser (no entity resolution, no network, no DTD
loading, no huge_tree) and refuses any document with a DOCTYPE, so XXE and entity-expansion
("billion laughs") inputs raise :class:`~formats.errors.FormatError`; the document is then
validated against the XSD before any value is read.
"""
from __future__ import annotations

import io
import os
from functools import lru_cache
from pathlib import Path
from typing import Iterator, Mapping

import numpy as np
from lxml import etree

from . import _text as _cells
from ._io import n_rows, source_name, write_chunks
from .errors import FormatError, where
from .stanag4607 import resolve_meta

__all__ = ["write_xml", "encode_xml", "read_xml", "validate_xml", "XSD_PATH", "NAMESPACE",
           "DWELL_COLUMNS", "DETECTION_COLUMNS"]

NAMESPACE = "urn:gmtiflow:gmti:1"
XSD_PATH = Path(__file__).with_name("gmti.xsd")
FORMAT_VERSION = 1

_INT, _FLOAT, _BOOL, _U8 = "int", "float", "bool", "u8"
DWELL_COLUMNS = {
    "dwell_id": _INT, "sensor_id": _INT, "time_s": _FLOAT, "revisit_id": _INT,
    "dwell_index": _INT,
    "last_dwell": _BOOL, "cpi_s": _FLOAT, "beam_scan_rad": _FLOAT, "beam_az_rad": _FLOAT,
    "platform_x_m": _FLOAT, "platform_y_m": _FLOAT, "platform_z_m": _FLOAT,
    "platform_vx_mps": _FLOAT, "platform_vy_mps": _FLOAT, "platform_vz_mps": _FLOAT,
    "platform_heading_rad": _FLOAT, "platform_pitch_rad": _FLOAT, "platform_bank_rad": _FLOAT,
    "platform_lat_deg": _FLOAT, "platform_lon_deg": _FLOAT, "platform_height_m": _FLOAT,
    "area_lat_deg": _FLOAT, "area_lon_deg": _FLOAT, "range_half_extent_m": _FLOAT,
    "angle_half_extent_rad": _FLOAT, "mdv_mps": _FLOAT, "wrap_velocity_mps": _FLOAT,
}
DETECTION_COLUMNS = {
    "det_id": _INT, "time_s": _FLOAT, "lat_deg": _FLOAT, "lon_deg": _FLOAT, "height_m": _FLOAT,
    "x_m": _FLOAT, "y_m": _FLOAT, "z_m": _FLOAT, "range_m": _FLOAT, "azimuth_rad": _FLOAT,
    "range_rate_mps": _FLOAT, "los_velocity_mps": _FLOAT, "wrap_velocity_mps": _FLOAT, "snr_db": _FLOAT,
    "classification": _U8, "sigma_range_m": _FLOAT, "sigma_azimuth_rad": _FLOAT,
    "sigma_cross_range_m": _FLOAT, "sigma_height_m": _FLOAT, "sigma_range_rate_mps": _FLOAT,
    "truth_id": _INT, "rcs_dbsm": _FLOAT, "true_range_m": _FLOAT, "true_azimuth_rad": _FLOAT,
    "true_range_rate_mps": _FLOAT, "merged": _BOOL, "range_folded": _BOOL,
    "doppler_wrapped": _BOOL, "implausible": _BOOL,
}
_JOB_ATTRS = (  # (XML attribute, meta key)
    ("sigmaTrack_deg", "nominal_track_sigma_deg"), ("sigmaSpeed_mps", "nominal_speed_sigma_mps"),
    ("sigmaSlantRange_m", "nominal_slant_range_sigma_m"),
    ("sigmaCrossRange_deg", "nominal_cross_range_sigma_deg"),
    ("sigmaRangeRate_mps", "nominal_range_rate_sigma_mps"), ("mdv_mps", "mdv_mps"),
    ("pd", "pd"), ("falseAlarmDensity_per_m2", "false_alarm_density_per_m2"),
)


def _esc(s) -> str:
    return (str(s).replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
            .replace('"', "&quot;").replace("\n", "&#10;").replace("\r", "&#13;")
            .replace("\t", "&#9;"))


def _fmt(x: float) -> str:
    if np.isnan(x):
        return "NaN"
    if np.isinf(x):
        return "INF" if x > 0 else "-INF"
    return repr(float(x))


def _attr_field(name: str, col: np.ndarray, kind: str, rows) -> _cells.Field:
    """' name="value"' of ``col[rows]`` (nothing where the value is NaN), a column at a time:
    doubles exact (:mod:`formats._text`), infinities as INF/-INF."""
    col = np.asarray(col)
    sub = col[rows]
    n = len(sub)
    if kind == _BOOL:
        return _cells.choice(sub.astype(bool), f' {name}="true"', f' {name}="false"')
    pre, end = _cells.literal(f' {name}="', n), _cells.literal('"', n)
    if kind in (_INT, _U8):
        if col.dtype.kind == "f":
            ok = np.isfinite(sub)
            value = _cells.int_cells(np.where(ok, sub, 0).astype(np.int64))
            return _cells.masked([pre] + value + [end], ok)
        if col.dtype.kind == "i" or (col.dtype.kind in "ub" and col.dtype.itemsize < 8):
            return [pre] + _cells.int_cells(col, rows) + [end]
        return [pre] + _cells.int_cells(sub.astype(np.int64)) + [end]
    ok = ~np.isnan(sub.astype(np.float64))
    return _cells.masked([pre] + _cells.float_cells(col, inf="INF", rows=rows) + [end], ok)


# Value ranges the XSD restricts (checked before writing so every written file validates).
_RANGES = {"lat_deg": (-90.0, 90.0), "lon_deg": (-180.0, 360.0), "platform_lat_deg": (-90.0, 90.0),
           "platform_lon_deg": (-180.0, 360.0), "area_lat_deg": (-90.0, 90.0),
           "area_lon_deg": (-180.0, 360.0)}
_NON_NEGATIVE = ("range_half_extent_m", "angle_half_extent_rad", "mdv_mps", "wrap_velocity_mps",
                 "sigma_range_m", "sigma_azimuth_rad", "sigma_cross_range_m", "sigma_height_m",
                 "sigma_range_rate_mps")


def _check_ranges(table, what):
    for col in table:
        lo, hi = _RANGES.get(col, (0.0, np.inf) if col in _NON_NEGATIVE else (None, None))
        if lo is None:
            continue
        x = np.asarray(table[col], dtype=np.float64)
        bad = ~np.isnan(x) & ((x < lo) | (x > hi) | ((hi == 360.0) & (x == 360.0)))
        if bad.any():
            raise ValueError(f"XML writer: {what} column {col!r} has value {x[bad][0]!r} outside "
                             f"[{lo}, {hi}] (row {int(np.flatnonzero(bad)[0])})")


def _attrs(table: Mapping[str, np.ndarray], columns: dict, rows, skip=()) -> list:
    return [f for name, kind in columns.items() if name in table and name not in skip
            for f in _attr_field(name, table[name], kind, rows)]


def iter_xml(dwells: Mapping[str, np.ndarray], detections: Mapping[str, np.ndarray],
             meta: Mapping, *, edition: str = "30", rows: int = 1 << 14) -> Iterator[bytes]:
    """The XML document (UTF-8) for these tables in pieces: the header, then the dwells and
    their reports about ``rows`` reports at a time (bounded memory); columns outside
    :data:`DWELL_COLUMNS`/:data:`DETECTION_COLUMNS` are not carried."""
    m = resolve_meta(meta, dwells, detections)
    nd = n_rows(dwells, "dwells")
    nt = n_rows(detections, "detections")
    if nd and ("dwell_id" not in dwells or "time_s" not in dwells):
        raise ValueError("XML writer: dwells table needs dwell_id and time_s")
    if nt and ("dwell_id" not in detections or "det_id" not in detections):
        raise ValueError("XML writer: detections table needs dwell_id and det_id")
    _check_ranges({k: v for k, v in dwells.items() if k in DWELL_COLUMNS}, "dwells")
    _check_ranges({k: v for k, v in detections.items() if k in DETECTION_COLUMNS}, "detections")
    if nd and not np.all(np.isfinite(np.asarray(dwells["time_s"], float))):
        raise ValueError("XML writer: dwells time_s must be finite")
    epoch = m["epoch"]
    d_ids = np.asarray(dwells.get("dwell_id", np.zeros(0, np.int64)), dtype=np.int64)
    if len(np.unique(d_ids)) != nd:
        raise ValueError("XML writer: dwell_id values are not unique")
    order = np.argsort(np.asarray(dwells.get("time_s", np.zeros(0)), float), kind="stable")
    sorter = np.argsort(d_ids, kind="stable")
    if nt:
        t_dwell = np.asarray(detections["dwell_id"], dtype=np.int64)
        pos = np.minimum(np.searchsorted(d_ids[sorter], t_dwell), max(nd - 1, 0))
        if nd == 0 or np.any(d_ids[sorter][pos] != t_dwell):
            raise ValueError("XML writer: a detection's dwell_id is not in the dwells table")
        row = sorter[pos]
    else:
        row = np.zeros(0, np.int64)
    # place of each dwell in time order; detections grouped by it
    rank = np.empty(nd, np.int64)
    rank[order] = np.arange(nd)
    t_order = np.lexsort((np.asarray(detections.get("det_id", np.arange(nt))), rank[row])) if nt else row
    counts = np.bincount(rank[row], minlength=nd) if nd else np.zeros(0, np.int64)

    out = io.StringIO()
    w = out.write
    w('<?xml version="1.0" encoding="UTF-8"?>\n')
    w(f'<GmtiDocument xmlns="{NAMESPACE}" formatVersion="{FORMAT_VERSION}" edition="{_esc(edition)}"'
      f' sceneEpochUtc="{epoch.strftime("%Y-%m-%dT%H:%M:%S.%fZ")}">\n')
    w(f'  <PacketHeader nationality="{_esc(m["nationality"])}" classification="{int(m["classification"])}"'
      f' classificationSystem="{_esc(m["classification_system"])}" securityCodes="{int(m["security_codes"])}"'
      f' exerciseIndicator="{int(m["exercise_indicator"])}" platformId="{_esc(m["platform_id"])}"'
      f' missionId="{int(m["mission_id"])}"/>\n')
    w(f'  <Mission missionPlan="{_esc(m["mission_plan"])}" flightPlan="{_esc(m["flight_plan"])}"'
      f' platformType="{int(m["platform_type"])}" platformConfiguration="{_esc(m["platform_configuration"])}"'
      f' referenceDate="{epoch.date().isoformat()}"/>\n')
    along, cross, alt = m["sensor_position_sigma_m"]
    job = (f'  <JobDefinition jobId="{int(m["job_id"])}" sensorType="{int(m["sensor_type"])}"'
           f' sensorModel="{_esc(m["sensor_model"])}" targetFiltering="{int(m["target_filtering"])}"'
           f' priority="{int(m["priority"])}" radarMode="{int(m["radar_mode"])}"'
           f' revisitInterval_s="{_fmt(m["revisit_interval_s"])}"'
           f' sigmaAlongTrack_m="{_fmt(along)}" sigmaCrossTrack_m="{_fmt(cross)}"'
           f' sigmaAltitude_m="{_fmt(alt)}"')
    for attr, key in _JOB_ATTRS:
        if m[key] is not None and np.isfinite(m[key]):
            job += f' {attr}="{_fmt(m[key])}"'
    job += (f' terrainModel="{int(m["terrain_model"])}" geoidModel="{int(m["geoid_model"])}"'
            f' targetClassification="{int(m["target_classification"])}"'
            f' truthTagApplication="{int(m["truth_tag_application"])}">\n    <BoundingArea>')
    w(job)
    for lat, lon in m["bounding_area"]:
        w(f'<Point lat_deg="{_fmt(lat)}" lon_deg="{_fmt(lon)}"/>')
    w('</BoundingArea>\n  </JobDefinition>\n')
    # every column written, also those absent on every element (all NaN) and those of an
    # empty table, so that a reader gets back the tables it was given
    w(f'  <Columns dwell="{" ".join(c for c in DWELL_COLUMNS if c in dwells)}"'
      f' targetReport="{" ".join(c for c in DETECTION_COLUMNS if c in detections)}"/>\n')
    yield out.getvalue().encode("utf-8")

    starts = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    # groups of whole dwells of about ``rows`` reports (and at most ``rows`` dwells) each
    cut = np.unique(np.r_[0, np.searchsorted(starts[1:], np.arange(rows, nt + rows, rows)) + 1,
                          np.arange(0, nd, rows), nd])
    cut = cut[(cut >= 0) & (cut <= nd)]
    dcols = {k: np.asarray(v) for k, v in dwells.items() if k in DWELL_COLUMNS}
    tcols = {k: np.asarray(v) for k, v in detections.items() if k in DETECTION_COLUMNS}
    for g0, g1 in zip(cut[:-1].tolist(), cut[1:].tolist()):
        if g0 == g1:
            continue
        k = g1 - g0
        dsel = _cells.contiguous(order[g0:g1])
        a, b = int(starts[g0]), int(starts[g1])
        empty = counts[g0:g1] == 0
        opening, o_off = _cells.join_rows(
            ["  <Dwell"] + _attrs(dcols, DWELL_COLUMNS, dsel)
            + [' timeUtc="', _cells.utc_cells(epoch, dcols["time_s"][dsel]),
               '"', _cells.choice(empty, "/>\n", ">\n")], k)
        tsel = _cells.contiguous(t_order[a:b])
        reports, r_off = _cells.join_rows(
            ["    <TargetReport"] + _attrs(tcols, DETECTION_COLUMNS, tsel, skip=("dwell_id",))
            + ["/>\n"],
            b - a)
        parts = []
        for i in range(k):
            parts.append(opening[o_off[i]:o_off[i + 1]])
            if not empty[i]:
                ra, rb = int(starts[g0 + i]) - a, int(starts[g0 + i + 1]) - a
                parts.append(reports[r_off[ra]:r_off[rb]])
                parts.append(b"  </Dwell>\n")
        yield b"".join(parts)
    yield b"</GmtiDocument>\n"


def encode_xml(dwells: Mapping[str, np.ndarray], detections: Mapping[str, np.ndarray],
               meta: Mapping, *, edition: str = "30") -> bytes:
    """The XML document (UTF-8 bytes) of :func:`iter_xml`."""
    return b"".join(iter_xml(dwells, detections, meta, edition=edition))


def write_xml(dest, dwells, detections, meta, *, edition: str = "30") -> None:
    """Write the XML document to a path (atomically) or a binary file object, a block of dwells
    at a time."""
    write_chunks(dest, iter_xml(dwells, detections, meta, edition=edition))


@lru_cache(maxsize=1)
def _schema() -> etree.XMLSchema:
    return etree.XMLSchema(etree.parse(str(XSD_PATH)))


def _parser() -> etree.XMLParser:
    return etree.XMLParser(resolve_entities=False, no_network=True, load_dtd=False,
                           dtd_validation=False, huge_tree=False, remove_comments=True)


def _parse(source):
    name = source_name(source)
    try:
        if isinstance(source, (bytes, bytearray)):
            tree = etree.parse(io.BytesIO(bytes(source)), _parser())
        elif isinstance(source, (str, os.PathLike)):
            tree = etree.parse(str(source), _parser())
        else:
            tree = etree.parse(source, _parser())
    except etree.XMLSyntaxError as exc:
        line, col = exc.position if exc.position else (0, 0)
        raise FormatError(f"{where(name)}line {line}, column {col}: not well-formed XML: "
                          f"{exc.msg}") from None
    except OSError as exc:
        raise FormatError(f"{where(name)}cannot read: {exc}") from None
    if tree.docinfo.internalDTD is not None or tree.docinfo.doctype:
        raise FormatError(f"{where(name)}line 1: a DOCTYPE (DTD / entity declarations) is not "
                          "allowed in a GMTI XML document")
    return tree, name


def validate_xml(source) -> None:
    """Raise FormatError (line, column, reason) unless the document is valid against the XSD."""
    tree, name = _parse(source)
    _validate(tree, name)


def _validate(tree, name):
    schema = _schema()
    if not schema.validate(tree):
        e = schema.error_log.last_error
        raise FormatError(f"{where(name)}line {e.line}, column {e.column}: not valid against "
                          f"gmti.xsd: {e.message}")


def _float(v):
    return np.nan if v is None else float(v)


def _columns(elements, columns: dict, name, declared=None) -> dict:
    """The ``columns`` the elements carry: those some element has an attribute of, and every
    column of ``declared`` (the document's ``Columns`` list: all NaN or an empty table)."""
    elements = list(elements)
    attrs = [dict(el.items()) for el in elements]
    n = len(attrs)
    declared = set(declared or ())
    out = {}
    for col, kind in columns.items():
        vals = [a.get(col) for a in attrs]
        if vals.count(None) == n and col not in declared:
            continue
        try:
            out[col] = _column(vals, kind, n)
        except (ValueError, OverflowError):
            # libxml2's xs:double admits forms Python's float() does not (e.g. "4e")
            for el, v in zip(elements, vals):
                try:
                    _column([v], kind, 1)
                except (ValueError, OverflowError):
                    raise FormatError(f"{where(name)}line {el.sourceline}: attribute {col}="
                                      f"{v!r} is not a readable number") from None
            raise FormatError(f"{where(name)}attribute {col}: cannot convert")  # pragma: no cover
    return out


def _column(vals: list, kind, n: int) -> np.ndarray:
    if kind == _BOOL:
        return np.array([v in ("true", "1") for v in vals], dtype=bool)
    if kind in (_INT, _U8):
        fill = -1 if kind == _INT else 0
        arr = np.fromiter((fill if v is None else int(v) for v in vals), np.int64, n)
        return arr.astype(np.uint8) if kind == _U8 else arr
    # xs:double lexical forms that Python's float() reads: INF, -INF, NaN, 1E5, .5
    conv = float if None not in vals else _float
    return np.fromiter(map(conv, vals), np.float64, n)


def read_xml(source) -> dict:
    """Read a GMTI XML document: ``{"dwells", "detections", "meta", "attrs"}``.

    ``meta`` holds the keys of :data:`formats.stanag4607.DEFAULT_META` (plus ``epoch_utc``), so
    ``write_xml(dest, r["dwells"], r["detections"], r["meta"])`` writes the same document.
    """
    tree, name = _parse(source)
    _validate(tree, name)
    root = tree.getroot()
    ns = {"g": NAMESPACE}
    ph = root.find("g:PacketHeader", ns).attrib
    mi = root.find("g:Mission", ns).attrib
    jd = root.find("g:JobDefinition", ns)
    ja = jd.attrib
    meta = {
        "epoch_utc": root.get("sceneEpochUtc"),
        "nationality": ph["nationality"], "classification": int(ph["classification"]),
        "classification_system": ph["classificationSystem"],
        "security_codes": int(ph["securityCodes"]),
        "exercise_indicator": int(ph["exerciseIndicator"]), "platform_id": ph["platformId"],
        "mission_id": int(ph["missionId"]),
        "mission_plan": mi["missionPlan"], "flight_plan": mi["flightPlan"],
        "platform_type": int(mi["platformType"]),
        "platform_configuration": mi["platformConfiguration"],
        "job_id": int(ja["jobId"]), "sensor_type": int(ja["sensorType"]),
        "sensor_model": ja["sensorModel"], "target_filtering": int(ja["targetFiltering"]),
        "priority": int(ja["priority"]), "radar_mode": int(ja["radarMode"]),
        "revisit_interval_s": float(ja["revisitInterval_s"]),
        "sensor_position_sigma_m": (float(ja.get("sigmaAlongTrack_m", "nan")),
                                    float(ja.get("sigmaCrossTrack_m", "nan")),
                                    float(ja.get("sigmaAltitude_m", "nan"))),
        "terrain_model": int(ja["terrainModel"]), "geoid_model": int(ja["geoidModel"]),
        "target_classification": int(ja["targetClassification"]),
        "truth_tag_application": int(ja["truthTagApplication"]),
        "bounding_area": [(float(p.get("lat_deg")), float(p.get("lon_deg")))
                          for p in jd.findall("g:BoundingArea/g:Point", ns)],
    }
    for attr, key in _JOB_ATTRS:
        meta[key] = float(ja[attr]) if attr in ja else None
    listed = root.find("g:Columns", ns)     # absent in documents written before it
    dwell_els = root.findall("g:Dwell", ns)
    dwells = _columns(dwell_els, DWELL_COLUMNS, name,
                      None if listed is None else listed.get("dwell").split())
    counts = [len(el) for el in dwell_els]
    target_els = [t for el in dwell_els for t in el]
    dets = _columns(target_els, DETECTION_COLUMNS, name,
                    None if listed is None else listed.get("targetReport").split())
    dwell_ids = dwells.get("dwell_id", np.zeros(0, np.int64))
    dets["dwell_id"] = np.repeat(dwell_ids, counts).astype(np.int64)
    if "time_s" not in dets and len(target_els):
        dets["time_s"] = np.repeat(dwells["time_s"], counts)
    if not target_els and listed is None:
        dets = {"det_id": np.zeros(0, np.int64), "dwell_id": np.zeros(0, np.int64)}
    dets.setdefault("det_id", np.zeros(0, np.int64))    # required on every TargetReport
    return {"dwells": dwells, "detections": dets, "meta": meta,
            "attrs": {"edition": root.get("edition"), "scene_epoch_utc": root.get("sceneEpochUtc"),
                      "format_version": int(root.get("formatVersion"))}}
