"""The run file: one HDF5 file per run (DESIGN §6, docs/tables.md).

Layout: one group per table (``/truth``, ``/platform``, ``/roads/nodes`` ...), one 1-D dataset
per column, chunked and gzip-compressed, with ``units`` (from the column-name suffix) and
``description`` attributes; ``/config`` holds the resolved YAML.  Root attributes:
``layout_version``, ``seed``, ``gmtiflow_version`` and ``complete``.

Reading (:func:`open_run`) trusts nothing in the file: before a consumer sees it, the file must
hold only groups and 1-D datasets stored inside it (no external or soft links, virtual datasets
or external storage), no column may claim more rows than its stored bytes can hold or than the
machine's memory, the root attributes must have their types and ranges, ``/config`` must be a
resolved YAML mapping (no ``${...}`` interpolation, which OmegaConf would evaluate), columns with
a unit or an ``_id`` are numeric, and a missing column raises StoreError when it is asked for.
Every failure is a :class:`~gmtiflow.errors.StoreError` naming the file and the object; no
message echoes the file's content.

A run file is written under a temporary name in the same directory and renamed into place only
when :meth:`RunWriter.commit` is called, after ``complete`` is set, so a crash, a kill or an error
never leaves a file that reads as a complete run.  HDF5 object timestamps are off so that the
same config and seed give byte-identical datasets.

Writing speed: every numeric column is compressed by
:class:`~gmtiflow.chunk_codec.ChunkDeflater`, which applies the datasets' own filters (shuffle,
then deflate; byte planes that are noise go into the deflate stream as stored blocks) on the
calling thread for a run's first :data:`~gmtiflow.chunk_codec.INLINE_RUN_BYTES`, then in worker
threads while the simulation goes on, and writes the finished chunks in order with HDF5's
direct chunk write (:mod:`gmtiflow.chunk_codec`).  The datasets and their attributes are made with
h5py's low-level API from property lists built once, a table's before its chunks are
written.  The file is the same standard gzip + shuffle HDF5 file, with the same values,
readable by any HDF5 reader.
"""
from __future__ import annotations

import functools
import hashlib
import math
import os
import re
import weakref
from pathlib import Path
from typing import Any, Dict, List, Mapping, Optional

import h5py
import numpy as np
import yaml
from h5py import h5a, h5d, h5g, h5p, h5s, h5t

from gmtiflow import __version__
from gmtiflow.chunk_codec import DEFLATE_LEVEL, INLINE_RUN_BYTES, ChunkDeflater
from gmtiflow.errors import StoreError
from gmtiflow.resources import available_memory_bytes, human_bytes
from gmtiflow.tables import Table, n_rows, unit_of

LAYOUT_VERSION = 1
"""Bumped whenever a table, column or attribute changes meaning."""

_DAMAGED = (KeyError, OSError, RuntimeError, ValueError, TypeError, UnicodeDecodeError)
"""What h5py raises on a damaged or foreign file's objects (reported as StoreError)."""

MAX_OBJECTS = 20_000
"""A run file holds a few hundred objects; more is refused before walking them all."""

MAX_EXPANSION = 1100
"""Deflate cannot expand stored bytes more than ~1032-fold: a column claiming more bytes than
this many times what it stores holds unwritten (fill-value) chunks, a 'decompression bomb'."""

TEXT_COLUMNS = {"roads/nodes": {"name"}, "roads/edges": {"road_class"},
                "vehicles": {"name", "vehicle_type"}, "metrics": {"name", "unit"},
                "metrics/events": {"kind"}}
"""The string columns gmtiflow writes into its known tables; any other column of these tables,
and any column with a unit suffix in any table, must be numeric or boolean."""

_KNOWN_TABLES = {"dwells", "detections", "looks", "tracks", "truth", "platform", "vehicles",
                 "roads/nodes", "roads/edges", "detection_ancestors", "metrics/events"}

_PLATFORM_COLUMNS = ("time_s", "x_m", "y_m", "z_m", "vx_mps", "vy_mps", "vz_mps", "lat_deg",
                     "lon_deg", "height_m", "heading_rad")
_VEHICLE_COLUMNS = ("vehicle_id", "vehicle_type", "convoy_id")


def required_columns() -> Dict[str, tuple]:
    """Columns every simulation run file of this layout has, per table: read off the writers'
    own column lists (imported lazily: the store sits below the stages)."""
    from gmtiflow.evaluate.events import EVENT_COLUMNS
    from gmtiflow.evaluate.tracks import REQUIRED_TRACK_COLUMNS
    from gmtiflow.formats.geojson import EDGE_COLUMNS, NODE_COLUMNS
    from gmtiflow.scene.fleet import TRUTH_COLUMNS
    from gmtiflow.sensor.columns import DETECTION_COLUMNS, DWELL_COLUMNS, LOOK_COLUMNS
    return {"dwells": tuple(DWELL_COLUMNS), "detections": tuple(DETECTION_COLUMNS),
            "looks": tuple(LOOK_COLUMNS), "tracks": REQUIRED_TRACK_COLUMNS,
            "truth": tuple(TRUTH_COLUMNS), "metrics/events": tuple(EVENT_COLUMNS),
            "roads/nodes": tuple(NODE_COLUMNS), "roads/edges": tuple(EDGE_COLUMNS),
            "platform": _PLATFORM_COLUMNS, "vehicles": _VEHICLE_COLUMNS,
            "detection_ancestors": ("det_id", "truth_id")}


_CHUNK_ROWS = 65536
_STR = h5py.string_dtype("utf-8")
# The run file's objects are made with h5py's low-level API: ``Group.create_dataset``,
# ``require_group`` and ``attrs[...] =`` rebuild the same property lists, types and dataspaces
# for every object (~0.2 ms a dataset, most of a small run's file cost; ~40 µs a group or a
# root attribute).  These are built once; the objects they make are the ones the high-level
# calls made (same types, shapes, filters, chunks; the same file, byte for byte).
_SCALAR_SPACE = h5s.create_simple(())
_STR_TYPE = h5t.py_create(_STR, logical=True)
_STR_MEMORY_TYPE = h5t.py_create(_STR)       # Python str objects, converted to _STR_TYPE
_FILE_TYPES: Dict[np.dtype, Any] = {}
_MEMORY_TYPES: Dict[np.dtype, Any] = {}
_DCPLS: Dict[tuple, Any] = {}
_GCPL = h5p.create(h5p.GROUP_CREATE)         # h5py's create_group: no timestamps
_GCPL.set_obj_track_times(False)
_LCPL = h5p.create(h5p.LINK_CREATE)          # h5py's: intermediate groups made, ASCII names
_LCPL.set_create_intermediate_group(True)
_LCPL.set_char_encoding(h5t.CSET_ASCII)
_TEXT_DCPL = h5p.create(h5p.DATASET_CREATE)  # h5py's create_dataset of a scalar: no
_TEXT_DCPL.set_obj_track_times(False)        # timestamps, attribute order not tracked
_TEXT_DCPL.set_attr_creation_order(0)
_CHUNK_CACHE_SLOTS = 1
"""Slots of the chunk cache of each dataset the writer makes (the file's access property):
numeric columns are written whole-chunk by direct chunk writes, which bypass the cache, and a
text column's chunks once each, so HDF5 2.0's default of 8,191 slots only cost a 64 KB table
zeroed for every column created.  The cache's size is left as it is: the same HDF5 calls in
the same order, the same file byte for byte.  The 10-target, 1-scan peer run's writer calls
replayed, alternated in one process (300 pairs, 03:08 UTC, load 5): 6.90 -> 6.57 ms CPU."""
_PLAIN_PATH = re.compile(r"[A-Za-z0-9_.-]+(/[A-Za-z0-9_.-]+)*")
"""Group paths :func:`_new_group` makes itself (ASCII, relative, no empty or odd parts)."""


def _file_type(dtype: np.dtype):
    """The HDF5 type h5py gives a dataset of ``dtype`` (bool: its enum; text: UTF-8 strings)."""
    if dtype.kind == "O":         # numpy's dtype equality ignores h5py's string metadata
        return _STR_TYPE
    tid = _FILE_TYPES.get(dtype)
    if tid is None:
        tid = _FILE_TYPES[dtype] = h5t.py_create(dtype, logical=True)
    return tid


def _dcpl(chunk_rows: int, compressed: bool):
    """Creation properties of a resizable column: chunks of ``chunk_rows``; shuffle + deflate
    when ``compressed``; no timestamps."""
    key = (chunk_rows, compressed)
    plist = _DCPLS.get(key)
    if plist is None:
        plist = h5p.create(h5p.DATASET_CREATE)
        plist.set_chunk((chunk_rows,))
        if compressed:
            plist.set_shuffle()
            plist.set_deflate(DEFLATE_LEVEL)
        plist.set_obj_track_times(False)
        plist.set_attr_creation_order(0)
        _DCPLS[key] = plist
    return plist


@functools.lru_cache(maxsize=None)
def _auto_chunk_rows(itemsize: int) -> int:
    """The chunk h5py picks for an empty resizable column (``chunks=True``)."""
    try:
        from h5py._hl.filters import guess_chunk
        return int(guess_chunk((0,), (None,), itemsize)[0])
    except (ImportError, TypeError, ValueError, IndexError):
        return 1024


def _new_group(file: h5py.File, name: str) -> tuple:
    """``(group id, absolute path)`` of group ``name`` (a path relative to the root, missing
    groups on the way made too), as ``file.require_group(name)`` gives it; made with the
    property lists h5py's ``create_group`` would build (:data:`_GCPL`, :data:`_LCPL`).  A
    path that exists already, or an unusual one, is left to h5py."""
    if _PLAIN_PATH.fullmatch(name):
        links = file.id.links
        parts = name.split("/")
        prefixes = ["/".join(parts[:i + 1]).encode() for i in range(len(parts))]
        exists = True
        for prefix in prefixes:         # a missing link on the way: the path is new
            exists = links.exists(prefix)
            if not exists:
                break
        if not exists:
            return h5g.create(file.id, prefixes[-1], lcpl=_LCPL, gcpl=_GCPL), "/" + name
    group = file.require_group(name)
    return group.id, group.name


def _set_root_attr(file: h5py.File, name: str, value) -> None:
    """Root attribute ``name`` = ``value``, replacing any of that name, as ``file.attrs[name] =
    value`` sets it (the same HDF5 calls: delete, create, write); a bool, int, float or str
    with the types built once (:func:`_file_type`), anything else through h5py."""
    cls = type(value)
    if cls not in (bool, int, float, str) or cls is int and not -2**63 <= value < 2**63:
        file.attrs[name] = value
        return
    data = np.array(value, dtype=_STR) if cls is str else np.asarray(value)
    mtype = _STR_MEMORY_TYPE if cls is str else _MEMORY_TYPES.get(data.dtype)
    if mtype is None:
        mtype = _MEMORY_TYPES[data.dtype] = h5t.py_create(data.dtype)
    key = name.encode()
    if h5a.exists(file.id, key):
        h5a.delete(file.id, key)
    attr = h5a.create(file.id, key, _file_type(data.dtype), _SCALAR_SPACE)
    try:
        attr.write(data, mtype=mtype)
    except BaseException:       # (text that is not UTF-8): no empty attribute left, as h5py
        attr.close()
        h5a.delete(file.id, key)
        raise
    attr.close()


_TEXT_VALUES: Dict[str, np.ndarray] = {}
"""The arrays :func:`_set_text_attr` writes, by text: a run's 137 columns have a dozen distinct
units, each array made once (read-only: HDF5 converts from it)."""


def _text_value(value: str) -> np.ndarray:
    """``value`` as the scalar array of Python strings h5py writes a text attribute from."""
    data = _TEXT_VALUES.get(value)
    if data is None:
        if len(_TEXT_VALUES) >= 1024:       # (descriptions: any text; units: a few)
            _TEXT_VALUES.clear()
        data = _TEXT_VALUES[value] = np.array(value, dtype=_STR)
        data.flags.writeable = False
    return data


def _set_text_attr(oid, name: bytes, value: str) -> None:
    """Attribute ``name`` = ``value``, a scalar UTF-8 string (as ``attrs[name] = value``), of an
    object that has none of that name (a column just created)."""
    attr = h5a.create(oid, name, _STR_TYPE, _SCALAR_SPACE)
    try:
        attr.write(_text_value(value), mtype=_STR_MEMORY_TYPE)
    finally:
        attr.close()


def _joined(parts: list, column: str) -> np.ndarray:
    """Column ``column`` of the rows of ``parts`` (tables) in order."""
    if len(parts) == 1:
        return parts[0][column]
    return np.concatenate([p[column] for p in parts])


def _column_pieces(parts: list, column: str) -> Optional[list]:
    """Column ``column`` of each of ``parts`` (tables), as arrays of one dtype (the dtype
    their join would have), for the deflater to join as it shuffles; None for a text
    column."""
    if len(parts) == 1:                 # (a table written at once: one piece)
        col = np.asarray(parts[0][column])
        return None if col.dtype.kind in "UO" else [col]
    pieces = [np.asarray(p[column]) for p in parts]
    if any(p.dtype.kind in "UO" for p in pieces):
        return None
    dtype = np.result_type(*pieces) if len(pieces) > 1 else pieces[0].dtype
    return [p.astype(dtype, copy=False) for p in pieces]


def _as_storable(col: np.ndarray) -> np.ndarray:
    col = np.asarray(col)
    if col.dtype.kind in "UO":
        return np.asarray([str(v) for v in col], dtype=object)
    return col


MIN_FREE_BYTES = 16 * 2**20
"""Free space the run file's disk must keep beyond each block written (HDF5 metadata, close)."""


def free_bytes(directory: os.PathLike) -> Optional[int]:
    """Bytes available to this user on the file system of ``directory`` (None if unknown)."""
    try:
        st = os.statvfs(directory)
    except (OSError, AttributeError):
        return None
    return int(st.f_bavail) * int(st.f_frsize)


class RunWriter:
    """Writes a run file atomically: ``with RunWriter(path) as w: ...; w.commit()``.

    Leaving the ``with`` block without :meth:`commit` (an exception, an early return) deletes the
    temporary file; nothing appears at ``path``.

    A full disk: HDF5 buffers its writes and, on ``ENOSPC``, prints errors from object
    destructors and can crash the process.  So before each block the writer checks that the
    disk keeps :data:`MIN_FREE_BYTES` beyond twice the block, and otherwise raises StoreError
    (the temporary is deleted; one clear message instead of a segfault).

    ``deflate_workers``: threads compressing the columns (0: none, all on the calling thread);
    by default up to 4, started only after the run's first :data:`INLINE_RUN_BYTES` of columns.
    The file is the same whatever the threads.
    """

    def __init__(self, path: os.PathLike, *, seed: int, attrs: Optional[Mapping] = None,
                 deflate_workers: Optional[int] = None):
        self.path = Path(path)
        self.tmp_path = self.path.with_name(f".{self.path.name}.{os.getpid()}.partial")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._check_space(0)
        self._committed = False
        inline = 0
        if deflate_workers is None:     # threads only once the run is big enough to repay them
            deflate_workers, inline = min(4, os.cpu_count() or 1), INLINE_RUN_BYTES
        self._deflater = ChunkDeflater(deflate_workers, inline_bytes=inline)
        try:
            self._file = h5py.File(self.tmp_path, "w", track_order=True,
                                   rdcc_nslots=_CHUNK_CACHE_SLOTS)
            self.set_attrs({"layout_version": LAYOUT_VERSION, "seed": int(seed),
                            "gmtiflow_version": __version__, "complete": False})
            self.set_attrs(attrs or {})
        except BaseException:       # Ctrl-C or a bad attribute before ``with`` took over
            self._deflater.close()
            if getattr(self, "_file", None) is not None:
                self._file.close()
            self.tmp_path.unlink(missing_ok=True)
            raise

    def __enter__(self) -> "RunWriter":
        return self

    def _check_space(self, n_bytes: int) -> None:
        free = free_bytes(self.path.parent)
        if free is not None and free < MIN_FREE_BYTES + 2 * n_bytes:
            raise StoreError(f"{self.path}: the disk is full ({human_bytes(free)} free in "
                             f"{self.path.parent}; writing the run file needs at least "
                             f"{human_bytes(MIN_FREE_BYTES + 2 * n_bytes)}); free space or "
                             f"choose another run directory")

    def __exit__(self, exc_type, exc, tb) -> None:
        if not self._committed:
            self.abort()

    def set_attrs(self, attrs: Mapping) -> None:
        """Set root attributes (the scene's origin and epoch, once the scene is built)."""
        for key, value in attrs.items():
            _set_root_attr(self._file, key, value)

    def _parts(self, table) -> tuple:
        """``(parts, rows)``: ``table`` as a non-empty list of tables with the same columns
        (each checked with n_rows), and their rows in all, after checking the disk has room
        for them."""
        parts = (table or [{}]) if isinstance(table, list) else [table]
        rows = sum(n_rows(p) for p in parts)
        self._check_space(sum(np.asarray(v).nbytes for p in parts for v in p.values()))
        return parts, rows

    def write_text(self, name: str, text: str) -> None:
        """A scalar UTF-8 string dataset (e.g. ``/config``), as ``create_dataset(name,
        data=text, dtype=_STR, track_times=False)`` makes it, from the property list and types
        built once (:data:`_TEXT_DCPL`); a path with groups in it is left to h5py."""
        if "/" in name or not _PLAIN_PATH.fullmatch(name):
            self._file.create_dataset(name, data=text, dtype=_STR, track_times=False)
            return
        dsid = h5d.create(self._file.id, name.encode(), _STR_TYPE, _SCALAR_SPACE,
                          dcpl=_TEXT_DCPL)
        dsid.write(h5s.ALL, h5s.ALL, np.array(text, dtype=_STR), mtype=_STR_MEMORY_TYPE)

    def write_table(self, name: str, table: "Mapping[str, np.ndarray] | List[Table]",
                    descriptions: Optional[Dict[str, str]] = None, *,
                    growing: bool = False) -> None:
        """Create group ``name`` with one resizable dataset per column.

        ``table``: a table, or a list of tables with the same columns (the table of their rows
        in order: each column is joined just before it is compressed, so the joined table is
        never made whole).  ``growing``: the table will be appended to (streaming), so its
        HDF5 chunks get the full size rather than the size of this first block.
        """
        parts, n = self._parts(table)
        gid, path = _new_group(self._file, name)
        prefix = path.rstrip("/") + "/"
        space = h5s.create_simple((n,), (h5s.UNLIMITED,))     # every column's: n rows
        numeric = []                    # deflated together once every column is made
        for column in parts[0]:
            pieces = _column_pieces(parts, column)
            text = pieces is None
            data = _as_storable(_joined(parts, column)) if text else None
            dtype = _STR if text else pieces[0].dtype
            if growing or n >= _CHUNK_ROWS:
                chunk_rows = _CHUNK_ROWS
            elif n:
                chunk_rows = n
            else:
                chunk_rows = _auto_chunk_rows(dtype.itemsize)
            dsid = h5d.create(gid, column.encode(), _file_type(dtype), space,
                              dcpl=_dcpl(chunk_rows, not text))
            # attributes first: added to an object whose data is already written they cost
            # HDF5 ~20 % more
            _set_text_attr(dsid, b"units", unit_of(column))
            if descriptions and column in descriptions:
                _set_text_attr(dsid, b"description", descriptions[column])
            if n and not text:      # compressed by the deflater (threads), written when ready
                numeric.append((prefix + column, dsid, chunk_rows, 0, pieces))
            elif n:
                dsid.write(h5s.ALL, h5s.ALL, np.asarray(data, dtype=_STR))
        self._deflater.add_many(numeric)

    def append_table(self, name: str, table: "Mapping[str, np.ndarray] | List[Table]") -> None:
        """Append rows to an existing table (for time-chunked streaming), or create it;
        ``table`` as in :meth:`write_table`."""
        if name not in self._file:
            self.write_table(name, table, growing=True)
            return
        group = self._file[name]
        columns = table[0] if isinstance(table, list) else table
        if set(group.keys()) != set(columns.keys()):
            raise ValueError(f"append to /{name}: columns {sorted(columns)} differ from "
                             f"{sorted(group.keys())}")
        parts, rows = self._parts(table)
        numeric = []                    # deflated together once every column is resized
        for column in parts[0]:
            ds = group[column]
            old = ds.shape[0]
            ds.resize((old + rows,))
            if ds.compression == "gzip" and ds.chunks is not None and old % ds.chunks[0] == 0 \
                    or ds.name in self._deflater.tails:
                numeric.append((ds.name, ds.id, ds.chunks[0], old,
                                [np.asarray(p[column]).astype(ds.dtype, copy=False)
                                 for p in parts]))
            else:
                ds[old:] = _as_storable(_joined(parts, column))
        self._deflater.add_many(numeric)

    def commit(self) -> Path:
        """Mark the file complete, close it and rename it into place."""
        self._deflater.finish()
        self._deflater.close()
        self._check_space(0)
        _set_root_attr(self._file, "complete", True)
        self._file.close()
        os.replace(self.tmp_path, self.path)
        self._committed = True
        return self.path

    def abort(self) -> None:
        """Close and delete the temporary file."""
        try:
            try:
                self._deflater.close()
            finally:
                self._file.close()
        finally:
            self.tmp_path.unlink(missing_ok=True)


def open_run(path: os.PathLike, *, require_columns: bool = False) -> h5py.File:
    """Open a complete run file of this layout version for reading, or raise StoreError.

    ``require_columns``: the caller reads the simulator's tables (export, report, evaluate):
    in a simulation run (``seed >= 0``; conversions have -1) every table gmtiflow writes must
    hold the columns its writer defines (:func:`check_columns`).
    """
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
    try:
        layout = require_columns and int(_scalar(f.attrs.get("seed", -1))) >= 0
        check_structure(f, path, layout=layout)
        check_attrs(f, path)
        if "config" in f:
            read_config(f)      # checked (and kept for a caller's read_config) once per open
        if layout:
            check_columns(f, path)
    except StoreError:
        f.close()
        raise
    except _DAMAGED as exc:
        f.close()
        raise StoreError(f"{path}: damaged HDF5 file ({type(exc).__name__})") from None
    return f


def check_structure(f: h5py.File, path, *, layout: bool = False) -> None:
    """StoreError unless every object of ``f`` is a group or a sane 1-D dataset inside it.

    Refused: external links (they open other files), soft links, virtual datasets, datasets
    with external raw storage, datasets of more than one dimension (the scalar ``/config``
    aside), columns that claim more bytes than :data:`MAX_EXPANSION` times what they store,
    and a table bigger than this machine's memory (a run file that cannot be read whole).
    A text column whose name has a unit suffix is refused; with ``layout`` (a simulation run
    read by a consumer of its tables) so is any text column of a known table but its
    :data:`TEXT_COLUMNS`.
    """
    memory = available_memory_bytes()
    count = 0
    stack = [("", f)]
    while stack:
        prefix, group = stack.pop()
        for name in group:
            where = f"{prefix}/{name}"
            count += 1
            if count > MAX_OBJECTS:
                raise StoreError(f"{path}: more than {MAX_OBJECTS} HDF5 objects; not a gmtiflow "
                                 f"run file")
            link = group.get(name, getlink=True)
            if isinstance(link, h5py.ExternalLink):
                raise StoreError(f"{path}: {where} is an external link to another file; run "
                                 f"files must be self-contained (refused)")
            if isinstance(link, h5py.SoftLink):
                raise StoreError(f"{path}: {where} is a soft link; gmtiflow writes none "
                                 f"(refused)")
            obj = group[name]
            if isinstance(obj, h5py.Group):
                stack.append((where, obj))
            elif isinstance(obj, h5py.Dataset):
                _check_dataset(obj, where, path, memory, layout)


def _check_dataset(ds: h5py.Dataset, where: str, path, memory: int, layout: bool) -> None:
    if ds.is_virtual:
        raise StoreError(f"{path}: {where} is a virtual dataset (it maps other files); "
                         f"refused")
    if ds.external:
        raise StoreError(f"{path}: {where} keeps its data in external files; refused")
    if where == "/config" or where.count("/") == 1 and ds.ndim == 0:
        if ds.ndim != 0:
            raise StoreError(f"{path}: {where} must be a scalar text dataset")
        return
    if ds.ndim != 1:
        raise StoreError(f"{path}: {where} has shape {ds.shape}; gmtiflow columns are 1-D")
    n_bytes = int(ds.shape[0]) * int(ds.dtype.itemsize)
    stored = int(ds.id.get_storage_size())
    if n_bytes > 2**20 and n_bytes > MAX_EXPANSION * stored:
        raise StoreError(f"{path}: {where} claims {ds.shape[0]} rows ({human_bytes(n_bytes)}) "
                         f"but stores only {human_bytes(stored)}; refused (a damaged or "
                         f"hostile file)")
    if n_bytes > memory:
        raise StoreError(f"{path}: {where} holds {ds.shape[0]} rows ({human_bytes(n_bytes)}), "
                         f"more than this machine's available memory "
                         f"({human_bytes(memory)}; GMTIFLOW_MEMORY_BYTES)")
    table, _, column = where[1:].rpartition("/")
    is_text = h5py.check_string_dtype(ds.dtype) is not None or ds.dtype.kind in "SUO"
    if is_text:    # known tables: only their text columns; any table: no text with a unit
        known = layout and (table in TEXT_COLUMNS or table in _KNOWN_TABLES)
        numeric = bool(unit_of(column)) or \
            (known and column not in TEXT_COLUMNS.get(table, ()))
        if numeric:
            raise StoreError(f"{path}: column {where} holds text; gmtiflow stores numbers "
                             f"there")
    elif ds.dtype.kind not in "biuf":
        raise StoreError(f"{path}: column {where} has the HDF5 type {ds.dtype}; gmtiflow "
                         f"columns are numbers, booleans or text")


def check_columns(f: h5py.File, path) -> None:
    """StoreError if a table of a simulation run lacks a column gmtiflow writes into it."""
    for table, columns in required_columns().items():
        if table in f:
            group = f[table]
            if not isinstance(group, h5py.Group):
                raise StoreError(f"{path}: /{table} is not a table (an HDF5 group of columns)")
            missing = [c for c in columns if c not in group]
            if missing:
                raise StoreError(f"{path}: table /{table} lacks the column(s) "
                                 f"{', '.join(missing)}; the file is damaged or was edited")


_ISO_UTC = re.compile(r"^\d{4}-\d{2}-\d{2}([T ]\d{2}:\d{2}(:\d{2}(\.\d+)?)?)?(Z|[+-]\d{2}:?\d{2})?$")


def _scalar(value: Any):
    if isinstance(value, np.ndarray):
        if value.shape not in ((), (1,)):
            return None
        value = value.reshape(()).item()
    if isinstance(value, np.generic):
        value = value.item()
    return value


def check_attrs(f: h5py.File, path) -> None:
    """StoreError unless the root attributes gmtiflow reads have their types and ranges."""
    attrs = f.attrs

    def number(key, lo=-math.inf, hi=math.inf, integer=False):
        if key not in attrs:
            return
        v = _scalar(attrs[key])
        ok = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) \
            and lo <= v <= hi and (not integer or float(v).is_integer())
        if not ok:
            raise StoreError(f"{path}: root attribute {key} must be a finite "
                             f"{'integer' if integer else 'number'} in [{lo:g}, {hi:g}]; "
                             f"this one is not")

    number("seed", integer=True)
    number("origin_lat_deg", -90, 90)
    number("origin_lon_deg", -180, 360)
    number("origin_height_m", -1e6, 1e7)
    number("scene_duration_s", 0)
    for key in ("scene_epoch_utc", "gmtiflow_version", "attribution"):
        if key in attrs:
            v = _scalar(attrs[key])
            if isinstance(v, bytes):
                try:
                    v = v.decode("utf-8")
                except UnicodeDecodeError:
                    v = None
            if not isinstance(v, str) or len(v) > 10_000:
                raise StoreError(f"{path}: root attribute {key} must be a text value")
            simulated = isinstance(_scalar(attrs.get("seed", -1)), int) and \
                _scalar(attrs.get("seed", -1)) >= 0
            if key == "scene_epoch_utc" and simulated and v and not _ISO_UTC.match(v.strip()):
                raise StoreError(f"{path}: root attribute scene_epoch_utc is not an ISO 8601 "
                                 f"UTC time (YYYY-MM-DDTHH:MM:SSZ)")


def read_attrs(f: h5py.File) -> dict:
    """The root attributes of an open run file as plain Python values (StoreError if damaged)."""
    try:
        return {k: (v.item() if isinstance(v, np.generic) else
                    _scalar(v) if isinstance(v, np.ndarray) and v.size == 1 else v)
                for k, v in f.attrs.items()}
    except _DAMAGED as exc:
        raise StoreError(f"{f.filename}: root attributes cannot be read, the file is damaged "
                         f"({exc})") from None


def read_table(source, name: str) -> Table:
    """Read table ``name`` from an open run file or a path."""
    if isinstance(source, h5py.File):
        return _read_group(source, name)
    with open_run(source) as f:
        return _read_group(f, name)


class StoredTable(dict):
    """A table read from a run file: asking for a column it lacks raises StoreError."""

    source: str = ""
    name: str = ""

    def __missing__(self, column):
        raise StoreError(f"{self.source}: table /{self.name} has no column {column!r}; the file "
                         f"is damaged or was written by another program")


def _read_group(f: h5py.File, name: str) -> Table:
    try:
        if name not in f or not isinstance(f[name], h5py.Group):
            raise StoreError(f"{f.filename}: has no table /{name}")
        out = {column: _read_dataset(ds) for column, ds in f[name].items()
               if isinstance(ds, h5py.Dataset)}
    except _DAMAGED as exc:
        raise StoreError(f"{f.filename}: table /{name} cannot be read, the file is damaged "
                         f"({exc})") from None
    lengths = {len(v) for v in out.values() if np.ndim(v) == 1}
    if len(lengths) > 1 or any(np.ndim(v) != 1 for v in out.values()):
        raise StoreError(f"{f.filename}: table /{name} has columns of different lengths or "
                         f"shapes; not a gmtiflow table")
    table = StoredTable(out)
    table.source, table.name = f.filename, name
    return table


def _read_dataset(ds: h5py.Dataset) -> np.ndarray:
    data = ds[()]
    if h5py.check_string_dtype(ds.dtype) is not None:
        data = np.asarray([v.decode("utf-8") if isinstance(v, bytes) else v for v in data],
                          dtype=str)
    return data


def read_column(f: h5py.File, name: str, column: str) -> np.ndarray:
    """One column of table ``name`` of an open run file (StoreError if missing or damaged)."""
    try:
        ds = f[name][column] if name in f and column in f[name] else None
        if not isinstance(ds, h5py.Dataset):
            raise StoreError(f"{f.filename}: table /{name} has no column {column!r}")
        return _read_dataset(ds)
    except _DAMAGED as exc:
        raise StoreError(f"{f.filename}: table /{name} cannot be read, the file is damaged "
                         f"({exc})") from None


def read_text(source, name: str, *, check: bool = True) -> str:
    """Read a scalar string dataset such as ``/config`` (checked with
    :func:`check_config_text` unless ``check`` is False)."""
    def get(f: h5py.File) -> str:
        try:
            obj = f[name]
            if not isinstance(obj, h5py.Dataset) or obj.ndim != 0 or \
                    h5py.check_string_dtype(obj.dtype) is None:
                raise StoreError(f"{f.filename}: /{name} is not a text dataset")
            value = obj[()]
            text = value.decode("utf-8") if isinstance(value, bytes) else str(value)
        except _DAMAGED as exc:
            raise StoreError(f"{f.filename}: /{name} cannot be read "
                             f"({type(exc).__name__})") from None
        if name == "config" and check:
            check_config_text(text, f.filename)
        return text
    if isinstance(source, h5py.File):
        return get(source)
    with open_run(source) as f:
        return get(f)


_CONFIGS: "weakref.WeakKeyDictionary[h5py.File, dict]" = weakref.WeakKeyDictionary()
"""The parsed ``/config`` of each open run file, read and checked by :func:`open_run`."""


def read_config(f: h5py.File) -> dict:
    """The run's ``/config`` as a dict, read and checked (:func:`check_config_text`) once per
    open file: :func:`open_run` already did it, so a reader of the config does not parse the
    YAML again.  The dict is shared by the callers of one open file: do not modify it."""
    doc = _CONFIGS.get(f)
    if doc is None:
        doc = _CONFIGS[f] = _parse_config(read_text(f, "config", check=False), f.filename)
    return doc


_SAFE_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
"""``yaml.safe_load``'s loader, in libyaml's C scanner and parser when PyYAML has it (the same
documents, ~10x faster: every reader of a run file parses its /config)."""


def check_config_text(text: str, source) -> None:
    """StoreError unless ``text`` is a resolved YAML mapping (the run's ``/config``)."""
    _parse_config(text, source)


_LAST_PARSED: Dict[bytes, dict] = {}
"""The last /config text parsed (by its digest) and its mapping: the run's readers in one
process (the exports, the report, the command's summary) each open the run file, and a config
listing 1,000 vehicles takes ~0.5 s CPU to parse (PyYAML constructs in Python even on
libyaml's parser).  Only texts that passed :func:`_parse_config`'s checks are kept."""


def _parse_config(text: str, source) -> dict:
    """The mapping of ``text``, or StoreError unless it is a resolved YAML mapping.

    A ``${...}`` anywhere is refused: OmegaConf would evaluate it when a consumer loads the
    config (``${oc.env:HOME}`` reads the environment), and gmtiflow stores resolved configs.
    The same text parsed again returns the same (shared: do not modify it) mapping.
    """
    if len(text) > 16 * 2**20:
        raise StoreError(f"{source}: /config is {len(text)} characters; not a gmtiflow config")
    digest = hashlib.blake2b(text.encode("utf-8", "surrogatepass"), digest_size=20).digest()
    doc = _LAST_PARSED.get(digest)
    if doc is None:
        doc = _checked_config(text, source)
        _LAST_PARSED.clear()
        _LAST_PARSED[digest] = doc
    return doc


def _checked_config(text: str, source) -> dict:
    """:func:`_parse_config`'s parse and checks, done for every new text."""
    try:
        doc = yaml.load(text, Loader=_SAFE_LOADER)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" (line {mark.line + 1})" if mark is not None else ""
        raise StoreError(f"{source}: /config is not valid YAML{where}") from None
    except RecursionError:
        raise StoreError(f"{source}: /config is nested too deeply") from None
    if not isinstance(doc, dict):
        raise StoreError(f"{source}: /config is not a YAML mapping of config groups")
    stack = [doc]
    while stack:
        node = stack.pop()
        items = node.items() if isinstance(node, dict) else enumerate(node) \
            if isinstance(node, list) else ()
        for key, value in items:
            if isinstance(value, (dict, list)):
                stack.append(value)
            elif isinstance(value, str) and "${" in value or isinstance(key, str) and "${" in key:
                raise StoreError(f"{source}: /config holds an interpolation '${{...}}'; run files "
                                 f"store resolved configs (refused: it would be evaluated)")
    return doc
