"""The run file: one HDF5 file per run (DESIGN §6, docs/tables.md).

Layout: one group per table (``/truth``, ``/platform``, ``/roads/nodes`` ...), one 1-D dataset
per column, chunked and gzip-compressed, with ``units`` (from the column-name suffix) and
``description`` attributes; ``/config`` holds the resolved YAML.  Root attributes:
``layout_version``, ``seed``, ``gmtiflow_version`` and ``complete``.

A run file is written under a temporary name in the same directory and renamed into place only
when :meth:`RunWriter.commit` is called, after ``complete`` is set, so a crash, a kill or an error
never leaves a file that reads as a complete run.  HDF5 object timestamps are off so that the
same config and seed give byte-identical datasets.
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Dict, Mapping, Optional

import h5py
import numpy as np

from gmtiflow import __version__
from gmtiflow.errors import StoreError
from gmtiflow.tables import Table, n_rows, unit_of

LAYOUT_VERSION = 1
"""Bumped whenever a table, column or attribute changes meaning."""

_DAMAGED = (KeyError, OSError, RuntimeError, ValueError, TypeError, UnicodeDecodeError)
"""What h5py raises on a damaged or foreign file's objects (reported as StoreError)."""

_CHUNK_ROWS = 65536
_STR = h5py.string_dtype("utf-8")


def _as_storable(col: np.ndarray) -> np.ndarray:
    col = np.asarray(col)
    if col.dtype.kind in "UO":
        return np.asarray([str(v) for v in col], dtype=object)
    return col


class RunWriter:
    """Writes a run file atomically: ``with RunWriter(path) as w: ...; w.commit()``.

    Leaving the ``with`` block without :meth:`commit` (an exception, an early return) deletes the
    temporary file; nothing appears at ``path``.
    """

    def __init__(self, path: os.PathLike, *, seed: int, attrs: Optional[Mapping] = None):
        self.path = Path(path)
        self.tmp_path = self.path.with_name(f".{self.path.name}.{os.getpid()}.partial")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file = h5py.File(self.tmp_path, "w", track_order=True)
        root = self._file.attrs
        root["layout_version"] = LAYOUT_VERSION
        root["seed"] = int(seed)
        root["gmtiflow_version"] = __version__
        root["complete"] = False
        for key, value in (attrs or {}).items():
            root[key] = value
        self._committed = False

    def __enter__(self) -> "RunWriter":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if not self._committed:
            self.abort()

    def set_attrs(self, attrs: Mapping) -> None:
        """Set root attributes (the scene's origin and epoch, once the scene is built)."""
        for key, value in attrs.items():
            self._file.attrs[key] = value

    def write_text(self, name: str, text: str) -> None:
        """A scalar UTF-8 string dataset (e.g. ``/config``)."""
        self._file.create_dataset(name, data=text, dtype=_STR, track_times=False)

    def write_table(self, name: str, table: Mapping[str, np.ndarray],
                    descriptions: Optional[Dict[str, str]] = None, *,
                    growing: bool = False) -> None:
        """Create group ``name`` with one resizable dataset per column.

        ``growing``: the table will be appended to (streaming), so its HDF5 chunks get the full
        size rather than the size of this first block.
        """
        n_rows(table)
        group = self._file.require_group(name)
        for column, values in table.items():
            data = _as_storable(values)
            kwargs = dict(maxshape=(None,), chunks=(_CHUNK_ROWS,) if len(data) else True,
                          track_times=False)
            if data.dtype.kind != "O":
                kwargs.update(compression="gzip", compression_opts=1, shuffle=True)
            if growing:
                kwargs["chunks"] = (_CHUNK_ROWS,)
            elif len(data) and len(data) < _CHUNK_ROWS:
                kwargs["chunks"] = (len(data),)
            ds = group.create_dataset(column, data=data,
                                      dtype=_STR if data.dtype.kind == "O" else data.dtype,
                                      **kwargs)
            ds.attrs["units"] = unit_of(column)
            if descriptions and column in descriptions:
                ds.attrs["description"] = descriptions[column]

    def append_table(self, name: str, table: Mapping[str, np.ndarray]) -> None:
        """Append rows to an existing table (for time-chunked streaming), or create it."""
        if name not in self._file:
            self.write_table(name, table, growing=True)
            return
        group = self._file[name]
        if set(group.keys()) != set(table.keys()):
            raise ValueError(f"append to /{name}: columns {sorted(table)} differ from "
                             f"{sorted(group.keys())}")
        rows = n_rows(table)
        for column, values in table.items():
            ds = group[column]
            old = ds.shape[0]
            ds.resize((old + rows,))
            ds[old:] = _as_storable(values)

    def commit(self) -> Path:
        """Mark the file complete, close it and rename it into place."""
        self._file.attrs["complete"] = True
        self._file.close()
        os.replace(self.tmp_path, self.path)
        self._committed = True
        return self.path

    def abort(self) -> None:
        """Close and delete the temporary file."""
        try:
            self._file.close()
        finally:
            self.tmp_path.unlink(missing_ok=True)


def open_run(path: os.PathLike) -> h5py.File:
    """Open a complete run file of this layout version for reading, or raise StoreError."""
    path = Path(path)
    if not path.is_file():
        raise StoreError(f"{path}: no such run file")
    try:
        f = h5py.File(path, "r")
    except OSError as exc:
        raise StoreError(f"{path}: not a readable HDF5 file ({exc})") from None
    try:    # a file cut short while being written can open yet fail here (h5py: KeyError)
        version = f.attrs.get("layout_version")
        complete = f.attrs.get("complete", False)
    except _DAMAGED as exc:
        f.close()
        raise StoreError(f"{path}: damaged HDF5 file, not a complete run ({exc})") from None
    if version is None:
        f.close()
        raise StoreError(f"{path}: an HDF5 file but not a gmtiflow run file (no layout_version "
                         f"attribute)")
    if version != LAYOUT_VERSION:
        f.close()
        raise StoreError(f"{path}: layout_version {version}, this gmtiflow reads "
                         f"{LAYOUT_VERSION}")
    if not (isinstance(complete, (bool, np.bool_)) and bool(complete)):
        f.close()
        raise StoreError(f"{path}: the run is incomplete (it was interrupted while writing)")
    return f


def read_attrs(f: h5py.File) -> dict:
    """The root attributes of an open run file as plain Python values (StoreError if damaged)."""
    try:
        return {k: (v.item() if isinstance(v, np.generic) else v) for k, v in f.attrs.items()}
    except _DAMAGED as exc:
        raise StoreError(f"{f.filename}: root attributes cannot be read, the file is damaged "
                         f"({exc})") from None


def read_table(source, name: str) -> Table:
    """Read table ``name`` from an open run file or a path."""
    if isinstance(source, h5py.File):
        return _read_group(source, name)
    with open_run(source) as f:
        return _read_group(f, name)


def _read_group(f: h5py.File, name: str) -> Table:
    try:
        if name not in f or not isinstance(f[name], h5py.Group):
            raise StoreError(f"{f.filename}: has no table /{name}")
        out = {}
        for column, ds in f[name].items():
            if not isinstance(ds, h5py.Dataset):
                continue
            data = ds[()]
            if h5py.check_string_dtype(ds.dtype) is not None:
                data = np.asarray([v.decode("utf-8") if isinstance(v, bytes) else v
                                   for v in data], dtype=str)
            out[column] = data
    except _DAMAGED as exc:
        raise StoreError(f"{f.filename}: table /{name} cannot be read, the file is damaged "
                         f"({exc})") from None
    lengths = {len(v) for v in out.values() if np.ndim(v) == 1}
    if len(lengths) > 1 or any(np.ndim(v) != 1 for v in out.values()):
        raise StoreError(f"{f.filename}: table /{name} has columns of different lengths or "
                         f"shapes; not a gmtiflow table")
    return out


def read_text(source, name: str) -> str:
    """Read a scalar string dataset such as ``/config``."""
    def get(f: h5py.File) -> str:
        try:
            value = f[name][()]
            return value.decode("utf-8") if isinstance(value, bytes) else str(value)
        except _DAMAGED as exc:
            raise StoreError(f"{f.filename}: /{name} cannot be read ({exc})") from None
    if isinstance(source, h5py.File):
        return get(source)
    with open_run(source) as f:
        return get(f)
