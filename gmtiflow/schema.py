"""Validation helpers shared by every config dataclass.

Each config group's schema is a dataclass declared next to the code that uses it
(``gmtiflow.scene.roadmap.RoadmapConfig`` ...) and composed into ``gmtiflow.config.AppConfig``.
Hydra/OmegaConf already reject unknown keys, wrong types and missing values at compose time.
Ranges and cross-field rules are declared by a method ``problems(self) -> list[Problem]`` on the
dataclass; :func:`gmtiflow.config.validate` walks the tree and raises one
:class:`~gmtiflow.errors.ConfigError` naming the full key path (``sensor.az_min_deg``), the value
and the allowed range.
"""
from __future__ import annotations

import math
from itertools import chain
from dataclasses import dataclass
from typing import Any, List, Optional


MAX_MAGNITUDE = 1e12
"""No numeric setting may exceed this in magnitude in its own unit (1e12 m, s, Hz, W ...):
such values are typos, and their products overflow float64 deep in the physics
(:func:`gmtiflow.config.magnitude_problems` reports them; a ``problems`` method that does
arithmetic on values beyond it leaves them to that).  ``seed`` is the one exception (any
integer in [0, 2^63))."""


@dataclass(frozen=True)
class Problem:
    """One invalid config value: ``key`` relative to the dataclass, and what was expected."""

    key: str
    message: str


def positive(obj: Any, *names: str) -> List[Problem]:
    """Problems for fields of ``obj`` that are not finite and > 0."""
    out = []
    for name in names:
        value = getattr(obj, name)
        if value is None:
            continue
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            out.append(Problem(name, f"must be a finite number > 0, got {value!r}"))
    return out


def non_negative(obj: Any, *names: str) -> List[Problem]:
    """Problems for fields of ``obj`` that are not finite and >= 0."""
    out = []
    for name in names:
        value = getattr(obj, name)
        if value is None:
            continue
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
            out.append(Problem(name, f"must be a finite number >= 0, got {value!r}"))
    return out


def in_range(obj: Any, name: str, lo: float, hi: float, *, lo_open: bool = False,
             hi_open: bool = False) -> List[Problem]:
    """Problems if field ``name`` of ``obj`` is outside [lo, hi] (ends open as asked)."""
    value = getattr(obj, name)
    if value is None:
        return []
    ok = isinstance(value, (int, float)) and math.isfinite(value)
    ok = ok and (value > lo if lo_open else value >= lo) and (value < hi if hi_open else value <= hi)
    if ok:
        return []
    left = "(" if lo_open else "["
    right = ")" if hi_open else "]"
    return [Problem(name, f"must be in {left}{lo}, {hi}{right}, got {value!r}")]


def ordered(obj: Any, low: str, high: str, *, strict: bool = True) -> List[Problem]:
    """Problems if ``obj.low`` is not below (or, not strict, not at most) ``obj.high``."""
    a, b = getattr(obj, low), getattr(obj, high)
    if a is None or b is None:
        return []
    if (a < b) if strict else (a <= b):
        return []
    rel = "<" if strict else "<="
    return [Problem(low, f"must be {rel} {high} ({b!r}), got {a!r}")]


def prefixed(prefix: str, problems: List[Problem]) -> List[Problem]:
    """Problems of a nested object, re-keyed under ``prefix``."""
    return [Problem(f"{prefix}.{p.key}", p.message) for p in problems]


def optional_path(value: Optional[str]) -> Optional[str]:
    """Normalise an optional path value ('' and None both mean unset)."""
    return value or None


def is_number(value: Any) -> bool:
    """A finite int or float (not a bool, not a string)."""
    return (isinstance(value, (int, float)) and not isinstance(value, bool)
            and math.isfinite(value))


def point_problems(key: str, point: Any, dims=(2, 3), what: str = "[x, y] or [x, y, z]",
                   geodetic: bool = False) -> List[Problem]:
    """Problems of one coordinate list (e.g. a waypoint) given as ``key``.

    Coordinate lists are typed ``Any`` in the schemas because OmegaConf 2.3 rejects YAML
    integers inside nested float containers (``List[List[float]]``); this check replaces the
    type check with a message that names the key.
    """
    if geodetic and hasattr(point, "keys"):     # {lat_deg, lon_deg[, height_m]}: frames.point_to_enu
        keys = set(point.keys())
        bad = keys - {"lat_deg", "lon_deg", "height_m"}
        if bad or not {"lat_deg", "lon_deg"} <= keys:
            return [Problem(key, f"a geodetic point is {{lat_deg: .., lon_deg: .., height_m: ..}} "
                                 f"(height_m optional), got keys {sorted(keys)}")]
        lat, lon, h = point.get("lat_deg"), point.get("lon_deg"), point.get("height_m", 0.0)
        if not (is_number(lat) and -90 <= lat <= 90 and is_number(lon) and -180 <= lon <= 360
                and (h is None or is_number(h))):
            return [Problem(key, f"lat_deg must be in [-90, 90], lon_deg in [-180, 360] and "
                                 f"height_m a finite number, got {dict(point)!r}")]
        return []
    ok = isinstance(point, (list, tuple)) and len(point) in dims and all(map(is_number, point))
    if ok:
        return []
    shown = list(point) if isinstance(point, (list, tuple)) else point
    alt = " or {lat_deg, lon_deg, height_m}" if geodetic else ""
    return [Problem(key, f"must be {what} in finite metres{alt}, got {shown!r}")]


def points_problems(key: str, points: Any, dims=(2, 3), what: str = "[x, y] or [x, y, z]",
                    geodetic: bool = False) -> List[Problem]:
    """:func:`point_problems` of every item of a list of points, keyed ``key[i]``.

    Lists of number lists of the right lengths are checked in bulk (a scene may list thousands
    of waypoints); anything else, or any non-finite value, is checked point by point.
    """
    if _finite_rows(points, dims):
        return []
    return [problem for i, point in enumerate(points)
            for problem in point_problems(f"{key}[{i}]", point, dims, what, geodetic)]


def _finite_rows(points: Any, dims) -> bool:
    """``points`` is a list of lists (or tuples) of ``dims`` finite ints and floats.

    ``math.fsum`` of finite values is finite (or raises on overflow); one NaN or infinity, or
    an int too large for a float, makes it NaN, infinite or raise: then the answer is False.
    """
    kinds = set(map(type, points))
    if not kinds or not kinds <= {list, tuple} or not set(map(len, points)) <= set(dims):
        return False
    flat = list(chain.from_iterable(points))
    if not set(map(type, flat)) <= {int, float}:
        return False
    try:
        return math.isfinite(math.fsum(flat))
    except (OverflowError, ValueError):
        return False
