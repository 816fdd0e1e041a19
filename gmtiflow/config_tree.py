"""Walking a validated config tree by key path (dataclasses, lists and dicts).

Key paths are the dotted names a user writes on the command line, with list items as ``[i]``:
``clutter.regions[0].radius_m``.  Used by the config audits (tests/reliability) and
``benchmarks/config_extremes.py`` to reach every numeric leaf without a hand-kept list.
"""
from __future__ import annotations

import dataclasses
import operator
import re
from itertools import chain
from typing import Callable, Dict, Iterator, List, Optional, Set, Tuple

_PART = re.compile(r"[^.\[\]]+|\[\d+\]")


def numeric_leaves(obj, prefix: str = "", bound: Optional[float] = None
                   ) -> Iterator[Tuple[str, object]]:
    """(key path, value) of every int/float leaf (bools excluded) of a config tree.

    With ``bound``, leaves known to lie within ±``bound`` may be left out: a list of numbers
    (or of lists of numbers, such as waypoints) whose numbers all lie within it, NaNs aside, is
    checked in bulk and skipped (its NaNs with it), as is an int/float field within it.  Every
    other leaf, every one beyond ±``bound`` among them, is still yielded, in the same order.
    """
    if dataclasses.is_dataclass(obj):
        for name, value in zip(field_names(obj), field_values(obj)):
            kind = type(value)
            if kind is int or kind is float:         # a scalar field, without a call
                if bound is None or not -bound <= value <= bound:
                    yield f"{prefix}{name}", value
            elif kind not in _NOT_NUMERIC and not is_empty(value):
                yield from numeric_leaves(value, f"{prefix}{name}.", bound)
    elif isinstance(obj, (list, tuple)):
        if bound is not None and (numbers_within(obj, bound) or records_within(obj, bound)):
            return
        for i, item in enumerate(obj):
            yield from numeric_leaves(item, f"{prefix[:-1]}[{i}].", bound)
    elif isinstance(obj, dict):
        for key, item in obj.items():
            yield from numeric_leaves(item, f"{prefix}{key}.", bound)
    elif isinstance(obj, (int, float)) and not isinstance(obj, bool):
        yield prefix[:-1], obj


_NOT_NUMERIC = frozenset({str, bool, type(None)})
_NUMBERS = frozenset({int, float})
SCALARS = frozenset({int, float, bool, str, type(None)})
"""The exact types of plain leaves: none of them is a container or a dataclass."""

_FIELD_NAMES: Dict[type, Tuple[str, ...]] = {}
_FIELD_GETTERS: Dict[type, Callable[[object], tuple]] = {}


def field_names(obj) -> Tuple[str, ...]:
    """The names of ``dataclasses.fields(obj)`` in order (cached per class)."""
    cls = obj if isinstance(obj, type) else type(obj)
    names = _FIELD_NAMES.get(cls)
    if names is None:
        names = _FIELD_NAMES[cls] = tuple(f.name for f in dataclasses.fields(cls))
    return names


def field_values(obj) -> tuple:
    """The values of those fields, in one call (``operator.attrgetter``)."""
    cls = obj if isinstance(obj, type) else type(obj)
    getter = _FIELD_GETTERS.get(cls)
    if getter is None:
        names = field_names(obj)
        if len(names) == 1:
            getter = lambda o, name=names[0]: (getattr(o, name),)    # noqa: E731
        else:
            getter = operator.attrgetter(*names) if names else (lambda o: ())
        _FIELD_GETTERS[cls] = getter
    return getter(obj)


def is_empty(value) -> bool:
    """An empty list, tuple or dict: no leaves and nothing to check below it."""
    return type(value) in (list, tuple, dict) and not value


def flat_items(items) -> Tuple[list, Set[type]]:
    """The items of a list and their exact types, a list of lists (or tuples) flattened one
    level first: bulk checks of scalar lists and waypoint lists without a call per item."""
    kinds = set(map(type, items))
    if kinds and kinds <= {list, tuple}:
        items = list(chain.from_iterable(items))
        kinds = set(map(type, items))
    return items, kinds


def holds_only_scalars(items) -> bool:
    """The list (or list of lists) holds plain scalars only: no dataclass or dict inside."""
    return flat_items(items)[1] <= SCALARS


def numbers_within(items, bound: float) -> bool:
    """Every item of the list (or list of lists) is an int, float or bool within ±``bound``.

    ``min`` and ``max`` skip NaNs after the first item and return NaN when it is the first
    (then the comparison fails): a True answer is never wrong about a number beyond ``bound``.
    """
    flat, kinds = flat_items(items)
    if not kinds <= {int, float, bool}:
        return False
    return not flat or (-bound <= min(flat) and max(flat) <= bound)


def record_columns(items) -> Optional[List[Tuple[str, tuple]]]:
    """``(field name, its values across the list)`` of two or more dataclasses of one class (a
    vehicle list: walked column by column, not item by item), or None for any other list."""
    if len(items) < 2:
        return None
    cls = type(items[0])
    if not dataclasses.is_dataclass(cls) or set(map(type, items)) != {cls}:
        return None
    return list(zip(field_names(cls), zip(*map(field_values, items))))


def records_within(items, bound: float) -> bool:
    """Every numeric leaf of two or more dataclasses of one class lies within ±``bound`` (NaNs
    aside, as in :func:`numbers_within`), checked field by field across the list (a long
    vehicle list), not item by item: fields that hold plain scalars, lists of them (or of
    number lists) or dataclasses of one class for which the same holds.  False otherwise."""
    columns = record_columns(items)
    if columns is None:
        return False
    for _, column in columns:
        kinds = set(map(type, column))
        if kinds <= _NOT_NUMERIC:
            continue
        if kinds <= SCALARS:
            numbers = column if kinds <= _NUMBERS else [
                v for v in column if type(v) is int or type(v) is float]
            if not (-bound <= min(numbers) and max(numbers) <= bound):
                return False
        elif kinds <= {list, tuple}:
            if not numbers_within(list(chain.from_iterable(column)), bound):
                return False
        elif len(kinds) != 1 or not records_within(column, bound):
            return False
    return True


def child(obj, part: str):
    """One step down: ``[i]`` indexes a list, a name reads a dict key or an attribute."""
    if part.startswith("["):
        return obj[int(part[1:-1])]
    return obj[part] if isinstance(obj, dict) else getattr(obj, part)


def get_path(obj, path: str):
    """The node at ``path`` (``""`` is the tree itself)."""
    for part in _PART.findall(path):
        obj = child(obj, part)
    return obj


def set_leaf(obj, path: str, value) -> None:
    """Set the leaf at ``path`` in place (frozen dataclasses too)."""
    parts = _PART.findall(path)
    for part in parts[:-1]:
        obj = child(obj, part)
    last = parts[-1]
    if last.startswith("["):
        obj[int(last[1:-1])] = value
    elif isinstance(obj, dict):
        obj[last] = value
    else:
        object.__setattr__(obj, last, value)


def unknown_keys(obj, prefix: str = "") -> Iterator[Tuple[str, Tuple[str, ...]]]:
    """(key path, the field names of its dataclass) of every attribute of a dataclass in the
    tree that is not one of its fields.

    ``OmegaConf.to_object`` sets a key that a structured node does not declare as a plain
    attribute of the dataclass it builds: a key added with ``+`` (``+sensor.pfaa=1e-6``, which
    Hydra itself suggests for a misspelt key) that nothing reads.  Dicts (``tracker.params``,
    ``vehicles.random.types``, ``sensors``) take any key and are only walked into."""
    if dataclasses.is_dataclass(obj):
        names = field_names(obj)
        attrs = getattr(obj, "__dict__", None)
        if attrs is not None and len(attrs) != len(names):
            for name in attrs:
                if name not in names:
                    yield f"{prefix}{name}", names
        for name, value in zip(names, field_values(obj)):
            if type(value) not in SCALARS and not is_empty(value):
                yield from unknown_keys(value, f"{prefix}{name}.")
    elif isinstance(obj, (list, tuple)):
        if holds_only_scalars(obj):
            return
        for i, item in enumerate(obj):
            yield from unknown_keys(item, f"{prefix[:-1]}[{i}].")
    elif isinstance(obj, dict):
        for key, item in obj.items():
            if type(item) not in SCALARS:
                yield from unknown_keys(item, f"{prefix}{key}.")
