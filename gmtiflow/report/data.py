"""Reading a finished run file into the plain tables the report figures take.

Everything the report shows comes from ``run.h5`` (docs/tables.md): the tables, the resolved
``/config`` YAML and the root attributes.  Tables a run did not write (an older layout, a stage
that was off) read as empty dicts, so every figure can say "nothing to show" instead of failing.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, Iterable, Iterator, Tuple

import h5py
import numpy as np

from gmtiflow.errors import StoreError
from gmtiflow.frames import Origin
from gmtiflow.sensor.outcome import Outcome
from gmtiflow.store import open_run, read_attrs, read_column, read_config, read_table
from gmtiflow.tables import Table

TABLES = ("roads/nodes", "roads/edges", "vehicles", "truth", "platform", "dwells", "detections",
          "detection_ancestors", "looks", "tracks", "metrics", "metrics/ospa",
          "metrics/track_errors", "metrics/identity_switches", "metrics/events",
          "metrics/truth_identity", "metrics/association", "metrics/sensors")

# Looks where the beam was on a visible target: the Swerling draw happened.
DRAWN = (Outcome.DETECTED, Outcome.DOPPLER_BLIND, Outcome.PD_MISS, Outcome.MERGED)
DETECTED = (Outcome.DETECTED, Outcome.MERGED)


@dataclass
class RunData:
    path: Path
    attrs: Dict[str, Any]
    config: Dict[str, Any]
    tables: Dict[str, Table] = field(default_factory=dict)

    def table(self, name: str) -> Table:
        return self.tables.get(name, {})

    @property
    def origin(self) -> Origin:
        a = self.attrs
        return Origin(float(a.get("origin_lat_deg", 0.0)), float(a.get("origin_lon_deg", 0.0)),
                      float(a.get("origin_height_m", 0.0)))

    def cfg(self, dotted: str, default=None):
        """A value of the resolved config by dotted key (``sensor.pfa``), or ``default``."""
        node: Any = self.config
        for part in dotted.split("."):
            if not isinstance(node, dict) or part not in node:
                return default
            node = node[part]
        return default if node is None else node


class LazyTable(Mapping):
    """A table of a checked run file whose columns are read when first asked for.

    The report's pages use a third of the columns (truth: 6 of 18), and reading a column means
    decompressing it, so reading all of them up front was a fifth of the report's time on a
    1,000-vehicle run.  Behaves like the table :func:`gmtiflow.store.read_table` returns: the
    column names and the row count are known at once, a missing column raises StoreError, and a
    column that cannot be read (the file changed or was damaged since) raises StoreError.
    """

    def __init__(self, path: Path, name: str, columns: Iterable[str], rows: int) -> None:
        self._path, self._name = path, name
        self._columns = tuple(columns)
        self._data: Dict[str, np.ndarray] = {}
        self.rows = rows
        """Rows of the table (known from the columns' shapes: :func:`n` reads no column)."""

    def __getitem__(self, column: str) -> np.ndarray:
        if column not in self._data:
            if column not in self._columns:
                raise StoreError(f"{self._path}: table /{self._name} has no column {column!r}; "
                                 f"the file is damaged or was written by another program")
            try:
                f = h5py.File(self._path, "r")
            except OSError as exc:
                raise StoreError(f"{self._path}: cannot be read any more ({exc})") from None
            with f:
                self._data[column] = read_column(f, self._name, column)
        return self._data[column]

    def __contains__(self, column: object) -> bool:
        return column in self._columns

    def get(self, column: str, default=None):
        return self[column] if column in self._columns else default

    def __iter__(self) -> Iterator[str]:
        return iter(self._columns)

    def __len__(self) -> int:
        return len(self._columns)


def _lazy_table(f: h5py.File, path: Path, name: str) -> LazyTable:
    """A :class:`LazyTable` of ``name`` after the checks :func:`read_table` makes on read."""
    group = f[name]
    if not isinstance(group, h5py.Group):
        raise StoreError(f"{path}: has no table /{name}")
    columns = {c: ds.shape for c, ds in group.items() if isinstance(ds, h5py.Dataset)}
    if len({s for s in columns.values()}) > 1 or any(len(s) != 1 for s in columns.values()):
        raise StoreError(f"{path}: table /{name} has columns of different lengths or shapes; "
                         f"not a gmtiflow table")
    return LazyTable(path, name, columns, next(iter(columns.values()), (0,))[0])


def load_run(run_path, tables: Iterable[str] = TABLES, *, lazy: bool = False) -> RunData:
    """Read the report's tables (or just ``tables``) from a complete run file (StoreError
    otherwise).  ``lazy``: read each column on first use (:class:`LazyTable`)."""
    path = Path(run_path)
    names = tuple(tables)
    with open_run(path, require_columns=True) as f:
        attrs = read_attrs(f)
        config = read_config(f) if "config" in f else {}    # checked by open_run: parsed once
        tables = {}
        for name in names:
            if name in f:
                tables[name] = _lazy_table(f, path, name) if lazy else read_table(f, name)
    if names and not tables:      # e.g. an HDF5 file that only claims to be a complete run
        raise StoreError(f"{path}: holds none of the tables {', '.join(names)}; not a "
                         f"gmtiflow run file")
    return RunData(path=path, attrs=attrs, config=config or {}, tables=tables)


def n(table: Table) -> int:
    """Rows of a table (0 for an empty or missing one)."""
    if isinstance(table, LazyTable):
        return table.rows
    for col in table.values():
        return len(col)
    return 0


def summary(metrics: Table) -> Dict[str, Tuple[float, str]]:
    """/metrics rows as ``{name: (value, unit)}``."""
    if not n(metrics):
        return {}
    units = metrics.get("unit", np.full(n(metrics), ""))
    return {str(k): (float(v), str(u)) for k, v, u in zip(metrics["name"], metrics["value"], units)}


def key_numbers(run: RunData) -> Dict[str, float]:
    """The counts a reader wants first, shared by the title page and the sweep report.

    ``pd_achieved`` = detected looks (outcome detected or merged) over looks where the Swerling
    draw happened (detected, doppler_blind, pd_miss, merged); ``pd_model_mean`` = the mean model
    P_D of the same looks — the two agree when the detection stage is right.
    """
    det, looks, tracks = run.table("detections"), run.table("looks"), run.table("tracks")
    out: Dict[str, float] = {"detections": float(n(det))}
    if n(det):
        truth_id = np.asarray(det["truth_id"])
        out["false_alarms"] = float(np.sum(truth_id < 0))
        out["merged"] = float(np.sum(np.asarray(det["merged"], bool)))
    else:
        out["false_alarms"] = out["merged"] = 0.0
    if n(looks):
        outcome = np.asarray(looks["outcome"])
        drawn = np.isin(outcome, DRAWN)
        out["looks"] = float(n(looks))
        out["looks_drawn"] = float(drawn.sum())
        if drawn.any():
            out["pd_achieved"] = float(np.isin(outcome[drawn], DETECTED).mean())
            out["pd_model_mean"] = float(np.nanmean(np.asarray(looks["pd"])[drawn]))
        else:
            out["pd_achieved"] = out["pd_model_mean"] = float("nan")
    else:
        out["looks"] = out["looks_drawn"] = 0.0
        out["pd_achieved"] = out["pd_model_mean"] = float("nan")
    out["tracks"] = float(len(np.unique(tracks["track_id"]))) if n(tracks) else 0.0
    if n(tracks) and "confirmed" in tracks:
        ids = np.asarray(tracks["track_id"])[np.asarray(tracks["confirmed"], bool)]
        out["confirmed_tracks"] = float(len(np.unique(ids)))
    else:
        out["confirmed_tracks"] = 0.0
    out["vehicles"] = float(n(run.table("vehicles")))
    out["dwells"] = float(n(run.table("dwells")))
    return out
