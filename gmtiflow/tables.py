"""Tables: the one data interface between stages (DESIGN §1).

A table is a ``dict[str, numpy.ndarray]`` of equal-length 1-D columns.  Column names carry their
unit as a suffix where it is not obvious (``range_m``, ``snr_db``); :func:`unit_of` reads it back
so the store can write units as attributes without a second registry to keep in step.
The column sets of each table are listed in ``docs/tables.md``.
"""
from __future__ import annotations

from functools import lru_cache
from typing import Dict, Mapping

import numpy as np

Table = Dict[str, np.ndarray]

# Suffix -> unit string (longest suffixes first so "_mps2" wins over "_mps").
_UNIT_SUFFIXES = (
    ("_mps2", "m/s^2"), ("_mps", "m/s"), ("_dbsm", "dBsm"), ("_db", "dB"), ("_deg", "deg"),
    ("_rad", "rad"), ("_km2", "km^2"), ("_m2", "m^2"), ("_m", "m"), ("_s", "s"), ("_hz", "Hz"),
    ("_w", "W"), ("_k", "K"),
)


@lru_cache(maxsize=4096)
def unit_of(column: str) -> str:
    """Unit of a column from its name suffix ('' when dimensionless or an id/flag); remembered
    per name (the store asks once per column written or checked)."""
    for suffix, unit in _UNIT_SUFFIXES:
        if column.endswith(suffix):
            return unit
    return ""


def n_rows(table: Mapping[str, np.ndarray]) -> int:
    """Number of rows; raises ValueError if the columns disagree."""
    lengths = {name: len(col) for name, col in table.items()}
    if not lengths:
        return 0
    distinct = set(lengths.values())
    if len(distinct) != 1:
        raise ValueError(f"table columns have different lengths: {lengths}")
    return distinct.pop()


def take(table: Mapping[str, np.ndarray], index) -> Table:
    """Rows selected by a boolean mask or an integer index array."""
    return {name: col[index] for name, col in table.items()}


def concat(tables, columns=None) -> Table:
    """Row-wise concatenation of tables with the same columns."""
    tables = [t for t in tables if t is not None]
    if not tables:
        return {}
    names = list(columns or tables[0].keys())
    return {name: np.concatenate([t[name] for t in tables]) for name in names}


def empty_like(table: Mapping[str, np.ndarray]) -> Table:
    """A zero-row table with the same columns and dtypes."""
    return {name: col[:0].copy() for name, col in table.items()}
