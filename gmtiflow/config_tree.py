"""Walking a validated config tree by key path (dataclasses, lists and dicts).

Key paths are the dotted names a user writes on the command line, with list items as ``[i]``:
``clutter.regions[0].radius_m``.  Used by the config audits (tests/reliability) and
``benchmarks/config_extremes.py`` to reach every numeric leaf without a hand-kept list.
"""
from __future__ import annotations

import dataclasses
import re
from typing import Iterator, Tuple

_PART = re.compile(r"[^.\[\]]+|\[\d+\]")


def numeric_leaves(obj, prefix: str = "") -> Iterator[Tuple[str, object]]:
    """(key path, value) of every int/float leaf (bools excluded) of a config tree."""
    if dataclasses.is_dataclass(obj):
        for f in dataclasses.fields(obj):
            yield from numeric_leaves(getattr(obj, f.name), f"{prefix}{f.name}.")
    elif isinstance(obj, (list, tuple)):
        for i, item in enumerate(obj):
            yield from numeric_leaves(item, f"{prefix[:-1]}[{i}].")
    elif isinstance(obj, dict):
        for key, item in obj.items():
            yield from numeric_leaves(item, f"{prefix}{key}.")
    elif isinstance(obj, (int, float)) and not isinstance(obj, bool):
        yield prefix[:-1], obj


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
