"""Radar cross sections of vehicles: constant per type, or an aspect-angle table (paper §5.1).

Aspect angle = vehicle heading − azimuth of the line of sight (platform → target, horizontal),
both clockwise from north, in [0°, 360°): 0° the vehicle drives straight away from the radar
(the radar sees its rear), 180° it comes straight at the radar (front), 90° it crosses the line
of sight from left to right as seen from the radar (the radar sees its left side).

Table files are UTF-8 CSV (a byte-order mark, as spreadsheets write, is skipped) with the
header ``aspect_deg,rcs_dbsm`` (``#`` comment lines and blank lines are skipped), at least two rows, angles strictly increasing in [0, 360), values within
±:data:`MAX_ABS_DBSM` dBsm, the file a regular file of at most :data:`MAX_TABLE_BYTES`.  They are interpolated
linearly in dBsm and periodically over 360° (the last row joins the first).  Any problem raises
:class:`~gmtiflow.errors.InputFileError` naming the file and line.
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Dict, Mapping, Optional, Sequence, Tuple

import numpy as np

from gmtiflow.errors import ConfigError, InputFileError
from gmtiflow.frames import heading_rad
from gmtiflow.sensor import fastnp
from gmtiflow.paths import check_input_file, excerpt

CONF_DIR = Path(__file__).resolve().parents[2] / "conf"

MAX_TABLE_BYTES = 16 * 2**20
"""An RCS table of 0.001° steps is 6 MB; a bigger file (or /dev/zero) is refused unread."""

MAX_ABS_DBSM = 100.0
"""RCS values beyond ±100 dBsm (1e-10 to 1e10 m²) are not a vehicle's: refused."""


def resolve_table_path(path: str) -> Path:
    """A table path as given, else relative to the packaged ``conf/`` directory."""
    p = Path(path).expanduser()
    if p.is_absolute() or p.exists():
        return p
    try:  # installed wheel: conf/ is the package gmtiflow.conf
        import gmtiflow.conf as _conf  # type: ignore[import-not-found]
        conf_dir = Path(next(iter(_conf.__path__)))
    except (ImportError, StopIteration):
        conf_dir = CONF_DIR
    for base in (conf_dir, CONF_DIR):
        if (base / p).exists():
            return base / p
    return p


def load_table(path: str) -> Tuple[np.ndarray, np.ndarray]:
    """(aspect_rad, rcs_dbsm) of an RCS table file, validated."""
    file = resolve_table_path(path)
    check_input_file(file, "RCS table", MAX_TABLE_BYTES)
    try:
        text = file.read_text(encoding="utf-8-sig")   # a spreadsheet's byte-order mark too
    except UnicodeDecodeError as exc:
        raise InputFileError(f"RCS table {file}: not UTF-8 text (byte {exc.start}); expected a "
                             "CSV file with columns aspect_deg,rcs_dbsm") from None
    except OSError as exc:
        raise InputFileError(f"RCS table {path!s}: cannot read ({exc.strerror or exc}); "
                             "expected a CSV file with columns aspect_deg,rcs_dbsm") from None
    rows = []
    header_seen = False
    for lineno, row in enumerate(csv.reader(text.splitlines()), start=1):
        cells = [c.strip() for c in row]
        if not cells or all(c == "" for c in cells) or cells[0].startswith("#"):
            continue
        if not header_seen:
            header_seen = True
            if [c.lower() for c in cells] != ["aspect_deg", "rcs_dbsm"]:
                other = [name for sep, name in ((";", "';'"), ("\t", "tabs"))
                         if sep in ",".join(cells)]
                hint = (f" (columns separated by {other[0]}; the table is comma-separated)"
                        if other else "")
                raise InputFileError(f"RCS table {file}, line {lineno}: expected the header "
                                     f"'aspect_deg,rcs_dbsm', got "
                                     f"{excerpt(','.join(cells))}{hint}")
            continue
        if len(cells) != 2:
            raise InputFileError(f"RCS table {file}, line {lineno}: expected 2 values "
                                 f"(aspect_deg, rcs_dbsm), got {len(cells)}")
        try:
            angle, value = float(cells[0]), float(cells[1])
        except ValueError:
            raise InputFileError(f"RCS table {file}, line {lineno}: non-numeric value in "
                                 f"{excerpt(','.join(cells))}") from None
        if not (math.isfinite(angle) and math.isfinite(value)):
            raise InputFileError(f"RCS table {file}, line {lineno}: values must be finite, got "
                                 f"{excerpt(','.join(cells))}")
        if abs(value) > MAX_ABS_DBSM:
            raise InputFileError(f"RCS table {file}, line {lineno}: rcs_dbsm {value:.6g} is "
                                 f"beyond ±{MAX_ABS_DBSM:g} dBsm; not a vehicle's RCS")
        if not 0.0 <= angle < 360.0:
            raise InputFileError(f"RCS table {file}, line {lineno}: aspect_deg must be in "
                                 f"[0, 360), got {angle!r}")
        if rows and angle <= rows[-1][0]:
            kind = "duplicate" if angle == rows[-1][0] else "unsorted"
            raise InputFileError(f"RCS table {file}, line {lineno}: {kind} aspect_deg {angle!r}; "
                                 "angles must be strictly increasing")
        rows.append((angle, value))
    if not header_seen:
        raise InputFileError(f"RCS table {file}: empty; expected the header 'aspect_deg,rcs_dbsm'"
                             " and at least 2 rows")
    if len(rows) < 2:
        raise InputFileError(f"RCS table {file}: needs at least 2 rows, got {len(rows)}")
    arr = np.asarray(rows, float)
    return np.radians(arr[:, 0]), arr[:, 1]


def interpolate(aspect_rad, table_aspect_rad, table_rcs_dbsm):
    """Periodic linear interpolation of a table (dBsm) at aspect angles (rad)."""
    return np.interp(np.mod(aspect_rad, 2.0 * np.pi), table_aspect_rad, table_rcs_dbsm,
                     period=2.0 * np.pi)


def aspect_rad(vehicle_heading_rad, los_east, los_north):
    """Aspect angle: vehicle heading − azimuth of the horizontal LOS, in [0, 2π)."""
    return np.mod(np.asarray(vehicle_heading_rad, float) - heading_rad(los_east, los_north),
                  2.0 * np.pi)


@dataclass(frozen=True)
class RcsModels:
    """Per-vehicle-type RCS models; ``type_code`` indexes ``constant_dbsm``/``tables``."""

    names: Tuple[str, ...]
    constant_dbsm: np.ndarray
    tables: Tuple[Optional[Tuple[np.ndarray, np.ndarray]], ...]

    def __post_init__(self):
        # each table prepared once for its periodic interpolation (np.interp's values)
        object.__setattr__(self, "_interp", tuple(
            None if t is None else fastnp.PeriodicInterp(t[0], t[1], 2.0 * np.pi)
            for t in self.tables))

    @classmethod
    def from_config(cls, rcs_cfg: Mapping) -> "RcsModels":
        names, consts, tables = [], [], []
        for name, model in rcs_cfg.items():
            names.append(str(name))
            consts.append(float(model.rcs_dbsm))
            tables.append(load_table(model.table) if model.table else None)
        return cls(tuple(names), np.asarray(consts, float), tuple(tables))

    def type_codes(self, vehicle_types: Sequence[str]) -> np.ndarray:
        """Index of each vehicle's model; unknown types use 'default' or raise ConfigError."""
        index: Dict[str, int] = {n: i for i, n in enumerate(self.names)}
        types = np.asarray(vehicle_types, dtype=str).ravel()
        codes = np.full(types.size, -1, np.int64)
        for name, code in index.items():     # a few names: one comparison pass each (no sort)
            codes[np.flatnonzero(types == name)] = code
        rest = np.flatnonzero(codes < 0)     # types without a model of their own
        if rest.size:
            kinds, inverse = np.unique(types[rest], return_inverse=True)
            kind_codes = np.empty(len(kinds), np.int64)
            for i, t in enumerate(kinds):
                code = index.get("default")
                if code is None:
                    raise ConfigError(f"sensor.rcs: no RCS model for vehicle type {t!r} and no "
                                      f"'default' entry; known types: {', '.join(self.names)}")
                kind_codes[i] = code
            codes[rest] = kind_codes[inverse.ravel()]
        return codes

    def rcs_dbsm(self, type_code, vehicle_heading_rad, los_east, los_north, los_azimuth_rad=None):
        """RCS (dBsm) of each pair from its type code, heading and line of sight.

        The aspect angle is only computed for the pairs whose type has a table.
        ``los_azimuth_rad``: ``arctan2(los_east, los_north)`` when the caller has it (as
        arctan2 gives it, in [−π, π]); the LOS components are then not read.
        """
        type_code = np.asarray(type_code)
        out = self.constant_dbsm[type_code]
        for code, interp in enumerate(self._interp):
            if interp is None:
                continue
            sel = np.flatnonzero(type_code == code)
            if sel.size:
                # np.interp with a period wraps the angle itself: no np.mod needed here
                los_az = (np.arctan2(np.asarray(los_east)[sel], np.asarray(los_north)[sel])
                          if los_azimuth_rad is None else np.asarray(los_azimuth_rad)[sel])
                aspect = np.asarray(vehicle_heading_rad)[sel] - los_az
                out[sel] = interp(aspect)           # np.interp(..., period=2π)
        return out
