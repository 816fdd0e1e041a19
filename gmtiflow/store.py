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

Writing speed: every numeric column is compressed by :class:`_ChunkDeflater`, which applies
the datasets' own filters (shuffle, then deflate, :func:`_deflated_chunk`; byte planes that are
noise go into the deflate stream as stored blocks) on the calling thread for a run's first
:data:`_INLINE_RUN_BYTES`, then in worker threads while the simulation goes on, and writes the
finished chunks in order with HDF5's direct chunk write; the planes of a table's chunks are
judged together (:func:`_deflated_chunks`).  The datasets and their attributes are made with
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
import threading
import weakref
from collections import deque
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any, Dict, List, Mapping, Optional

import h5py
import numpy as np
import yaml
from h5py import h5a, h5d, h5g, h5p, h5s, h5t

from gmtiflow import __version__
from gmtiflow.errors import StoreError
from gmtiflow.resources import available_memory_bytes, human_bytes
from gmtiflow.tables import Table, n_rows, unit_of

try:    # zlib-ng: the same standard deflate streams for less CPU (docs/tables.md)
    from zlib_ng import zlib_ng as zlib
    _MATCH_STRATEGY: Optional[int] = zlib.Z_DEFAULT_STRATEGY
except ImportError:     # pragma: no cover (zlib-ng is a dependency; CPython's zlib will do)
    import zlib
    _MATCH_STRATEGY = None
"""How :func:`_deflated_chunk` deflates a byte plane whose bytes repeat in strings (a periodic
column: vehicles on laps, a beam scan), besides zlib's run-length strategy (``Z_RLE``), which
after the shuffle finds a column's runs of equal bytes (its exponents) and codes the bytes by
their frequencies.  zlib-ng's level 1 (its "quick" deflate: matches found by a hash, static
codes) deflates such a plane ~10x faster and to a fraction of ``Z_RLE``'s bytes, but codes
every other byte in 8-9 bits whatever their frequencies; CPython's zlib has no such mode
(None: ``Z_RLE`` or Huffman-only for every plane, :data:`_HUFFMAN_MARGIN_BITS`)."""

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
_DEFLATE_LEVEL = 1
_INLINE_BYTES = 16 * 1024
"""Chunks smaller than this are deflated on the calling thread (:class:`_ChunkDeflater`)."""
_BATCH_BYTES = 8 * 2**20
"""The chunks deflated together on the calling thread (:func:`_deflated_chunks`) hold at most
this many bytes of values (unless one chunk holds more): their shuffled planes are all in
memory until the last is encoded, a bounded copy of a table's block."""
_INLINE_RUN_BYTES = 64 * 2**20
"""A run's first this many bytes of columns are deflated on the calling thread, the rest in
worker threads (:class:`_ChunkDeflater`): the threads cost CPU of their own (starting them, and
handing the GIL to and fro around every zlib call: ~0.02 s on the 19 MB of the 10-target Stone
Soup peer run, on 2 cores; docs/scale.md), which only a run big enough to keep them busy
repays in wall time."""

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
            plist.set_deflate(_DEFLATE_LEVEL)
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


_SMALL_BYTES = 4096
"""Chunks smaller than this are shuffled and deflated whole, as one section
(:func:`_small_stream`)."""
_NOISE_BITS = 7.7
"""A byte plane whose sample has more entropy than this (bits a byte, of 8; a sample of
uniformly random bytes has ~7.91) is stored, not deflated: deflate would spend ~7 ms a MB on it
to save a few percent at most."""
_SAMPLE_BLOCKS, _SAMPLE_BYTES = 8, 256
_LITERAL_BITS = 8.0
"""What :data:`_MATCH_STRATEGY` spends on a byte that no match covers, about (its static
codes).  A plane goes to it when that, over the bytes its sample's repeated strings leave
(:func:`_plane_samples`), is less than what ``Z_RLE`` spends, about: the sample's entropy over
the bytes that do not repeat the one before (a run is one match to ``Z_RLE``).  Counting the
runs keeps a plane of one dominant byte, whose repeated strings are its runs, with ``Z_RLE``
(zlib-ng's quick deflate spent ~2x its bytes): on the columns of the Stone Soup peer runs (10
and 1,000 targets) and the fidelity benchmark's `fast` scene, 2-4 % fewer bytes than without,
for ~1 ms more CPU on the 10-target run."""
_HUFFMAN_MARGIN_BITS = 0.5
"""A plane that is neither noise nor for :data:`_MATCH_STRATEGY` is deflated with zlib's
Huffman-only strategy (``Z_HUFFMAN_ONLY``: no matches, each byte coded by its frequency) when
what that spends, about (the sample's entropy, at least 1 bit a byte: a Huffman code's
shortest), is at most what ``Z_RLE`` spends, about (over the bytes that no run-length match
covers, those equal to the three before: a match needs three, their own entropy, plus this
margin for the matches' own codes).  Short runs (the sensor's σ's and RCS, one value for every
false alarm between the targets' own) then cost ``Z_RLE`` a match search at every byte, and
it codes them in more bytes than Huffman-only: on the planes of the fidelity benchmark's
`fast` and `full` scenes (1,000 vehicles, issue 18) 14-16 % less deflate CPU for as many
bytes.  The entropy of the uncovered bytes, not the whole sample's: where one byte dominates,
the runs are mostly of it and the bytes they leave are spread more evenly, so with the whole
sample's entropy the detections' σ and RCS planes of the `fast` scene went to ``Z_RLE``, which
spent twice Huffman-only's CPU on them for ~6 % more bytes."""
_HUFFMAN_STORE_BITS = 6.75
"""A plane bound for Huffman-only (:data:`_HUFFMAN_MARGIN_BITS`) whose sample has at least this
entropy (bits a byte, of 8) is stored instead: Huffman-only would spend ~2.6 ms a MB on it
(zlib-ng, this project's machine) to save 10-15 % of its bytes (the top mantissa bytes of
measured values: the detections' ranges, range rates and angles).  On the chunks of the run
files of the Stone Soup peer (10 targets) and of the fidelity benchmark's `fast` and `full`
scenes: ~4 %, ~7 % and ~10 % less deflate CPU for 0.1 %, 0.4 % and 0.5 % more bytes
(replayed, 23:05 UTC, issue 18)."""
_MEM_LEVEL = 9
"""zlib's ``memLevel`` of the plane compressors (:func:`_compressor`): 9 (256 KiB of buffers
more than the default 8) lets a deflate block hold 32,768 symbols, so a 64 KiB plane ends
half as many blocks (each a Huffman tree built and written): ~6 % less deflate CPU on the
planes of the fidelity benchmark's scenes, for the same bytes within 0.1 %."""
_XLOGX = np.zeros(_SAMPLE_BLOCKS * _SAMPLE_BYTES + 1)
_XLOGX[1:] = np.arange(1, len(_XLOGX)) * np.log2(np.arange(1, len(_XLOGX)))
_ZLIB_HEADER = b"\x78\x01"            # deflate, 32 KiB window, fastest
_LAST_BLOCK = b"\x01\x00\x00\xff\xff"  # an empty stored block marked final
_local = threading.local()


_SAMPLE_INDEX: Dict[int, np.ndarray] = {}
_KEY_OFFSETS = np.arange(256, dtype=np.uint16) << 8


def _sample(planes: np.ndarray) -> Optional[np.ndarray]:
    """The sample :func:`_plane_samples` judges ``planes`` (byte planes, one a row) by: of each
    plane, :data:`_SAMPLE_BLOCKS` runs of :data:`_SAMPLE_BYTES` bytes spread over it, one row
    of the result; None for planes too short to sample (or none)."""
    k, n = planes.shape
    if k == 0 or n < 4 * _SAMPLE_BLOCKS * _SAMPLE_BYTES:
        return None
    index = _SAMPLE_INDEX.get(n)
    if index is None:
        if len(_SAMPLE_INDEX) >= 256:
            _SAMPLE_INDEX.clear()
        starts = np.linspace(0, n - _SAMPLE_BYTES, _SAMPLE_BLOCKS).astype(np.intp)
        index = _SAMPLE_INDEX[n] = (starts[:, None] + np.arange(_SAMPLE_BYTES)).ravel()
    return planes.take(index, axis=1)


def _plane_samples(planes: np.ndarray):
    """``(bits, repeated, strings, noise, runs, literal_bits)`` of ``planes`` (byte planes,
    one a row), from a sample of :data:`_SAMPLE_BLOCKS` runs of :data:`_SAMPLE_BYTES` bytes
    spread over each plane (:func:`_sample`): its entropy in bits a byte, the fraction of its
    bytes equal to the one before, the fraction of the 4-byte strings of its middle run that
    occur twice or more in that run (what deflate's matches can replace), whether the plane
    looks like noise: more than :data:`_NOISE_BITS` bits a byte and hardly a byte equal to
    the one before (the low bytes of measured floats), the fraction of its bytes equal to the
    three before (what a run-length match can cover), and the entropy of the bytes those
    leave (``Z_RLE``'s literals: in a plane of one dominant byte the runs are mostly that
    byte, and what they leave is spread more evenly than the whole plane).  All None for
    planes too short to sample.  Depends on the bytes only (deterministic files)."""
    sample = _sample(planes)
    if sample is None:
        return None, None, None, None, None, None
    return _sample_stats(sample)


def _key_offsets(k: int) -> np.ndarray:
    """``256 * i`` for the i-th of ``k`` sample rows: (row, byte) as one bincount key."""
    if k <= len(_KEY_OFFSETS):
        return _KEY_OFFSETS[:k, None]
    return (np.arange(k, dtype=np.uint32) << 8)[:, None]


def _sample_stats(sample: np.ndarray):
    """:func:`_plane_samples`'s figures of each row of ``sample`` (rows of :func:`_sample`,
    of one plane or of many chunks' planes: every figure is its row's own)."""
    k = sample.shape[0]
    keys = sample + _key_offsets(k)                   # (row, byte) as one bincount key
    counts = np.bincount(keys.ravel(), minlength=256 * k)
    m = sample.shape[1]
    bits = np.log2(m) - _XLOGX[counts].reshape(k, 256).sum(axis=1) / m
    runs = sample.reshape(k, _SAMPLE_BLOCKS, _SAMPLE_BYTES)
    # flags as 0/1 bytes, counted in uint16 sums (~3x cheaper than bool sums into intp; a
    # count is at most the sample's 2,048 bytes)
    same = (runs[:, :, 1:] == runs[:, :, :-1]).view(np.uint8)    # byte i + 1 equal to byte i
    repeated = same.reshape(k, -1).sum(axis=1, dtype=np.uint16) / runs[0, :, 1:].size
    in_run = same[:, :, 2:] & same[:, :, 1:-1]
    in_run &= same[:, :, :-2]                         # byte i + 3 equal to bytes i .. i + 2
    covered = in_run.reshape(k, -1).sum(axis=1, dtype=np.uint16)
    run_bytes = covered / in_run[0].size
    literals = counts - np.bincount(keys.reshape(runs.shape)[:, :, 3:][in_run.view(bool)],
                                    minlength=256 * k)
    m_literal = m - covered          # > 0: the first three bytes of a run are never covered
    literal_bits = np.log2(m_literal) - \
        _XLOGX[literals].reshape(k, 256).sum(axis=1) / m_literal
    noise = (bits > _NOISE_BITS) & (repeated < 1 / 32)
    mid = runs[:, _SAMPLE_BLOCKS // 2].astype(np.uint32)
    keys = mid[:, :-3] | mid[:, 1:-2] << 8 | mid[:, 2:-1] << 16 | mid[:, 3:] << 24
    keys.sort(axis=1)
    strings = (keys[:, 1:] == keys[:, :-1]).view(np.uint8).sum(axis=1, dtype=np.uint16) / \
        (keys.shape[1] - 1)
    return bits, repeated, strings, noise, run_bytes, literal_bits


def _noise_planes(planes: np.ndarray) -> np.ndarray:
    """Which rows of ``planes`` (byte planes, one a row) look like noise
    (:func:`_plane_samples`; none of planes too short to sample)."""
    noise = _plane_samples(planes)[3]
    return np.zeros(len(planes), bool) if noise is None else noise


def _compressor(strategy: int):
    """This thread's compressor of ``strategy`` (raw deflate, level 1, memLevel
    :data:`_MEM_LEVEL`), made once: a new one costs ~50 µs of page faults.  Every section it
    gives ends with a full flush, after which it refers to nothing before: its sections are
    those of a new compressor."""
    key = f"z{strategy}"
    z = getattr(_local, key, None)
    if z is None:
        z = zlib.compressobj(_DEFLATE_LEVEL, zlib.DEFLATED, -15, _MEM_LEVEL, strategy)
        setattr(_local, key, z)
    return z


def _stored_blocks(plane: np.ndarray) -> list:
    """``plane``'s bytes as deflate stored blocks (not final; at most 65,535 bytes each)."""
    data = memoryview(plane)
    out = []
    for i in range(0, len(data), 65535):
        piece = data[i:i + 65535]
        out += [b"\x00" + len(piece).to_bytes(2, "little") +
                (len(piece) ^ 0xFFFF).to_bytes(2, "little"), piece]
    return out


def _constant_planes(values) -> np.ndarray:
    """Which byte positions hold the same byte in every value of ``values`` (an array, or a
    list of arrays of one dtype: its constant byte planes, the high bytes of ids, every byte of
    a constant column); none for an element size with no unsigned integer of that size."""
    pieces = [p for p in (values if isinstance(values, list) else [values]) if len(p)]
    k = (values[0] if isinstance(values, list) else values).dtype.itemsize
    if k not in (1, 2, 4, 8) or not pieces:
        return np.zeros(k, bool)
    us = [p.view(f"u{k}") for p in pieces]
    ones = functools.reduce(np.bitwise_or, [np.bitwise_or.reduce(u) for u in us])
    both = functools.reduce(np.bitwise_and, [np.bitwise_and.reduce(u) for u in us])
    differ = ones ^ both                                      # bits not all 0 nor all 1
    return np.frombuffer(np.asarray(differ, us[0].dtype).tobytes(), np.uint8) == 0


def _shuffled(pieces: list, varying: np.ndarray, n: int) -> np.ndarray:
    """Byte planes ``varying`` (byte positions, ascending) of the ``n`` values of ``pieces``
    (contiguous arrays of one dtype, their rows in order), one plane a row: HDF5's shuffle of
    the joined values, written plane by plane from each piece (no joined copy).  A single
    piece whose planes all vary: the plain transpose."""
    k = pieces[0].dtype.itemsize
    if len(pieces) == 1:
        raw = pieces[0].view(np.uint8)
        if k == 1:
            return raw.reshape(1, -1)[:len(varying)]
        if len(varying) == k:
            return np.ascontiguousarray(raw.reshape(-1, k).T)
        return raw.reshape(-1, k).T[varying]         # the varying planes only (a copy)
    planes = np.empty((len(varying), n), np.uint8)
    every = len(varying) == k
    at = 0
    for piece in pieces:
        rows = piece.view(np.uint8).reshape(-1, k)
        if every:
            planes[:, at:at + len(rows)] = rows.T
        else:
            for i, j in enumerate(varying.tolist()):
                planes[i, at:at + len(rows)] = rows[:, j]
        at += len(rows)
    return planes


_SECTIONS: Dict[tuple, bytes] = {}
"""Deflate sections of constant byte planes, by (byte, length): made once by a fresh
compressor, so the same plane always gives the same bytes (deterministic files)."""


def _constant_section(byte: int, n: int) -> bytes:
    """``n`` bytes equal to ``byte``, deflated (``Z_RLE``) and ended by a full flush: a section
    that refers to nothing before it, so any section may precede or follow it."""
    key = (byte, n)
    section = _SECTIONS.get(key)
    if section is None:
        z = zlib.compressobj(_DEFLATE_LEVEL, zlib.DEFLATED, -15, 8, zlib.Z_RLE)
        section = z.compress(bytes((byte,)) * n) + z.flush(zlib.Z_FULL_FLUSH)
        if len(_SECTIONS) >= 4096:
            _SECTIONS.clear()
        _SECTIONS[key] = section
    return section


def _adler32_run(adler: int, byte: int, n: int) -> int:
    """``zlib.adler32(bytes((byte,)) * n, adler)`` without the bytes."""
    a, b = adler & 0xFFFF, adler >> 16
    b = (b + n * a + byte * n * (n + 1) // 2) % 65521
    a = (a + n * byte) % 65521
    return (b << 16) | a


def _deflated_chunk(values, pad_rows: int = 0) -> bytes:
    """One HDF5 chunk through the filters of a gmtiflow column, shuffle then deflate: the bytes
    of element position j of every value together (HDF5's shuffle filter), then one zlib
    stream (HDF5's deflate filter inflates any).  ``values``: the chunk's values, an array or
    a list of arrays of one dtype (its rows in order: joined by the shuffle itself,
    :func:`_shuffled`); ``pad_rows``: zero values after them (a dataset's last, partial chunk,
    padded to its full size as HDF5 stores an edge chunk), each plane's zeros a cached
    section (:func:`_constant_section`) after the plane's bytes, judged and deflated without
    them.

    Each byte plane is a section of that stream: one that holds a single byte value
    (:func:`_constant_planes`: the high bytes of ids, every plane of a constant column) as a
    cached section (:func:`_constant_section`; neither shuffled, checked for noise nor
    checksummed byte by byte), one that looks like noise (:func:`_plane_samples`) as stored
    blocks, any other deflated and ended by a full flush, after which the compressor refers
    to nothing before (so stored blocks, other sections, or the next chunk, can follow): with
    zlib's run-length strategy (``Z_RLE``), or with :data:`_MATCH_STRATEGY` when that deflates
    the plane to fewer bytes, as judged from its sample (:data:`_LITERAL_BITS`), or with
    Huffman-only when its runs are too short to repay ``Z_RLE`` (:data:`_HUFFMAN_MARGIN_BITS`;
    stored if its entropy leaves Huffman-only little to gain, :data:`_HUFFMAN_STORE_BITS`; a
    plane too short to sample: ``Z_RLE``).  Each thread
    has one compressor of each (:func:`_compressor`).  On the columns of real runs this takes
    about a quarter of the CPU of HDF5's own level-1 deflate, for 1-2 % more bytes
    (docs/tables.md).  zlib releases the GIL while compressing.  A chunk of fewer than
    :data:`_SMALL_BYTES` is shuffled and deflated whole (:func:`_small_stream`)."""
    prep = _chunk_planes(values, pad_rows)
    if isinstance(prep, bytes):
        return prep
    return _encoded(prep, _plane_ways(_plane_samples(prep[4]), len(prep[4])), pad_rows)


def _deflated_chunks(chunks: list) -> list:
    """``[_deflated_chunk(values, pad_rows) for values, pad_rows in chunks]``, the same bytes,
    with the planes of every chunk judged at once (:func:`_sample_stats` over all their
    samples, :func:`_plane_ways`): a table's columns, each a chunk of a few planes, pay
    numpy's per-call cost once rather than once a column."""
    preps = [_chunk_planes(values, pad_rows) for values, pad_rows in chunks]
    if all(type(prep) is bytes for prep in preps):     # small chunks: each a finished stream
        return preps
    samples = [None if isinstance(prep, bytes) else _sample(prep[4]) for prep in preps]
    judged = [x for x in samples if x is not None]
    ways = iter(_plane_ways(_sample_stats(np.concatenate(judged)) if len(judged) > 1 else
                            _sample_stats(judged[0]), sum(len(x) for x in judged))
                if judged else [])
    out = []
    for prep, sample, (_, pad_rows) in zip(preps, samples, chunks):
        if isinstance(prep, bytes):
            out.append(prep)
            continue
        n_planes = len(prep[4])
        way = [next(ways) for _ in range(n_planes)] if sample is not None else \
            _plane_ways((None,) * 6, n_planes)
        out.append(_encoded(prep, way, pad_rows))
    return out


_STORED = -1
"""A plane's way (:func:`_plane_ways`): stored blocks, not deflated."""


def _plane_ways(stats, n_planes: int) -> list:
    """How each of ``n_planes`` planes goes into the stream, from their sample figures
    ``stats`` (:func:`_plane_samples`; all None: too short to sample, ``Z_RLE``): the zlib
    strategy of the compressor expected to deflate it smaller, or :data:`_STORED` (noise, or
    too little to gain from Huffman-only: :data:`_HUFFMAN_STORE_BITS`)."""
    bits, repeated, strings, noise, run_bytes, literal_bits = stats
    if noise is None:
        return [zlib.Z_RLE] * n_planes
    runs_pay = np.maximum(bits, 1.0) > literal_bits * (1 - run_bytes) + _HUFFMAN_MARGIN_BITS
    way = np.where(runs_pay, zlib.Z_RLE, zlib.Z_HUFFMAN_ONLY)
    if _MATCH_STRATEGY is not None:
        matched = (1 - strings) * _LITERAL_BITS < bits * (1 - repeated)     # bits a byte
        way = np.where(matched, _MATCH_STRATEGY, way)
    way = np.where(noise | (way == zlib.Z_HUFFMAN_ONLY) & (bits >= _HUFFMAN_STORE_BITS),
                   _STORED, way)
    return way.tolist()


def _chunk_planes(values, pad_rows: int):
    """A chunk's values (as :func:`_deflated_chunk` takes them) as ``(pieces, k, n, const,
    planes)``: its contiguous pieces, element size, rows, constant planes and the others
    shuffled (:func:`_shuffled`); or, for a chunk of fewer than :data:`_SMALL_BYTES` without
    padding, its finished deflate stream (one zlib call: the analysis costs more)."""
    pieces = values if isinstance(values, list) else [values]
    k = pieces[0].dtype.itemsize
    pieces = [np.ascontiguousarray(p) for p in pieces if len(p)] or pieces[:1]
    n = sum(len(p) for p in pieces)
    if n * k < _SMALL_BYTES and not pad_rows:
        raw = (pieces[0] if len(pieces) == 1 else np.concatenate(pieces)).view(np.uint8)
        return _small_stream(raw if k == 1 else np.ascontiguousarray(raw.reshape(-1, k).T))
    const = _constant_planes(pieces)
    return pieces, k, n, const, _shuffled(pieces, np.flatnonzero(~const), n)


def _small_stream(data: np.ndarray) -> bytes:
    """The zlib stream of ``data`` (a small chunk's shuffled bytes) as one section of this
    thread's level-1 compressor (:func:`_compressor`, ``Z_DEFAULT_STRATEGY``), ended by a
    full flush, then an empty final block and the checksum: ~10 bytes more than
    ``zlib.compress`` gives, which makes a new compressor (~350 KB) every call; after the
    1 MB conversion buffers of HDF5's text writes are freed (the heap trimmed), each of those
    touched fresh pages again (the 10-target peer run at 18 scans: ~240 of its ~280 page
    faults a run in the writer, 01:27 UTC)."""
    z = _compressor(zlib.Z_DEFAULT_STRATEGY)
    try:
        body = z.compress(data) + z.flush(zlib.Z_FULL_FLUSH)
    except BaseException:       # stopped mid-section (Ctrl-C): not reused
        delattr(_local, f"z{zlib.Z_DEFAULT_STRATEGY}")
        raise
    return b"".join((_ZLIB_HEADER, body, _LAST_BLOCK, zlib.adler32(data).to_bytes(4, "big")))


def _encoded(prep: tuple, ways: list, pad_rows: int) -> bytes:
    """The deflate stream of a chunk prepared by :func:`_chunk_planes`, its varying planes
    going in the ``ways`` of :func:`_plane_ways` (:func:`_deflated_chunk`)."""
    pieces, k, n, const, planes = prep
    rows = iter(planes)
    how = iter(ways)
    first = pieces[0].view(np.uint8)[:k].tolist()
    parts = [_ZLIB_HEADER]
    adler = 1
    z_open = None             # the compressor of the open section (not yet flushed)
    try:
        padding = _constant_section(0, pad_rows) if pad_rows else None
        for j in range(k):
            if const[j]:
                z = None
                if first[j] == 0 and pad_rows:        # the padding too: one section
                    section = _constant_section(0, n + pad_rows)
                    adler = _adler32_run(adler, 0, n + pad_rows)
                else:
                    section = _constant_section(first[j], n)
                    adler = _adler32_run(adler, first[j], n)
            else:
                plane = next(rows)
                adler = zlib.adler32(plane, adler)
                way = next(how)
                z = None if way == _STORED else _compressor(way)
            if z_open is not None and z is not z_open:
                parts.append(z_open.flush(zlib.Z_FULL_FLUSH))
            if z is not None:
                parts.append(z.compress(plane))
            elif const[j]:
                parts.append(section)
            else:
                parts += _stored_blocks(plane)
            z_open = z
            if pad_rows and not (const[j] and first[j] == 0):    # this plane's zeros
                if z_open is not None:
                    parts.append(z_open.flush(zlib.Z_FULL_FLUSH))
                    z_open = None
                parts.append(padding)
                adler = _adler32_run(adler, 0, pad_rows)
        if z_open is not None:
            parts.append(z_open.flush(zlib.Z_FULL_FLUSH))
    except BaseException:
        for key in list(vars(_local)):    # a compressor stopped mid-plane is not reused
            delattr(_local, key)
        raise
    parts += [_LAST_BLOCK, adler.to_bytes(4, "big")]
    return b"".join(parts)


class _ChunkDeflater:
    """Writes whole chunks of compressed 1-D datasets, compressing them in worker threads.

    Rows are given in order per dataset (:meth:`add`, or a table's columns at once:
    :meth:`add_many`); whole chunks go to the pool at once, the
    rest of a chunk waits for more rows (or :meth:`finish`, which pads the last chunk with zeros,
    as HDF5 stores an edge chunk).  Compressed chunks are written on the calling thread, in the
    order they were submitted and at points that do not depend on the threads' timing, so the
    file's layout does not either; at most :attr:`max_pending` chunks wait in memory.  A chunk
    of fewer than :data:`_INLINE_BYTES` is compressed and written at once on the calling thread
    (a thread hand-off costs more than its deflate), and so is every chunk until
    ``inline_bytes`` have been (a small run: :data:`_INLINE_RUN_BYTES`), the chunks of one
    :meth:`add_many` together (:func:`_deflated_chunks`); which chunks those are depends on their
    sizes only, so the order of the HDF5 calls still does not depend on the threads.
    """

    def __init__(self, workers: int, max_pending: int = 64, inline_bytes: int = 0):
        self.workers = workers
        self.inline_bytes = inline_bytes       # left to deflate on the calling thread
        self.pool: Optional[ThreadPoolExecutor] = None     # started with the first big chunk
        self.max_pending = max_pending
        self.pending: deque = deque()
        self.tails: Dict[str, tuple] = {}      # dataset path -> (id, chunk rows, first row,
        #                                        the rows: a list of arrays)

    def add(self, key: str, dsid, chunk_rows: int, start: int, values) -> None:
        """Rows ``values`` (an array, or a list of arrays of one dtype: their rows in order,
        never joined into one copy) of dataset ``dsid`` (path ``key``, chunks of
        ``chunk_rows``) from row ``start`` (the dataset already has that size)."""
        self.add_many([(key, dsid, chunk_rows, start, values)])

    def add_many(self, columns: list) -> None:
        """:meth:`add` of each ``(key, dsid, chunk_rows, start, values)`` of ``columns`` (a
        table's), their whole chunks deflated together (:meth:`_submit_many`)."""
        jobs = []
        for key, dsid, chunk_rows, start, values in columns:
            pieces = list(values) if isinstance(values, list) else [values]
            tail = self.tails.pop(key, None)
            if tail is None and len(pieces) == 1 and len(pieces[0]) == chunk_rows:
                jobs.append((dsid, start, pieces, 0))      # one whole chunk (_cut's)
                continue
            if tail is not None:
                start = tail[2]
                pieces = tail[3] + pieces
            total = sum(len(p) for p in pieces)
            full = (total // chunk_rows) * chunk_rows
            chunks, rest = _cut(pieces, chunk_rows, full)
            jobs += [(dsid, start + i * chunk_rows, chunk, 0) for i, chunk in enumerate(chunks)]
            if full < total:
                self.tails[key] = (dsid, chunk_rows, start + full, rest)
        self._submit_many(jobs)
        self.write_done()

    def _submit_many(self, jobs: list) -> None:
        """Deflate and write each ``(dsid, offset, chunk, pad_rows)`` of ``jobs``: ``chunk``
        (an array, or a list of arrays: its rows in order) followed by ``pad_rows`` zero
        values (:func:`_deflated_chunk`).  Which go to the threads depends on their sizes
        only; the others are deflated together (:func:`_deflated_chunks`, at most
        :data:`_BATCH_BYTES` of values at a time) and written at once, in order."""
        inline: list = []
        inline_bytes = 0
        for dsid, offset, chunk, pad_rows in jobs:
            if isinstance(chunk, list):
                chunk = chunk[0] if len(chunk) == 1 else chunk
            nbytes = sum(p.nbytes for p in chunk) if isinstance(chunk, list) else chunk.nbytes
            if self.workers <= 0 or nbytes < _INLINE_BYTES or self.inline_bytes > 0:
                self.inline_bytes -= nbytes
                if inline and inline_bytes + nbytes > _BATCH_BYTES:
                    self._write_inline(inline)
                    inline, inline_bytes = [], 0
                inline.append((dsid, offset, chunk, pad_rows))
                inline_bytes += nbytes
                continue
            if self.pool is None:
                self.pool = ThreadPoolExecutor(max_workers=self.workers,
                                               thread_name_prefix="deflate")
            self.pending.append((dsid, offset,
                                 self.pool.submit(_deflated_chunk, chunk, pad_rows)))
            self.write_done()           # at most max_pending wait, a table's many chunks too
        if inline:
            self._write_inline(inline)

    @staticmethod
    def _write_inline(jobs: list) -> None:
        """Deflate ``jobs`` (as :meth:`_submit_many` takes them) together on this thread and
        write them, in order."""
        streams = _deflated_chunks([(chunk, pad_rows) for _, _, chunk, pad_rows in jobs])
        for (dsid, offset, _, _), stream in zip(jobs, streams):
            dsid.write_direct_chunk((offset,), stream)

    def write_done(self, wait: bool = False) -> None:
        """Write the oldest compressed chunks, in order, until at most ``max_pending`` remain
        (none with ``wait``).  Never "whichever are ready": the HDF5 calls then come in the same
        order in every run, and so does the file's layout (byte-identical files)."""
        while self.pending and (wait or len(self.pending) > self.max_pending):
            dsid, offset, future = self.pending.popleft()
            dsid.write_direct_chunk((offset,), future.result())

    def finish(self) -> None:
        """Write every dataset's last, partial chunk, padded with zeros to its full size;
        wait for every chunk."""
        self._submit_many([(dsid, start, pieces, chunk_rows - sum(len(p) for p in pieces))
                           for dsid, chunk_rows, start, pieces in self.tails.values()])
        self.tails.clear()
        self.write_done(wait=True)

    def close(self) -> None:
        """Drop whatever is pending (abort) and stop the threads."""
        self.tails.clear()
        if self.pool is not None:
            self.pool.shutdown(wait=True, cancel_futures=True)
            self.pool = None
        self.pending.clear()


def _cut(pieces: list, chunk_rows: int, full: int) -> tuple:
    """``(chunks, rest)``: the first ``full`` rows (a multiple of ``chunk_rows``) of
    ``pieces`` (arrays, their rows in order) as chunks of ``chunk_rows`` rows, each a list of
    views of the pieces, and the list of views of the rows after them."""
    chunks: list = []
    rest: list = []
    current: list = []
    have = 0
    for piece in pieces:
        i = 0
        while i < len(piece):
            if len(chunks) * chunk_rows >= full:
                rest.append(piece[i:])
                break
            take = min(len(piece) - i, chunk_rows - have)
            current.append(piece[i:i + take])
            have += take
            i += take
            if have == chunk_rows:
                chunks.append(current)
                current, have = [], 0
    return chunks, rest


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
    by default up to 4, started only after the run's first :data:`_INLINE_RUN_BYTES` of columns.
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
            deflate_workers, inline = min(4, os.cpu_count() or 1), _INLINE_RUN_BYTES
        self._deflater = _ChunkDeflater(deflate_workers, inline_bytes=inline)
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
