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


def all_positive(values: List[Any]) -> bool:
    """:func:`positive` finds no problem in any of ``values`` (a field's values across a long
    list of specs), checked at once; False also where the bulk check cannot tell
    (:func:`finite_min`): then check them one by one."""
    least = finite_min(values, skip_none=True)
    return least is not None and least > 0


def all_non_negative(values: List[Any]) -> bool:
    """:func:`non_negative` finds no problem in any of ``values``: as :func:`all_positive`."""
    least = finite_min(values, skip_none=True)
    return least is not None and least >= 0


def finite_min(values: List[Any], skip_none: bool = False) -> Optional[float]:
    """The least of ``values`` (its Nones left out if ``skip_none``; +inf for no values) when
    every one is a finite int or float (:func:`_finite_sum`: a few C calls for a long list),
    None otherwise, for a bool or a subclass (numpy's floats) too, and where the sum cannot
    tell: None means "check them one by one", not "a problem"."""
    kinds = set(map(type, values))
    if skip_none and _NONE in kinds:
        values = [v for v in values if v is not None]
        kinds.discard(_NONE)
    if not values:
        return math.inf
    if not kinds <= _PLAIN_NUMBERS or not _finite_sum(values, kinds):
        return None
    return min(values)


def _finite_sum(values: List[Any], kinds: set) -> bool:
    """The sum of ``values`` (ints and floats, of types ``kinds``) is finite, which holds only
    if every value is.  Floats alone by ``sum`` (a NaN or an infinity makes it NaN or
    infinite; finite floats that overflow give False, a needless "no"); with ints by
    ``math.fsum``, exact (an int too large for a float raises: False, where ``sum`` of ints
    could cancel it out)."""
    try:
        return math.isfinite(sum(values) if kinds == _FLOAT else math.fsum(values))
    except (OverflowError, ValueError):
        return False


_NONE = type(None)
_PLAIN_NUMBERS = frozenset({int, float})
_FLOAT = {float}


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
    if finite_rows(points, dims):
        return []
    return [problem for i, point in enumerate(points)
            for problem in point_problems(f"{key}[{i}]", point, dims, what, geodetic)]


def finite_rows(points: Any, dims) -> bool:
    """``points`` is a list of lists (or tuples) of ``dims`` finite ints and floats.

    Their sum is finite (:func:`_finite_sum`; False, and the points are checked one by one,
    where it cannot tell).
    """
    kinds = set(map(type, points))
    if not kinds or not kinds <= {list, tuple} or not set(map(len, points)) <= set(dims):
        return False
    flat = list(chain.from_iterable(points))
    kinds = set(map(type, flat))
    return kinds <= _PLAIN_NUMBERS and _finite_sum(flat, kinds)
