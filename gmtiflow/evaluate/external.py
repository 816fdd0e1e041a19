"""External trackers' track files as they come: ISO time or seconds, ENU or lat/lon.

:func:`read_track_csv` reads a track CSV with a header line and any of the columns of
:data:`gmtiflow.evaluate.tracks.ALLOWED` plus ``time_utc``: the time as ``time_s`` (seconds
from the run's ``scene_epoch_utc``) or as ``time_utc`` (ISO 8601: ``2026-06-01T08:00:05.5Z``,
an offset such as ``+02:00``, or no zone = UTC, as Stone Soup's naive datetimes); ``time_s``
wins when both are given.  Values stay text here; :func:`~gmtiflow.evaluate.tracks.validate_tracks`
converts and checks them (and turns ``lat_deg lon_deg`` into scene ENU).

:func:`check_times` refuses a table whose times do not overlap the scene, naming the likely
unit (Unix seconds, Unix milliseconds, milliseconds from the epoch) instead of scoring every
step as missed.
"""
from __future__ import annotations

import csv
import io
from datetime import datetime, timezone
from pathlib import Path
from typing import Mapping, Optional

import numpy as np

from gmtiflow.errors import InputFileError
from gmtiflow.evaluate.tracks import ALLOWED

TIME_UTC = "time_utc"


def parse_epoch(epoch_utc: str) -> datetime:
    """An ISO-8601 instant as an aware UTC datetime (no zone: UTC)."""
    t = datetime.fromisoformat(str(epoch_utc).strip().replace("Z", "+00:00"))
    return t.replace(tzinfo=timezone.utc) if t.tzinfo is None else t.astimezone(timezone.utc)


def utc_to_seconds(values, epoch_utc: str, source: str) -> np.ndarray:
    """Seconds from ``epoch_utc`` of ISO-8601 strings (one error naming the first bad row)."""
    epoch = parse_epoch(epoch_utc)
    out = np.empty(len(values))
    for i, v in enumerate(values):
        try:
            out[i] = (parse_epoch(v) - epoch).total_seconds()
        except (TypeError, ValueError):
            raise InputFileError(f"{source}: column 'time_utc' row {i}: {str(v)!r} is not an "
                                 f"ISO-8601 time such as 2026-06-01T08:00:05.5Z") from None
    return out


def read_track_csv(path, epoch_utc: Optional[str]) -> dict:
    """A track CSV as text columns, ``time_utc`` turned into ``time_s`` (see the module doc)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except OSError as exc:
        raise InputFileError(f"{path}: cannot read ({exc.strerror or exc})") from None
    except UnicodeDecodeError:
        raise InputFileError(f"{path}: not a UTF-8 text file") from None
    try:
        rows = list(csv.reader(io.StringIO(text, newline="")))
    except csv.Error as exc:
        raise InputFileError(f"{path}: not CSV ({exc})") from None
    while rows and not any(cell.strip() for cell in rows[-1]):
        rows.pop()
    if not rows:
        raise InputFileError(f"{path}: empty file, expected a header line")
    header = [h.strip() for h in rows[0]]
    known = set(ALLOWED) | {TIME_UTC}
    for j, h in enumerate(header):
        if h not in known:
            raise InputFileError(f"{path}: line 1, column {j + 1}: unknown column {h!r}; a track "
                                 f"CSV has {', '.join(sorted(known))}")
        if header.count(h) > 1:
            raise InputFileError(f"{path}: line 1: duplicate column {h!r}")
    body = rows[1:]
    for i, r in enumerate(body):
        if len(r) != len(header):
            raise InputFileError(f"{path}: line {i + 2}: {len(r)} fields, expected "
                                 f"{len(header)} (as in the header)")
    cols = {h: np.asarray([r[j].strip() for r in body], dtype=str) for j, h in enumerate(header)}
    if TIME_UTC in cols:
        utc = cols.pop(TIME_UTC)
        if "time_s" not in cols:
            if epoch_utc is None:
                raise InputFileError(f"{path}: times are time_utc but the run has no "
                                     f"scene_epoch_utc to count seconds from")
            cols["time_s"] = utc_to_seconds(utc, epoch_utc, str(path))
    if "time_s" not in cols:
        raise InputFileError(f"{path}: missing the time: a time_s (seconds from the run's "
                             f"scene_epoch_utc) or a time_utc (ISO 8601) column")
    return cols


def check_times(tracks: Mapping[str, np.ndarray], t0_s: float, t1_s: float,
                epoch_utc: Optional[str], source: str) -> None:
    """InputFileError naming the likely unit when the track times miss the scene [t0, t1]."""
    t = np.asarray(tracks["time_s"], float)
    if not len(t):
        return
    span = max(t1_s - t0_s, 1.0)
    slack = 0.05 * span + 10.0
    inside = (t >= t0_s - slack) & (t <= t1_s + slack)
    if inside.mean() >= 0.5:
        return
    lo, hi = float(t.min()), float(t.max())
    hint = ""
    if epoch_utc is not None:
        epoch_unix = parse_epoch(epoch_utc).timestamp()
        for scale, unit in ((1.0, "Unix seconds"), (1e-3, "Unix milliseconds"),
                            (1e-6, "Unix microseconds")):
            rel = t * scale - epoch_unix
            if np.mean((rel >= t0_s - slack) & (rel <= t1_s + slack)) >= 0.5:
                hint = (f"; they look like {unit} (subtract the epoch {epoch_utc} = "
                        f"{epoch_unix:.0f} s{' after converting to seconds' if scale != 1 else ''}"
                        f", or give a time_utc column)")
                break
    if not hint:
        for scale, unit in ((1e-3, "milliseconds"), (1e-6, "microseconds"), (60.0, "minutes")):
            rel = t * scale
            if np.mean((rel >= t0_s - slack) & (rel <= t1_s + slack)) >= 0.9:
                hint = f"; they look like {unit} from the epoch (time_s is in seconds)"
                break
    raise InputFileError(
        f"{source}: column 'time_s' runs from {lo:.6g} to {hi:.6g} but the scene spans "
        f"{t0_s:g}..{t1_s:g} s from its epoch{'' if epoch_utc is None else ' ' + epoch_utc}"
        f"{hint or '; time_s is seconds from the scene epoch'}")
