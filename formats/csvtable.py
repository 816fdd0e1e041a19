"""CSV forms of the detection, truth and track tables (pandas and Stone Soup read them as is).

One row per table row, one column per table column, a header line, comma separated, UTF-8,
``\\n`` line ends.  The first two columns are the time as ISO-8601 UTC (``time_utc``,
microseconds, ``Z``) and as seconds since the scene epoch (``time_s``, authoritative on reading);
then the table's columns in the order of :data:`COLUMNS`.  Floats are written column-wise by
:mod:`formats._text` in digits that read back exactly (repr's layout), NaN as ``nan``, booleans as
``True``/``False``; a block of rows at a time (:func:`iter_csv`).  Rows are written in time
order (stable), as Stone Soup's readers require.

Stone Soup::

    from stonesoup.reader.generic import CSVDetectionReader
    reader = CSVDetectionReader("detections.csv", state_vector_fields=("x_m", "y_m"),
                                time_field="time_utc")
    for time, detections in reader: ...   # every other column lands in Detection.metadata

pandas: ``pandas.read_csv("detections.csv", parse_dates=["time_utc"])``.

Reading validates the header (required columns present, no unknown or duplicate column) and every
cell (numeric, integer, boolean as the column requires); a problem raises
:class:`~formats.errors.FormatError` naming the line and column.
"""
from __future__ import annotations

import csv
import io
from typing import Mapping

import numpy as np

from . import _text as _cells
from ._io import (n_rows, parse_epoch, read_source, source_name,
                  write_chunks)
from .errors import FormatError, where

__all__ = ["write_csv", "read_csv", "encode_csv", "write_detections_csv", "read_detections_csv",
           "write_truth_csv", "read_truth_csv", "write_tracks_csv", "read_tracks_csv",
           "COLUMNS", "REQUIRED"]

F, I, B, U8 = "float", "int", "bool", "u8"

COLUMNS: dict[str, dict[str, str]] = {
    "detections": {
        "time_s": F, "det_id": I, "dwell_id": I, "sensor_id": I, "lat_deg": F, "lon_deg": F,
        "height_m": F,
        "x_m": F, "y_m": F, "z_m": F, "range_m": F, "azimuth_rad": F, "range_rate_mps": F,
        "los_velocity_mps": F,
        "sigma_range_m": F, "sigma_azimuth_rad": F, "sigma_range_rate_mps": F, "snr_db": F,
        "truth_id": I, "true_range_m": F, "true_azimuth_rad": F, "true_range_rate_mps": F,
        "merged": B, "range_folded": B, "doppler_wrapped": B, "implausible": B, "rcs_dbsm": F,
        "wrap_velocity_mps": F, "sigma_cross_range_m": F, "sigma_height_m": F,
        "classification": U8,
    },
    # Where the sensor was and what it looked at, one row per dwell (dwells without
    # detections too): a CSV-only tracker's negative information.
    "dwells": {
        "time_s": F, "dwell_id": I, "sensor_id": I, "revisit_id": I, "dwell_index": I,
        "last_dwell": B, "cpi_s": F, "platform_x_m": F, "platform_y_m": F, "platform_z_m": F,
        "platform_lat_deg": F, "platform_lon_deg": F, "platform_height_m": F,
        "platform_vx_mps": F, "platform_vy_mps": F, "platform_vz_mps": F,
        "platform_heading_rad": F, "platform_pitch_rad": F, "platform_bank_rad": F,
        "beam_az_rad": F, "beam_scan_rad": F, "area_lat_deg": F, "area_lon_deg": F,
        "range_half_extent_m": F, "angle_half_extent_rad": F, "mdv_mps": F,
        "wrap_velocity_mps": F,
    },
    "truth": {
        "time_s": F, "vehicle_id": I, "convoy_id": I, "x_m": F, "y_m": F, "z_m": F,
        "lat_deg": F, "lon_deg": F, "height_m": F, "vx_mps": F, "vy_mps": F, "vz_mps": F,
        "ax_mps2": F, "ay_mps2": F, "az_mps2": F, "speed_mps": F, "heading_rad": F,
        "route_s_m": F, "edge_id": I, "mode": U8, "invisible": B,
    },
    "tracks": {
        "time_s": F, "track_id": I, "x_m": F, "y_m": F, "vx_mps": F, "vy_mps": F,
        "cov_xx_m2": F, "cov_xy_m2": F, "cov_yy_m2": F, "range_rate_mps": F, "confirmed": B,
    },
}
REQUIRED = {
    "detections": ("time_s", "det_id", "dwell_id"),
    "dwells": ("time_s", "dwell_id"),
    "truth": ("time_s", "vehicle_id", "x_m", "y_m"),
    "tracks": ("time_s", "track_id", "x_m", "y_m"),
}
_ID = {"detections": "det_id", "dwells": "dwell_id", "truth": "vehicle_id", "tracks": "track_id"}
TIME_UTC = "time_utc"


def _kind(kind: str) -> dict:
    if kind not in COLUMNS:
        raise ValueError(f"CSV kind must be one of {sorted(COLUMNS)}, got {kind!r}")
    return COLUMNS[kind]


def _field(col, kind: str, rows) -> _cells.Field:
    """The text of ``col[rows]`` (the whole column is given, so that the formats of one table
    format it once: :func:`formats._text.shared_columns`)."""
    col = np.asarray(col)
    if kind == B:
        return _cells.choice(col[rows].astype(bool), "True", "False")
    if kind in (I, U8):
        if col.dtype.kind == "i" or (col.dtype.kind in "ub" and col.dtype.itemsize < 8):
            return _cells.int_cells(col, rows)
        return _cells.int_cells(col[rows].astype(np.int64))
    return _cells.float_cells(col, rows=rows)     # 'nan', 'inf', '-inf' as repr writes


def _prepare(table: Mapping[str, np.ndarray], kind: str, epoch_utc: str):
    """(column names, row order, epoch) of a table to write, after the checks."""
    cols = _kind(kind)
    n_rows(table, kind)
    unknown = [c for c in table if c not in cols]
    if unknown:
        raise ValueError(f"CSV writer ({kind}): columns {unknown} are not part of the {kind} CSV; "
                         f"known: {list(cols)}")
    missing = [c for c in REQUIRED[kind] if c not in table]
    if missing:
        raise ValueError(f"CSV writer ({kind}): table lacks required columns {missing}")
    epoch = parse_epoch(epoch_utc)
    t = np.asarray(table["time_s"], dtype=np.float64)
    order = np.lexsort((np.asarray(table[_ID[kind]]), t))
    return [c for c in cols if c in table], order, epoch


def iter_csv(table: Mapping[str, np.ndarray], kind: str, *, epoch_utc: str,
             rows: int = 1 << 15):
    """The CSV bytes of a table in pieces: the header, then ``rows`` rows at a time (bounded
    memory; every value formatted column-wise by :mod:`formats._text`)."""
    names, order, epoch = _prepare(table, kind, epoch_utc)
    cols = _kind(kind)
    yield (",".join([TIME_UTC] + names) + "\n").encode()
    t = np.asarray(table["time_s"], dtype=np.float64)
    for a, b in _cells.row_chunks(len(order), rows):
        sel = _cells.contiguous(order[a:b])
        pieces: list = [_cells.utc_cells(epoch, t[sel])]
        for c in names:
            pieces += [",", _field(table[c], cols[c], sel)]
        pieces.append("\n")
        yield _cells.join(pieces, b - a)


def encode_csv(table: Mapping[str, np.ndarray], kind: str, *, epoch_utc: str) -> bytes:
    """CSV bytes of a detections / truth / tracks table (columns outside COLUMNS[kind] are
    refused with ValueError, so nothing is dropped silently)."""
    return b"".join(iter_csv(table, kind, epoch_utc=epoch_utc))


def write_csv(dest, table: Mapping[str, np.ndarray], kind: str, *, epoch_utc: str) -> None:
    """Write a table as CSV to a path (atomically) or a binary file object, a chunk of rows at
    a time."""
    write_chunks(dest, iter_csv(table, kind, epoch_utc=epoch_utc))


def _text(source) -> tuple[str, str | None]:
    name = source_name(source)
    raw = read_source(source)
    if isinstance(raw, str):
        return raw, name
    try:
        return raw.decode("utf-8-sig"), name
    except UnicodeDecodeError as exc:
        line = raw[:exc.start].count(b"\n") + 1
        raise FormatError(f"{where(name)}line {line}: not UTF-8 text (byte {exc.start})") from None


def _too_big(v: str) -> bool:
    try:
        return not -2 ** 63 <= int(v.strip()) < 2 ** 63
    except ValueError:
        return False


def _convert(values: list[str], kind: str, name, col_name, col_no) -> np.ndarray:
    try:
        if kind == F:
            return np.fromiter(map(float, values), np.float64, len(values))
        if kind in (I, U8):
            a = np.fromiter(map(int, values), np.int64, len(values))
            if kind == U8 and np.any((a < 0) | (a > 255)):
                raise ValueError
            return a.astype(np.uint8) if kind == U8 else a
        low = np.char.lower(np.char.strip(np.array(values, dtype=str))) if values else np.zeros(0, str)
        ok = np.isin(low, ["true", "false", "1", "0"])
        if not ok.all():
            raise ValueError
        return np.isin(low, ["true", "1"])
    except (ValueError, OverflowError):       # OverflowError: an integer beyond int64
        pass
    for i, v in enumerate(values):            # locate the first bad cell for the message
        try:
            if kind == F:
                float(v)
            elif kind in (I, U8):
                x = int(v.strip())
                if kind == U8 and not 0 <= x <= 255:
                    raise ValueError
                if not -2 ** 63 <= x < 2 ** 63:
                    raise ValueError
            elif v.strip().lower() not in ("true", "false", "1", "0"):
                raise ValueError
        except ValueError:
            expect = {F: "a number", I: "an integer" + (" within 64 bits" if _too_big(v) else ""),
                      U8: "an integer 0..255",
                      B: "True or False"}[kind]
            raise FormatError(f"{where(name)}line {i + 2}, column {col_no} ({col_name}): "
                              f"{v!r} is not {expect}") from None
    raise FormatError(f"{where(name)}column {col_no} ({col_name}): cannot convert")  # pragma: no cover


def read_csv(source, kind: str) -> dict:
    """Read a detections / truth / tracks CSV back into a table (``time_utc`` is not returned:
    ``time_s`` is authoritative)."""
    cols = _kind(kind)
    text, name = _text(source)
    try:
        rows = list(csv.reader(io.StringIO(text, newline="")))
    except csv.Error as exc:
        raise FormatError(f"{where(name)}not CSV: {exc}") from None
    if not rows:
        raise FormatError(f"{where(name)}line 1: empty file, expected a header line")
    header = [h.strip() for h in rows[0]]
    seen = set()
    for j, h in enumerate(header):
        if h in seen:
            raise FormatError(f"{where(name)}line 1, column {j + 1}: duplicate column {h!r}")
        seen.add(h)
        if h != TIME_UTC and h not in cols:
            raise FormatError(f"{where(name)}line 1, column {j + 1}: unknown column {h!r} for a "
                              f"{kind} CSV; expected some of {[TIME_UTC] + list(cols)}")
    missing = [c for c in REQUIRED[kind] if c not in header]
    if missing:
        raise FormatError(f"{where(name)}line 1: missing required columns {missing}")
    body = rows[1:]
    while body and not body[-1]:
        body.pop()
    width = len(header)
    for i, r in enumerate(body):
        if len(r) != width:
            raise FormatError(f"{where(name)}line {i + 2}: {len(r)} fields, expected {width} "
                              "(as in the header)")
    out = {}
    columns = list(zip(*body)) if body else [()] * width
    for j, h in enumerate(header):
        if h == TIME_UTC:
            continue
        out[h] = _convert(list(columns[j]), cols[h], name, h, j + 1)
    return {c: out[c] for c in cols if c in out}


def write_detections_csv(dest, detections, *, epoch_utc: str) -> None:
    """Detections CSV (one row per detection); see the module docstring."""
    write_csv(dest, detections, "detections", epoch_utc=epoch_utc)


def read_detections_csv(source) -> dict:
    return read_csv(source, "detections")


def write_truth_csv(dest, truth, *, epoch_utc: str) -> None:
    """Truth CSV (one row per sample time and vehicle)."""
    write_csv(dest, truth, "truth", epoch_utc=epoch_utc)


def read_truth_csv(source) -> dict:
    return read_csv(source, "truth")


def write_tracks_csv(dest, tracks, *, epoch_utc: str) -> None:
    """Tracks CSV (one row per track and update time)."""
    write_csv(dest, tracks, "tracks", epoch_utc=epoch_utc)


def read_tracks_csv(source) -> dict:
    return read_csv(source, "tracks")
