"""The tracker protocol: how any tracker is fed a run, dwell by dwell, and what it gives back.

A tracker is any object with three methods (:class:`Tracker`)::

    reset(scene: SceneInfo) -> None          # once, before the first batch
    update(batch: Batch) -> tracks or None   # once per batch, in time order
    finish() -> tracks or None               # once, after the last batch

*tracks* is a table (a mapping of equal-length columns, e.g. a dict of numpy arrays or a pandas
DataFrame's ``to_dict("list")``) of the track states the tracker reports at that batch:
``track_id x_m y_m`` required, ``time_s`` optional (default: the batch's ``time_s``), and any of
the optional /tracks columns (``vx_mps vy_mps``, ``cov_xx_m2 cov_xy_m2 cov_yy_m2``,
``range_rate_mps``, ``confirmed``; docs/tables.md).  Return ``None`` (or an empty table) to
report nothing.  :func:`run_tracker` concatenates everything, keeps the last state of a track
reported twice at one instant, and checks the result with
:func:`~gmtiflow.evaluate.tracks.validate_tracks`: the /tracks table the metrics score.

A :class:`Batch` is one dwell (``per="dwell"``, default) or one revisit (``per="revisit"``: the
consecutive dwells of one sensor's revisit) with:

* ``dwells``: one row per dwell in time order (:data:`DWELL_FIELDS`): ``dwell_id sensor_id
  revisit_id revisit_end time_s``, the platform state ``platform_{x,y,z}_m
  platform_v{x,y,z}_mps`` (scene ENU, the dwell's own sensor), the beam ``beam_az_rad``
  (world azimuth, clockwise from north), and the footprint ``angle_half_extent_rad
  range_half_extent_m`` around ``area_{x,y,z}_m`` (the dwell-area centre, ENU) at slant range
  ``area_range_m`` from the platform; ``mdv_mps``, ``wrap_velocity_mps``.  Columns the run does
  not have are absent (footprint centre: needs the scene origin);
* ``detections``: the dwells' detections (possibly none: a dwell that saw nothing is still a
  batch), ordered by dwell, :data:`BLIND_DETECTION_COLUMNS` only — the measurement, its σ's
  and the processor's flags, never truth (``truth_id``, ``true_*``, ``merged``, the
  ambiguity flags and the target RCS are dropped); ``sensor_id`` is 0 when the run has one
  sensor.  Within a dwell, by measured slant range (then azimuth), with the dwell's
  ``det_id`` values handed out in that order (:func:`gmtiflow.blind.truth_free_order`, as
  ``export.blind`` files): not run.h5's order, which lists targets by vehicle id, then false
  alarms;
* ``time_s`` (its last dwell's time) and ``index`` (0, 1, ...).

Several sensors: batches of all sensors come in one time order, each detection with its own
dwell's (own sensor's) geometry and σ's, so a tracker that updates each detection with its own
sensor geometry does centralised measurement-level fusion.

:func:`batches` makes the batches from in-memory /dwells and /detections tables, :func:`stream`
from a run file (``gmtiflow.stream("outputs/.../run.h5")``), for users who drive their own
loop.  :func:`load_tracker` builds a tracker from the config (``tracker.target``, an import path,
with ``tracker.params`` as keyword arguments); :func:`run_tracker` drives one and reports an
exception raised in the tracker's code as a :class:`TrackerError` naming the class, the method
and the dwell.
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Any, Dict, Iterable, Iterator, Mapping, Optional, Tuple

import numpy as np

from gmtiflow import frames
# TRUTH_DETECTION_COLUMNS: part of the protocol's names for user trackers (defined in blind)
from gmtiflow.blind import (BLIND_DETECTION_COLUMNS, TRUTH_DETECTION_COLUMNS,  # noqa: F401
                            truth_free_order)
from gmtiflow.errors import ConfigError, GmtiflowError, InputFileError
from gmtiflow.tables import Table

try:                                    # typing.Protocol: 3.8+
    from typing import Protocol, runtime_checkable
except ImportError:                     # pragma: no cover
    Protocol = object                   # type: ignore

    def runtime_checkable(cls):         # type: ignore
        return cls

DWELL_FIELDS = (
    "dwell_id", "sensor_id", "revisit_id", "revisit_end", "time_s", "cpi_s",
    "platform_x_m", "platform_y_m", "platform_z_m",
    "platform_vx_mps", "platform_vy_mps", "platform_vz_mps",
    "platform_heading_rad", "platform_lat_deg", "platform_lon_deg", "platform_height_m",
    "beam_az_rad", "angle_half_extent_rad", "range_half_extent_m",
    "area_lat_deg", "area_lon_deg", "area_x_m", "area_y_m", "area_z_m", "area_range_m",
    "mdv_mps", "wrap_velocity_mps")
"""Columns of ``Batch.dwells`` (those the run provides)."""

_DET_REQUIRED = ("dwell_id", "x_m", "y_m")
_DWELL_REQUIRED = ("dwell_id", "time_s", "platform_x_m", "platform_y_m", "platform_z_m",
                   "platform_vx_mps", "platform_vy_mps", "platform_vz_mps")


class TrackerError(GmtiflowError):
    """A tracker's own code raised: names the tracker class, the method and the dwell."""


@dataclass(frozen=True)
class SceneInfo:
    """What a tracker may know before the first dwell (given to ``reset``)."""

    origin: Optional[frames.Origin] = None
    """Geodetic origin of the scene ENU frame (x east, y north, z up), if known."""
    epoch_utc: Optional[str] = None
    """UTC instant of ``time_s = 0`` (ISO 8601), if known."""
    duration_s: Optional[float] = None
    n_dwells: int = 0
    n_batches: int = 0
    sensor_ids: Tuple[int, ...] = (0,)
    per: str = "dwell"
    """``dwell`` or ``revisit``: what one batch holds."""
    seed: int = 0
    """The run's seed, for trackers that draw random numbers (derive streams from it)."""


@dataclass(frozen=True)
class Batch:
    """One dwell (or one revisit) as a tracker receives it; see the module docstring."""

    index: int
    time_s: float
    dwells: Table
    detections: Table

    @property
    def n_dwells(self) -> int:
        return len(self.dwells["dwell_id"])

    @property
    def n_detections(self) -> int:
        return len(self.detections["dwell_id"])

    def dwell_slices(self) -> Iterator[Tuple[int, slice]]:
        """``(k, rows)``: the detection rows (a slice) of the batch's ``k``-th dwell."""
        counts = self.dwells["n_detections"]
        stop = 0
        for k in range(len(counts)):
            start, stop = stop, stop + int(counts[k])
            yield k, slice(start, stop)


@runtime_checkable
class Tracker(Protocol):
    """The three methods gmtiflow calls (structural: no base class needed)."""

    def reset(self, scene: SceneInfo) -> None: ...

    def update(self, batch: Batch) -> Optional[Mapping[str, Any]]: ...

    def finish(self) -> Optional[Mapping[str, Any]]: ...


def _require(table: Mapping[str, np.ndarray], names, what: str) -> None:
    missing = [n for n in names if n not in table]
    if missing:
        raise InputFileError(f"{what}: missing column(s) {', '.join(missing)} "
                             f"(docs/tables.md lists the columns)")


def _key(sensor, dwell) -> np.ndarray:
    return np.asarray(sensor, np.int64) * (1 << 40) + np.asarray(dwell, np.int64)


class _Prepared:
    """/dwells and /detections sorted once into batch order; batches are slices of them."""

    def __init__(self, detections: Mapping[str, np.ndarray], dwells: Mapping[str, np.ndarray],
                 origin: Optional[frames.Origin], per: str) -> None:
        if per not in ("dwell", "revisit"):
            raise ConfigError(f"tracker.per: must be 'dwell' or 'revisit', got {per!r}")
        _require(detections, _DET_REQUIRED, "/detections")
        _require(dwells, _DWELL_REQUIRED, "/dwells")
        n_dw = len(dwells["dwell_id"])
        n_det = len(detections["dwell_id"])
        dw_sensor = (np.asarray(dwells["sensor_id"], np.int64) if "sensor_id" in dwells
                     else np.zeros(n_dw, np.int64))
        # Time order; ties (instant scans) by dwell id then sensor: the baseline's order.
        order = np.lexsort((dw_sensor, np.asarray(dwells["dwell_id"]),
                            np.asarray(dwells["time_s"], float)))
        dw: Table = {}
        for name in DWELL_FIELDS:
            if name in dwells:
                dw[name] = np.asarray(dwells[name])[order]
        dw["sensor_id"] = dw_sensor[order]
        if "revisit_id" in dw:
            rev = np.asarray(dw["revisit_id"], np.int64)
            # A dwell ends its revisit when the next dwell of the same sensor is of another one.
            end = np.ones(n_dw, bool)
            for s in np.unique(dw["sensor_id"]):
                idx = np.flatnonzero(dw["sensor_id"] == s)
                end[idx[:-1]] = rev[idx[1:]] != rev[idx[:-1]]
            dw["revisit_end"] = end
        else:
            dw["revisit_id"] = np.arange(n_dw, dtype=np.int64)
            dw["revisit_end"] = np.ones(n_dw, bool)
        if origin is not None and all(c in dw for c in ("area_lat_deg", "area_lon_deg")):
            cx, cy, cz = frames.geodetic_to_enu(origin, dw["area_lat_deg"], dw["area_lon_deg"],
                                                np.full(n_dw, origin.height_m))
            dw["area_x_m"], dw["area_y_m"], dw["area_z_m"] = cx, cy, cz
            dw["area_range_m"] = np.sqrt((cx - dw["platform_x_m"]) ** 2
                                         + (cy - dw["platform_y_m"]) ** 2
                                         + (cz - dw["platform_z_m"]) ** 2)

        # Detections grouped by dwell position (stable: their own order within a dwell).
        det_sensor = (np.asarray(detections["sensor_id"], np.int64) if "sensor_id" in detections
                      else np.zeros(n_det, np.int64))
        dkey = _key(dw["sensor_id"], dw["dwell_id"])
        key_order = np.argsort(dkey, kind="stable")
        sorted_keys = dkey[key_order]
        det_key = _key(det_sensor, detections["dwell_id"])
        pos = np.searchsorted(sorted_keys, det_key)
        known = (pos < n_dw) & (sorted_keys[np.minimum(pos, max(n_dw - 1, 0))] == det_key) \
            if n_dw else np.zeros(n_det, bool)
        if not known.all():
            i = int(np.flatnonzero(~known)[0])
            raise InputFileError(f"/detections row {i}: dwell_id "
                                 f"{int(np.asarray(detections['dwell_id'])[i])} is not in "
                                 f"/dwells")
        det_dwell_pos = key_order[pos] if n_det else np.zeros(0, np.int64)
        # Grouped by dwell position, each dwell's reports in a truth-free order (by measured
        # slant range, det_ids handed out in that order; gmtiflow.blind): run.h5's order
        # (targets by vehicle id, then false alarms) would give truth away.
        det: Table = {name: np.asarray(detections[name]) for name in BLIND_DETECTION_COLUMNS
                      if name in detections}
        det["sensor_id"] = det_sensor
        det = truth_free_order(det, group=det_dwell_pos)
        counts = np.bincount(det_dwell_pos, minlength=n_dw).astype(np.int64)
        dw["n_detections"] = counts
        self.dwells, self.detections = dw, det
        self.det_start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)

        # Batch boundaries: every dwell, or runs of one sensor's revisit.
        if per == "dwell" or n_dw == 0:
            self.bounds = np.arange(n_dw + 1, dtype=np.int64)
        else:
            rev, sen = dw["revisit_id"], dw["sensor_id"]
            cut = np.flatnonzero((rev[1:] != rev[:-1]) | (sen[1:] != sen[:-1])) + 1
            self.bounds = np.concatenate([[0], cut, [n_dw]]).astype(np.int64)
        self.n_dwells = n_dw
        self.sensor_ids = tuple(int(s) for s in np.unique(dw["sensor_id"])) or (0,)

    def __len__(self) -> int:
        return len(self.bounds) - 1

    def __iter__(self) -> Iterator[Batch]:
        dw, det, start, bounds = self.dwells, self.detections, self.det_start, self.bounds
        times = dw["time_s"]
        dw_items, det_items = list(dw.items()), list(det.items())
        for b in range(len(bounds) - 1):
            lo, hi = int(bounds[b]), int(bounds[b + 1])
            dlo, dhi = int(start[lo]), int(start[hi])
            yield Batch(index=b, time_s=float(times[hi - 1]),
                        dwells={k: v[lo:hi] for k, v in dw_items},
                        detections={k: v[dlo:dhi] for k, v in det_items})


def batches(detections: Mapping[str, np.ndarray], dwells: Mapping[str, np.ndarray], *,
            origin: Optional[frames.Origin] = None, per: str = "dwell") -> Iterator[Batch]:
    """The batches of a run's /detections and /dwells tables, in time order (a generator)."""
    return iter(_Prepared(detections, dwells, origin, per))


def scene_info_of(run_path) -> SceneInfo:
    """The :class:`SceneInfo` of a run file (without counting its batches)."""
    from gmtiflow.store import open_run
    with open_run(run_path) as f:
        attrs = dict(f.attrs)
    epoch = attrs.get("scene_epoch_utc")
    return SceneInfo(origin=frames.Origin.from_attrs(attrs),
                     epoch_utc=None if epoch is None else str(epoch),
                     duration_s=(float(attrs["scene_duration_s"])
                                 if "scene_duration_s" in attrs else None),
                     seed=int(attrs.get("seed", 0)))


def stream(run_path, per: str = "dwell") -> Iterator[Batch]:
    """Batches of a run file, in time order: ``for batch in gmtiflow.stream("run.h5"): ...``.

    Reads /dwells and the blind columns of /detections (never truth).  ``per``: ``dwell`` or
    ``revisit``.  :func:`scene_info_of` gives the run's :class:`SceneInfo`.
    """
    from gmtiflow.store import open_run, read_table
    with open_run(run_path) as f:
        origin = frames.Origin.from_attrs(f.attrs)
        if "dwells" not in f or "detections" not in f:
            raise InputFileError(f"{run_path}: has no /dwells or /detections to stream")
        dwells = read_table(f, "dwells")
        detections = {k: v for k, v in read_table(f, "detections").items()
                      if k in BLIND_DETECTION_COLUMNS}
    return batches(detections, dwells, origin=origin, per=per)


def import_object(path: str, what: str = "tracker.target"):
    """The object at ``pkg.module.Name`` (or ``pkg.module:Name``); ConfigError if it is not."""
    if not isinstance(path, str) or not path.strip():
        raise ConfigError(f"{what}: must be an import path such as mypkg.MyTracker, got "
                          f"{path!r}")
    path = path.strip()
    if ":" in path:
        mod_name, _, attr = path.partition(":")
    else:
        mod_name, _, attr = path.rpartition(".")
    if not mod_name or not attr:
        raise ConfigError(f"{what}: {path!r} is not an import path (module.Name)")
    try:
        module = importlib.import_module(mod_name)
    except ImportError as exc:
        raise ConfigError(f"{what}: cannot import module {mod_name!r} for {path!r} "
                          f"({exc})") from None
    except SyntaxError as exc:          # the user's module does not compile
        raise TrackerError(f"{what}: module {mod_name!r} has a syntax error: {exc.msg} "
                           f"({exc.filename}, line {exc.lineno})") from None
    except Exception as exc:            # noqa: BLE001 - the user's module raised at import
        raise TrackerError(f"{what}: importing module {mod_name!r} raised "
                           f"{type(exc).__name__}: {exc}") from None
    obj = module
    for part in attr.split("."):
        try:
            obj = getattr(obj, part)
        except AttributeError:
            raise ConfigError(f"{what}: module {mod_name!r} has no {attr!r}") from None
        except Exception as exc:        # noqa: BLE001 - a module __getattr__ that raised
            raise TrackerError(f"{what}: reading {attr!r} of module {mod_name!r} raised "
                               f"{type(exc).__name__}: {exc}") from None
    return obj


def _name(obj) -> str:
    cls = obj if isinstance(obj, type) else type(obj)
    return f"{cls.__module__}.{cls.__qualname__}"


def load_tracker(target: str, params: Optional[Mapping[str, Any]] = None):
    """Instantiate ``target`` (an import path to a class or factory) with ``params``."""
    factory = import_object(target)
    if not callable(factory):
        raise ConfigError(f"tracker.target: {target!r} is not a class or a function")
    kwargs = dict(params or {})
    try:
        tracker = factory(**kwargs)
    except TypeError as exc:
        raise ConfigError(f"tracker.params: {target}({', '.join(kwargs)}) failed: {exc}"
                          ) from exc
    except Exception as exc:
        raise TrackerError(f"tracker {target}: constructor raised "
                           f"{type(exc).__name__}: {exc}") from exc
    missing = [m for m in ("reset", "update", "finish") if not callable(getattr(tracker, m, None))]
    if missing:
        raise ConfigError(f"tracker.target: {_name(tracker)} lacks the tracker method(s) "
                          f"{', '.join(missing)} (docs/evaluation.md, 'Plug in a tracker')")
    return tracker


def _text(message) -> str:
    """An error message's place, given as text or as a function making it (only on error)."""
    return message() if callable(message) else message


def _as_table(result, batch_time: Optional[float], who) -> Optional[Dict[str, np.ndarray]]:
    """A tracker's report as a dict of 1-D arrays with ``time_s`` (None when empty).  ``who``
    (text, or a function giving it) names the report in error messages."""
    if result is None:
        return None
    if isinstance(result, dict) and _plain_columns(result):
        n = len(next(iter(result.values()))) if result else 0
        if n == 0:
            return None
        if "time_s" not in result:
            if batch_time is None:
                raise TrackerError(f"{_text(who)} returned rows without a time_s column")
            return {**result, "time_s": np.full(n, batch_time)}
        return dict(result)
    if hasattr(result, "to_dict") and hasattr(result, "columns"):   # pandas DataFrame
        result = {c: np.asarray(result[c]) for c in result.columns}
    if not isinstance(result, Mapping):
        raise TrackerError(f"{_text(who)} returned {type(result).__name__}; expected a table (a "
                           f"mapping of columns such as track_id, x_m, y_m) or None")
    out = {str(k): np.atleast_1d(np.asarray(v)) for k, v in result.items()}
    lengths = {k: len(v) for k, v in out.items()}
    if len(set(lengths.values())) > 1:
        raise TrackerError(f"{_text(who)} returned columns of different lengths: {lengths}")
    n = next(iter(lengths.values()), 0)
    if n == 0:
        return None
    if "time_s" not in out:
        if batch_time is None:
            raise TrackerError(f"{_text(who)} returned rows without a time_s column")
        out["time_s"] = np.full(n, batch_time)
    return out


def _where(batch: Batch) -> str:
    ids = batch.dwells["dwell_id"]
    if len(ids) == 1:
        where = f"dwell {int(ids[0])}"
    else:
        where = f"dwells {int(ids[0])}..{int(ids[-1])}"
    sensors = np.unique(batch.dwells["sensor_id"])
    if len(sensors) == 1 and int(sensors[0]) != 0:
        where += f" of sensor {int(sensors[0])}"
    return f"{where} (t = {batch.time_s:.3f} s, batch {batch.index})"


def _plain_columns(result: dict) -> bool:
    """Whether ``result`` is already what :func:`_as_table` makes of it: str keys, 1-D numpy
    arrays of one length (the baseline's reports; then it is used as it is)."""
    n = -1
    for k, v in result.items():
        if type(k) is not str or type(v) is not np.ndarray or v.ndim != 1:
            return False
        if n < 0:
            n = len(v)
        elif len(v) != n:
            return False
    return True


def _call(tracker, method: str, arg, where):
    """``tracker.method(arg)``; an exception in it becomes a TrackerError naming ``where`` (text,
    or a function giving it)."""
    try:
        return getattr(tracker, method)(*(() if arg is None else (arg,)))
    except GmtiflowError:
        raise
    except Exception as exc:
        raise TrackerError(f"tracker {_name(tracker)}.{method}() raised at {_text(where)}: "
                           f"{type(exc).__name__}: {exc}") from exc


def collect(parts, origin: Optional[frames.Origin], source: str) -> Table:
    """One /tracks table from the reports: sorted by (track_id, time_s), last report per instant
    kept, then checked with :func:`~gmtiflow.evaluate.tracks.validate_tracks`."""
    from gmtiflow.evaluate.tracks import validate_tracks
    parts = [p for p in parts if p is not None]
    if not parts:
        return None
    names = list(parts[0])
    for p in parts[1:]:
        if list(p) != names and set(p) != set(names):
            raise TrackerError(f"{source}: reports differ in their columns ({sorted(names)} vs "
                               f"{sorted(p)}); give the same columns every time")
    table = {n: np.concatenate([p[n] for p in parts]) for n in names}
    try:
        ids = np.asarray(table["track_id"])
        t = np.asarray(table["time_s"], float)
    except KeyError:
        raise TrackerError(f"{source}: reported tracks without a track_id column") from None
    except (TypeError, ValueError):
        raise TrackerError(f"{source}: time_s is not numeric") from None
    order = np.lexsort((t, ids))
    table = {n: c[order] for n, c in table.items()}
    ids, t = ids[order], t[order]
    # A track reported twice at one instant (several dwells at one time): keep its last state.
    last = np.ones(len(ids), bool)
    last[:-1] = (ids[1:] != ids[:-1]) | (t[1:] != t[:-1])
    table = {n: c[last] for n, c in table.items()}
    try:
        return validate_tracks(table, origin, source)
    except InputFileError as exc:
        raise TrackerError(str(exc)) from None


def run_tracker(tracker, prepared: Iterable[Batch], scene: SceneInfo,
                origin: Optional[frames.Origin] = None) -> Optional[Table]:
    """Drive ``tracker`` over ``prepared`` batches; returns its /tracks (None: no rows)."""
    who = _name(tracker)
    _call(tracker, "reset", scene, "reset (before the first dwell)")
    parts = []
    for batch in prepared:
        res = _call(tracker, "update", batch, lambda: _where(batch))
        if res is not None:
            parts.append(_as_table(res, batch.time_s,
                                   lambda: f"tracker {who}.update() at {_where(batch)}"))
    res = _call(tracker, "finish", None, "finish (after the last dwell)")
    if res is not None:
        parts.append(_as_table(res, None, f"tracker {who}.finish()"))
    return collect(parts, origin, f"tracker {who}")
