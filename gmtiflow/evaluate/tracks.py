"""Validation of track tables, above all those of external trackers read by ``formats``.

A track table (docs/tables.md, /tracks) is a dict of equal-length numpy columns:

* required: ``track_id`` (integer-valued), ``time_s``, and a position, either ``x_m y_m`` (scene
  ENU) or ``lat_deg lon_deg`` (WGS-84; optional ``height_m``; converted with
  :func:`gmtiflow.frames.geodetic_to_enu`, which needs the scene origin);
* optional, all-or-nothing groups: ``vx_mps vy_mps``; ``cov_xx_m2 cov_xy_m2 cov_yy_m2``;
  and single columns ``range_rate_mps``, ``confirmed`` (bool or 0/1), ``z_m``.

:func:`validate_tracks` raises one :class:`~gmtiflow.errors.InputFileError` naming the column and
the (0-based) data row for: an unknown or missing column, columns of different lengths, a value
that is not a finite number (NaN, inf, text), a position farther than 1e8 m from the scene
origin, a non-integer or negative track id (ids are 0 .. 2^63 - 1), the same track id twice at
one time, and times that do not increase within a track (in the order given).  It returns the
table normalised: ``x_m y_m`` (lat/lon replaced), canonical dtypes, rows sorted by
(track_id, time_s).
"""
from __future__ import annotations

from typing import Mapping, Optional

import numpy as np

from gmtiflow import frames
from gmtiflow.errors import InputFileError
from gmtiflow.paths import excerpt
from gmtiflow.tables import Table

#: The columns of the tracks the baseline writes into /tracks (the Stone Soup trackers a subset).
TRACK_COLUMNS = ("track_id", "time_s", "x_m", "y_m", "vx_mps", "vy_mps", "cov_xx_m2",
                 "cov_xy_m2", "cov_yy_m2", "range_rate_mps", "confirmed")
#: The columns every /tracks table of a run has (a tracker of the protocol may report only
#: these; the store requires them when reading a run file).
REQUIRED_TRACK_COLUMNS = ("track_id", "time_s", "x_m", "y_m")

GROUPS = (("vx_mps", "vy_mps"), ("cov_xx_m2", "cov_xy_m2", "cov_yy_m2"))
SINGLE_OPTIONAL = ("range_rate_mps", "confirmed", "z_m")
ALLOWED = (("track_id", "time_s", "x_m", "y_m", "lat_deg", "lon_deg", "height_m")
           + tuple(c for g in GROUPS for c in g) + SINGLE_OPTIONAL)


def _show(value) -> str:
    """A value as a user reads it (plain Python repr, not numpy's)."""
    return repr(value.item() if isinstance(value, np.generic) else value)


def _fail(source: str, message: str) -> InputFileError:
    return InputFileError(f"{source}: {message}")


def _numeric(table, name: str, source: str) -> np.ndarray:
    raw = np.asarray(table[name])
    try:
        col = raw.astype(np.float64, copy=False)     # a float64 column is not copied
    except (TypeError, ValueError):
        for i, v in enumerate(raw):
            try:
                float(v)
            except (TypeError, ValueError):
                raise _fail(source, f"column {_show(name)} row {i}: {_show(v)} is not a "
                                    f"number") from None
        raise _fail(source, f"column {_show(name)} is not numeric") from None
    bad = np.flatnonzero(~np.isfinite(col))
    if len(bad):
        i = int(bad[0])
        raise _fail(source, f"column {_show(name)} row {i}: {_show(raw[i])} is not a finite number"
                            f" ({len(bad)} such row(s))")
    return col


#: Scene ENU positions farther than this are refused: no point on Earth is more than ~12,700 km
#: from the origin, and a track at 1e300 m went through the pair search's integer cell keys
#: (numpy cast and overflow warnings; it was scored as a false track).
MAX_POSITION_M = 1e8

_FLOAT_EXACT_INT = 2 ** 53
"""Beyond this, float64 cannot tell neighbouring integers apart (2^60 and 2^60 + 1 are one)."""


def _track_ids(table, source: str) -> np.ndarray:
    """The ``track_id`` column as int64, exactly: integers (and integer text, as a CSV reader
    gives it) as they are, a float column only where it holds integers below 2^53.  Ids used to
    go through float64, which merged the tracks 2^60 and 2^60 + 1 into one without a word.
    Negative ids are refused: the metrics tables write -1 for "no track", and the scorer read
    every negative id as none (a tracker numbering its tracks -1, -2, ... scored coverage 0)."""
    ids = _track_ids_int64(table, source)
    neg = np.flatnonzero(ids < 0)
    if len(neg):
        i = int(neg[0])
        raise _fail(source, f"column 'track_id' row {i}: {int(ids[i])} is negative; track ids are "
                            f"0 .. 2^63 - 1 (-1 stands for 'no track' in the metrics tables)")
    return ids


def _track_ids_int64(table, source: str) -> np.ndarray:
    """:func:`_track_ids` before the sign check."""
    raw = np.asarray(table["track_id"])
    if raw.dtype.kind == "u" and len(raw) and raw.max() > np.iinfo(np.int64).max:
        i = int(np.argmax(raw > np.iinfo(np.int64).max))
        raise _fail(source, f"column 'track_id' row {i}: {_show(raw[i])} does not fit a signed "
                            f"64-bit integer")
    if raw.dtype.kind in "iubUSO":
        try:        # objects as their text: int(1.5) would truncate, int("1.5") refuses
            return (raw.astype(str) if raw.dtype.kind == "O" else raw).astype(np.int64)
        except OverflowError:
            for i, v in enumerate(raw):
                try:
                    np.int64(int(str(v, "ascii") if isinstance(v, bytes) else v))
                except (OverflowError, ValueError):
                    raise _fail(source, f"column 'track_id' row {i}: {excerpt(str(v))} does "
                                        f"not fit a signed 64-bit integer") from None
            raise _fail(source, "column 'track_id' does not fit signed 64-bit integers"
                        ) from None
        except (TypeError, ValueError):
            pass                            # not all integer text: the float checks below
    ids = _numeric(table, "track_id", source)
    frac = np.flatnonzero(ids != np.round(ids))
    if len(frac):
        i = int(frac[0])
        raise _fail(source, f"column 'track_id' row {i}: {_show(ids[i])} is not an integer")
    far = np.flatnonzero(np.abs(ids) > _FLOAT_EXACT_INT)
    if len(far):
        i = int(far[0])
        raise _fail(source, f"column 'track_id' row {i}: {_show(ids[i])} is beyond 2^53, where "
                            f"floating point cannot tell neighbouring ids apart; write the ids "
                            f"as integers")
    return ids.astype(np.int64)


def validate_tracks(table: Mapping[str, np.ndarray], origin: Optional[frames.Origin] = None,
                    source: str = "tracks") -> Table:
    """Check a track table and return it normalised (see the module docstring).

    ``source`` names the table in messages (e.g. the file it was read from).
    """
    names = list(table.keys())
    unknown = [n for n in names if n not in ALLOWED]
    if unknown:
        raise _fail(source, f"unknown column(s) {', '.join(map(repr, unknown))}; a track table "
                            f"has {', '.join(ALLOWED)}")
    lengths = {n: len(np.asarray(table[n])) for n in names}
    if len(set(lengths.values())) > 1:
        raise _fail(source, f"columns have different lengths: {lengths}")
    for n in ("track_id", "time_s"):
        if n not in table:
            raise _fail(source, f"missing required column {_show(n)}")
    has_xy = "x_m" in table or "y_m" in table
    has_ll = "lat_deg" in table or "lon_deg" in table
    if has_xy:
        for n in ("x_m", "y_m"):
            if n not in table:
                raise _fail(source, f"missing column {_show(n)} (x_m and y_m come together)")
    elif has_ll:
        for n in ("lat_deg", "lon_deg"):
            if n not in table:
                raise _fail(source, f"missing column {_show(n)} (lat_deg and lon_deg come "
                                    f"together)")
        if origin is None:
            raise _fail(source, "positions are lat_deg/lon_deg but no scene origin was given to "
                                "convert them to x_m/y_m")
    else:
        raise _fail(source, "missing position columns: need x_m and y_m, or lat_deg and lon_deg")
    for group in GROUPS:
        present = [n for n in group if n in table]
        if present and len(present) != len(group):
            missing = [n for n in group if n not in table]
            raise _fail(source, f"column(s) {', '.join(present)} given without "
                                f"{', '.join(missing)} (they come together)")

    out: Table = {}
    out["track_id"] = _track_ids(table, source)
    out["time_s"] = _numeric(table, "time_s", source)
    if has_xy:
        out["x_m"] = _numeric(table, "x_m", source)
        out["y_m"] = _numeric(table, "y_m", source)
    else:
        lat = _numeric(table, "lat_deg", source)
        lon = _numeric(table, "lon_deg", source)
        h = _numeric(table, "height_m", source) if "height_m" in table else np.full(
            len(lat), origin.height_m)
        bad = np.flatnonzero((np.abs(lat) > 90.0) | (np.abs(lon) > 360.0))
        if len(bad):
            i = int(bad[0])
            raise _fail(source, f"row {i}: lat_deg {_show(lat[i])} / lon_deg "
                                f"{_show(lon[i])} out of range")
        x, y, z = frames.geodetic_to_enu(origin, lat, lon, h)
        out["x_m"], out["y_m"] = x, y
        if "z_m" not in table:
            out["z_m"] = z
    for n in ("x_m", "y_m"):
        far = np.flatnonzero(np.abs(out[n]) > MAX_POSITION_M)
        if len(far):
            i = int(far[0])
            raise _fail(source, f"column {_show(n)} row {i}: {_show(out[n][i])} is farther than "
                                f"{MAX_POSITION_M:.0e} m from the scene origin (no point on Earth"
                                f" is; a unit or frame error?)")
    for group in GROUPS:
        if group[0] in table:
            for n in group:
                out[n] = _numeric(table, n, source)
    for n in ("range_rate_mps", "z_m"):
        if n in table:
            out[n] = _numeric(table, n, source)
    if "confirmed" in table:
        conf = np.asarray(table["confirmed"])
        if conf.dtype.kind in "UO":            # text from CSV/XML: true/false/1/0
            words = {"true": True, "false": False, "1": True, "0": False}
            text = [str(v).strip().lower() for v in conf]
            bad = [i for i, w in enumerate(text) if w not in words]
            if bad:
                raise _fail(source, f"column 'confirmed' row {bad[0]}: {_show(conf[bad[0]])} is "
                                    f"not a bool (true/false or 1/0)")
            conf = np.asarray([words[w] for w in text], bool)
        if conf.dtype != bool:
            vals = _numeric(table, "confirmed", source)
            bad = np.flatnonzero((vals != 0) & (vals != 1))
            if len(bad):
                i = int(bad[0])
                raise _fail(source, f"column 'confirmed' row {i}: {_show(conf[i])} is not a bool "
                                    f"(true/false or 1/0)")
            conf = vals.astype(bool)
        out["confirmed"] = conf.astype(bool)
    if "cov_xx_m2" in out:
        bad = np.flatnonzero((out["cov_xx_m2"] < 0) | (out["cov_yy_m2"] < 0))
        if len(bad):
            i = int(bad[0])
            raise _fail(source, f"row {i}: negative variance cov_xx_m2/cov_yy_m2")

    n = len(out["track_id"])
    if n:
        order = np.lexsort((out["time_s"], out["track_id"]))
        sid, st = out["track_id"][order], out["time_s"][order]
        same = np.flatnonzero((sid[1:] == sid[:-1]) & (st[1:] == st[:-1]))
        if len(same):
            a, b = sorted((int(order[same[0]]), int(order[same[0] + 1])))
            raise _fail(source, f"column 'track_id': rows {a} and {b} are both track "
                                f"{sid[same[0]]} at time_s {_show(st[same[0]])} (ids collide)")
        # Times must increase within each track in the order the rows were given.
        by_id = np.argsort(out["track_id"], kind="stable")
        bid, bt = out["track_id"][by_id], out["time_s"][by_id]
        back = np.flatnonzero((bid[1:] == bid[:-1]) & (bt[1:] < bt[:-1]))
        if len(back):
            row = int(by_id[back[0] + 1])
            raise _fail(source, f"column 'time_s' row {row}: track {bid[back[0]]} goes back in "
                                f"time ({_show(bt[back[0] + 1])} after "
                                f"{_show(bt[back[0]])}); rows of a "
                                f"track must be in increasing time order")
        out = {k: v[order] for k, v in out.items()}
    return out


def empty_tracks() -> Table:
    """A zero-row /tracks table with the baseline's columns and dtypes."""
    out = {name: np.zeros(0, float) for name in TRACK_COLUMNS}
    out["track_id"] = np.zeros(0, np.int64)
    out["confirmed"] = np.zeros(0, bool)
    return out
