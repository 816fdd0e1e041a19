"""External trajectory: a flight log or a flight simulator's output read from CSV (paper §4).

The paper plans to "replace only the platform module by a flight simulator"; this is that seam.
The file (docs/platform.md) has a header row and one row per sample:

``time_s, lat_deg, lon_deg, height_m`` (required; WGS-84, height above the ellipsoid) and
optionally ``heading_deg, pitch_deg, roll_deg`` (all three or none).  Times are seconds on the
log's clock, strictly increasing; scene time ``t`` reads the log at ``t + time_offset_s``.

Interpolation: the samples are converted to scene ENU and each of x, y, z is a cubic spline in
time (scipy ``CubicSpline``, not-a-knot ends), so the velocity is the exact derivative of the
interpolated position and is continuous, as is the acceleration.  Without attitude columns the
heading is that of the horizontal velocity, pitch the flight-path angle and bank the coordinated
turn's (paper eq. 3, φ = arctan(v ψ̇ / g) from the spline's velocity and acceleration); with them
heading, pitch and roll are interpolated linearly (heading on the unwrapped angle).
A time outside the log is an error, never an extrapolation.
"""
from __future__ import annotations

import csv
from pathlib import Path
from typing import Dict, List

import numpy as np

from gmtiflow import frames
from gmtiflow.errors import InputFileError
from gmtiflow.paths import check_input_file, excerpt
from gmtiflow.scene import flight
from gmtiflow.scene.platform_config import PlatformConfig, PlatformKind
from gmtiflow.tables import Table

REQUIRED = ("time_s", "lat_deg", "lon_deg", "height_m")
#: Largest trajectory log read (bytes): ten million samples at ~60 B a row.
MAX_TRAJECTORY_BYTES = 1 << 30
ATTITUDE = ("heading_deg", "pitch_deg", "roll_deg")
LIMITS = {"lat_deg": (-90.0, 90.0), "lon_deg": (-180.0, 360.0), "pitch_deg": (-90.0, 90.0),
          "roll_deg": (-90.0, 90.0)}


def resolve_path(path: str) -> Path:
    """A trajectory path as given: absolute, or relative to the current directory."""
    p = Path(path).expanduser()
    return p if p.is_absolute() else Path.cwd() / p


def read_trajectory_csv(path) -> Dict[str, np.ndarray]:
    """The columns of a trajectory CSV, validated; errors name the file, line and column."""
    path = Path(path)
    where = f"platform.path: {path}"
    if not path.exists() and not path.is_symlink():
        raise InputFileError(f"{where}: no such trajectory file")
    # a regular file of bounded size (/dev/zero used to be read without end)
    check_input_file(path, "platform.path: trajectory file", MAX_TRAJECTORY_BYTES)
    try:
        with open(path, newline="", encoding="utf-8") as fh:
            rows = list(csv.reader(fh))
    except FileNotFoundError:
        raise InputFileError(f"{where}: no such trajectory file") from None
    except (OSError, UnicodeDecodeError) as exc:
        what = exc.strerror if isinstance(exc, OSError) and exc.strerror else \
            f"not UTF-8 text (byte {exc.start})" if isinstance(exc, UnicodeDecodeError) else \
            type(exc).__name__
        raise InputFileError(f"{where}: cannot read the trajectory file ({what})") from None
    rows = [(n, r) for n, r in enumerate(rows, start=1) if r and any(c.strip() for c in r)
            and not r[0].lstrip().startswith("#")]
    if not rows:
        raise InputFileError(f"{where}: empty trajectory file (needs a header row "
                             f"{','.join(REQUIRED)} and at least 2 samples)")
    header_line, header = rows[0]
    names = [c.strip() for c in header]
    missing = [c for c in REQUIRED if c not in names]
    if missing:
        raise InputFileError(f"{where} line {header_line}: header lacks column(s) "
                             f"{', '.join(missing)} (got {', '.join(excerpt(n) for n in names)})")
    present = [c for c in ATTITUDE if c in names]
    if present and len(present) != len(ATTITUDE):
        raise InputFileError(f"{where} line {header_line}: attitude columns come as all of "
                             f"{', '.join(ATTITUDE)} or none (got {', '.join(present)})")
    unknown = [c for c in names if c not in REQUIRED + ATTITUDE]
    if unknown:
        raise InputFileError(f"{where} line {header_line}: unknown column(s) "
                             f"{', '.join(excerpt(n) for n in unknown)} (known: "
                             f"{', '.join(REQUIRED + ATTITUDE)})")
    wanted = list(REQUIRED) + present
    index = {c: names.index(c) for c in wanted}
    data = rows[1:]
    if len(data) < 2:
        raise InputFileError(f"{where}: needs at least 2 samples, got {len(data)}")
    cols: Dict[str, List[float]] = {c: [] for c in wanted}
    for line, row in data:
        if len(row) != len(names):
            raise InputFileError(f"{where} line {line}: {len(row)} fields, the header has "
                                 f"{len(names)}")
        for c in wanted:
            text = row[index[c]].strip()
            try:
                value = float(text)
            except ValueError:
                raise InputFileError(f"{where} line {line}, column {c}: not a number: "
                                     f"{excerpt(text)}") from None
            if not np.isfinite(value):
                raise InputFileError(f"{where} line {line}, column {c}: must be finite, "
                                     f"got {excerpt(text)}")
            lo_hi = LIMITS.get(c)
            if lo_hi and not lo_hi[0] <= value <= lo_hi[1]:
                raise InputFileError(f"{where} line {line}, column {c}: {value:g} is outside "
                                     f"[{lo_hi[0]:g}, {lo_hi[1]:g}]")
            cols[c].append(value)
    out = {c: np.asarray(v, float) for c, v in cols.items()}
    lines = np.asarray([line for line, _ in data])
    bad = np.flatnonzero(np.diff(out["time_s"]) <= 0.0)
    if bad.size:
        k = int(bad[0]) + 1
        raise InputFileError(f"{where} line {lines[k]}, column time_s: times must be strictly "
                             f"increasing, got {out['time_s'][k]:g} after "
                             f"{out['time_s'][k - 1]:g} (line {lines[k - 1]})")
    return out


def coverage_problem(cfg: PlatformConfig, duration_s: float, key: str = "platform"):
    """Why an external trajectory cannot fly a scene of ``duration_s``, or None.

    The run samples the platform at scene times 0 .. ``duration_s`` and a log is never
    extrapolated, so a log that starts late or ends early is a config error, found before any
    work (it used to surface only at the platform stage).  Reads the file (errors in it are
    InputFileError naming file, line and column, as at the platform stage).
    """
    if PlatformKind(cfg.kind) is not PlatformKind.trajectory or not cfg.path:
        return None
    path = resolve_path(cfg.path)
    t = read_trajectory_csv(path)["time_s"]
    offset = float(cfg.time_offset_s)
    first, last = float(t[0]) - offset, float(t[-1]) - offset
    if first <= 0.0 and last >= float(duration_s):
        return None
    return (f"{key}.path: {path} covers scene times {first:g} .. {last:g} s (log times "
            f"{float(t[0]):g} .. {float(t[-1]):g} s, {key}.time_offset_s = {offset:g}) but the "
            f"scene needs 0 .. {float(duration_s):g} s (scene.duration_s): a trajectory is not "
            f"extrapolated; extend the log, change {key}.time_offset_s or shorten "
            f"scene.duration_s")


def check_scene_coverage(app_cfg) -> None:
    """ConfigError if any sensor's external trajectory does not cover the whole scene."""
    from gmtiflow.config import sensor_slots
    from gmtiflow.errors import ConfigError

    for slot in sensor_slots(app_cfg):
        key = "platform" if slot.sensor_id == 0 else f"sensors.{slot.name}.platform"
        problem = coverage_problem(slot.platform, app_cfg.scene.duration_s, key)
        if problem:
            raise ConfigError(f"invalid config: {problem}")


class Trajectory:
    """State along an external trajectory log at any instants within it (vectorised)."""

    def __init__(self, cfg: PlatformConfig, origin: frames.Origin):
        self.cfg = cfg
        self.origin = origin
        self.source = str(cfg.path)
        log = read_trajectory_csv(resolve_path(cfg.path))
        self.offset_s = float(cfg.time_offset_s)
        t = log["time_s"]
        self.log_start_s, self.log_end_s = float(t[0]), float(t[-1])
        x, y, z = frames.geodetic_to_enu(origin, log["lat_deg"], log["lon_deg"],
                                         log["height_m"])
        from scipy.interpolate import CubicSpline   # 0.3 s: only when a platform flies
        self.spline = CubicSpline(t, np.column_stack([x, y, z]), axis=0, bc_type="not-a-knot")
        self.velocity = self.spline.derivative(1)
        self.acceleration = self.spline.derivative(2)
        self.log_t_s = t
        self.attitude = None
        if "heading_deg" in log:
            self.attitude = (np.unwrap(np.radians(log["heading_deg"])),
                             np.radians(log["pitch_deg"]), np.radians(log["roll_deg"]))

    def scene_span_s(self):
        """The scene times the log covers: [start, end]."""
        return self.log_start_s - self.offset_s, self.log_end_s - self.offset_s

    def state_at(self, time_s) -> Table:
        """The /platform columns (docs/tables.md) at each of ``time_s`` (scene seconds)."""
        t = np.atleast_1d(np.asarray(time_s, float))
        tl = t + self.offset_s
        if t.size:
            outside = (tl < self.log_start_s) | (tl > self.log_end_s) | ~np.isfinite(tl)
            if np.any(outside):
                first, last = self.scene_span_s()
                bad = t[outside]
                raise InputFileError(
                    f"platform.path: {self.source} covers scene times {first:g} .. {last:g} s "
                    f"(log times {self.log_start_s:g} .. {self.log_end_s:g} s, time_offset_s = "
                    f"{self.offset_s:g}); asked for {bad.min():g} .. {bad.max():g} s: a trajectory "
                    f"is not extrapolated, extend the log or shorten scene.duration_s")
        pos = self.spline(tl)
        vel = self.velocity(tl)
        x, y, z = pos[:, 0], pos[:, 1], pos[:, 2]
        vx, vy, vz = vel[:, 0], vel[:, 1], vel[:, 2]
        if self.attitude is None:
            acc = self.acceleration(tl)
            v_h = np.hypot(vx, vy)
            heading = frames.heading_rad(vx, vy)
            pitch = np.arctan2(vz, v_h)
            bank = flight.coordinated_bank_rad(vx, vy, acc[:, 0], acc[:, 1])
        else:
            head_u, pitch_l, roll_l = self.attitude
            heading = np.mod(np.interp(tl, self.log_t_s, head_u), 2.0 * np.pi)
            pitch = np.interp(tl, self.log_t_s, pitch_l)
            bank = np.interp(tl, self.log_t_s, roll_l)
        return flight.state_table(self.origin, t, x, y, z, vx, vy, vz, heading, pitch, bank)
