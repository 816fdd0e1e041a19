"""HDF5 chunks of gmtiflow's numeric columns, through the datasets' own filters, and the
writer that compresses them in order (docs/tables.md, "Writing speed").

A run file's numeric columns are chunked 1-D datasets with HDF5's shuffle and deflate filters
(:mod:`gmtiflow.store` makes them).  This module produces the bytes of such a chunk itself, so
the writer can hand HDF5 finished chunks (direct chunk write) instead of running its filters:

* :func:`_deflated_chunk`: one chunk, shuffle then deflate.  The shuffle puts byte position j of
  every value together (a byte plane); each plane is judged on a sample and goes into one zlib
  stream as stored blocks (noise: the low mantissa bytes of measured values), a cached section
  (a constant plane), or deflated by the strategy that suits it (run-length, Huffman-only, or
  zlib-ng's quick deflate for planes whose bytes repeat in strings).  Any zlib inflates the
  result; the values read back are the values written.
* :func:`_deflated_chunks`: a table's chunks together, their planes judged at once.
* :class:`ChunkDeflater`: rows in, whole chunks out, in the order they were given, on the
  calling thread for a small run and in worker threads for a big one; the HDF5 calls come in
  the same order whatever the threads, so the file is byte-identical from run to run.

Byte layout conventions: values little-endian as the dataset stores them; the chunk's last rows
padded with zeros to its full size (as HDF5 stores an edge chunk); the zlib stream's header is
``78 01`` (deflate, level :data:`DEFLATE_LEVEL`), its trailer the Adler-32 of the shuffled bytes.
"""
from __future__ import annotations

import functools
import threading
from collections import deque
from concurrent.futures import ThreadPoolExecutor
from typing import Dict, Optional

import numpy as np

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

DEFLATE_LEVEL = 1
_INLINE_BYTES = 16 * 1024
"""Chunks smaller than this are deflated on the calling thread (:class:`ChunkDeflater`)."""
_BATCH_BYTES = 8 * 2**20
"""The chunks deflated together on the calling thread (:func:`_deflated_chunks`) hold at most
this many bytes of values (unless one chunk holds more): their shuffled planes are all in
memory until the last is encoded, a bounded copy of a table's block."""
INLINE_RUN_BYTES = 64 * 2**20
"""A run's first this many bytes of columns are deflated on the calling thread, the rest in
worker threads (:class:`ChunkDeflater`): the threads cost CPU of their own (starting them, and
handing the GIL to and fro around every zlib call: ~0.02 s on the 19 MB of the 10-target Stone
Soup peer run, on 2 cores; docs/scale.md), which only a run big enough to keep them busy
repays in wall time."""

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
        z = zlib.compressobj(DEFLATE_LEVEL, zlib.DEFLATED, -15, _MEM_LEVEL, strategy)
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
        z = zlib.compressobj(DEFLATE_LEVEL, zlib.DEFLATED, -15, 8, zlib.Z_RLE)
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


class ChunkDeflater:
    """Writes whole chunks of compressed 1-D datasets, compressing them in worker threads.

    Rows are given in order per dataset (:meth:`add`, or a table's columns at once:
    :meth:`add_many`); whole chunks go to the pool at once, the
    rest of a chunk waits for more rows (or :meth:`finish`, which pads the last chunk with zeros,
    as HDF5 stores an edge chunk).  Compressed chunks are written on the calling thread, in the
    order they were submitted and at points that do not depend on the threads' timing, so the
    file's layout does not either; at most :attr:`max_pending` chunks wait in memory.  A chunk
    of fewer than :data:`_INLINE_BYTES` is compressed and written at once on the calling thread
    (a thread hand-off costs more than its deflate), and so is every chunk until
    ``inline_bytes`` have been (a small run: :data:`INLINE_RUN_BYTES`), the chunks of one
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
