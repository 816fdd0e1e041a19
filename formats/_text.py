"""Text of whole columns at once: the numbers of the CSV, XML and GeoJSON writers, vectorised.

A column's cells are :class:`Cells`: one byte string per row, held as a ``uint8`` matrix (one
row per table row, left-aligned) and the length of each.  :func:`join` lays several such
columns and literal pieces side by side and returns the bytes of all rows, in row order; no
Python code runs per value.

Floats (:func:`float_cells`) are written so that they read back exactly (Python's ``float()``,
``strtod``, pandas and GDAL round to nearest): the shortest of 15, 16 or 17 significant digits
that is proven to lie within half a unit in the last place of the value, trailing zeros
removed, laid out as Python's ``repr`` lays it out (``0.1``, ``12345.678``, ``1e-05``,
``1.5e+16``).  The digits come from the value scaled by a power of ten in extended precision
(``numpy.longdouble``, 64-bit mantissa on x86-64) and the proof is made in that precision with
a margin wider than its error (|D − x| < 0.99 × the half-gap to the neighbouring doubles, with
D's error below 2⁻⁶² |x| and the half-gap at least 2⁻⁵⁴ |x|).  A value the proof does not
cover (subnormals; a platform whose ``longdouble`` is a plain double) is written with ``repr``;
so every value round-trips on every platform, and the text may differ from ``repr`` only in
digits beyond the shortest ones (``repr`` is the shortest string that round-trips).  Most values
are decided before that in double precision (:func:`_proof_fast`: the scaled value formed
exactly as a sum of two doubles), where the answer cannot differ from the extended-precision
one; the rest, about 1 in 30 (values next to a decimal's tolerance), go through :func:`_proof`.

Within :func:`shared_columns` a column's text is made once and reused by every format that
writes it; columns that repeat values in runs are formatted once per run.
"""
from __future__ import annotations

import threading
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Iterator, List, Optional, Sequence, Union

import numpy as np

_POW10_U = np.array([10 ** k for k in range(20)], dtype=np.uint64)
_POW10_LD_EXP = np.arange(-400, 401)
with np.errstate(over="ignore", under="ignore"):
    _POW10_LD = np.power(np.longdouble(10), _POW10_LD_EXP.astype(np.longdouble))
_LD_EXTENDED = np.finfo(np.longdouble).nmant >= 63


@dataclass
class Cells:
    """One byte string per row: bytes ``start[i] : start[i] + lens[i]`` of row i of ``chars``
    (rows × width, or 1 × width for the same bytes on every row)."""

    chars: np.ndarray
    lens: np.ndarray
    start: Union[np.ndarray, int] = 0
    nul: bool = False
    """Some cell holds a NUL byte (text never does; :func:`join_rows` pads with NULs)."""

    def masked(self, keep: np.ndarray) -> "Cells":
        """The same cells, empty where ``keep`` is False."""
        return Cells(self.chars, np.where(keep, self.lens, 0), self.start, self.nul)

    def take(self, rows) -> "Cells":
        """The cells of ``rows`` (indices or a slice), in that order."""
        chars = self.chars if len(self.chars) == 1 else self.chars[rows]
        start = self.start if np.ndim(self.start) == 0 else np.asarray(self.start)[rows]
        return Cells(chars, self.lens[rows], start, self.nul)

    def compact(self) -> "Cells":
        """The same cells in less memory (kept whole by :func:`shared_columns`)."""
        if np.ndim(self.start) or not len(self.lens) or self.lens.max() > 255:
            return self
        chars = self.chars if len(self.chars) == 1 else \
            np.ascontiguousarray(self.chars[:, :int(self.lens.max())])
        return Cells(chars, self.lens.astype(np.uint8), 0, self.nul)


Field = List[Cells]
"""A column's text: the concatenation of its pieces, row by row."""
Piece = Union[Cells, bytes, str]


def masked(field: Field, keep: np.ndarray) -> Field:
    """``field`` with every piece (literal text too) empty where ``keep`` is False."""
    return [(literal(c, len(keep)) if isinstance(c, (str, bytes)) else c).masked(keep)
            for c in field]


def literal(text: Union[str, bytes], n: int) -> Cells:
    """``text`` on each of ``n`` rows."""
    b = text.encode() if isinstance(text, str) else bytes(text)
    return Cells(np.frombuffer(b, np.uint8).reshape(1, len(b)), np.full(n, len(b), np.int64),
                 0, b"\0" in b)


def from_strings(codes: np.ndarray, texts: Sequence[Union[str, bytes]]) -> Cells:
    """Row i is ``texts[codes[i]]`` (a few distinct texts shared by many rows)."""
    enc = [t.encode() if isinstance(t, str) else bytes(t) for t in texts]
    w = max([len(t) for t in enc] + [1])
    table = np.zeros((len(enc), w), np.uint8)
    for k, t in enumerate(enc):
        table[k, :len(t)] = np.frombuffer(t, np.uint8)
    lens = np.array([len(t) for t in enc], np.int64)
    codes = np.asarray(codes, np.int64)
    return Cells(table[codes], lens[codes], 0, any(b"\0" in t for t in enc))


def choice(flags: np.ndarray, if_true: str, if_false: str) -> Field:
    """``if_true`` where ``flags`` else ``if_false`` (e.g. booleans)."""
    return [from_strings(np.asarray(flags, bool).astype(np.int64), [if_false, if_true])]


def strings(values, quote=None) -> Field:
    """Text values; ``quote`` (optional) maps each distinct text to its written form (JSON or
    XML escaping), so it runs once per distinct value, not per row."""
    values = np.asarray(values)
    uniq, inv = np.unique(values.astype(str), return_inverse=True)
    texts = [quote(u) if quote else u for u in uniq.tolist()]
    return [from_strings(inv.reshape(-1), texts)]


def ascii_fixed(values: np.ndarray) -> Field:
    """An array of ASCII strings (e.g. ISO-8601 times), without per-value work."""
    b = np.asarray(values).astype("S")
    w = max(b.dtype.itemsize, 1)
    chars = np.frombuffer(b.tobytes(), np.uint8).reshape(len(b), w) if len(b) else \
        np.zeros((0, w), np.uint8)
    return [Cells(chars, np.count_nonzero(chars, axis=1).astype(np.int64))]


def utc_cells(epoch, time_s) -> Field:
    """ISO-8601 UTC text of ``epoch + time_s`` (:func:`formats._io.iso_utc`; empty where the
    time is not finite), made once per run of equal times (a dwell's reports share its time)."""
    from ._io import iso_utc
    t = np.asarray(time_s, dtype=np.float64)
    runs = _repeats(t)
    if runs is not None:
        return _expand(ascii_fixed(iso_utc(epoch, t[runs[0]])), runs[1])
    return ascii_fixed(iso_utc(epoch, t))


_GROUPS = np.frombuffer(b"".join(f"{k:03d}".encode() for k in range(1000)), "V3")
"""The three ASCII digits of 0..999, one 3-byte item each (a whole group per gather)."""


def _digits(mag: np.ndarray, width: int) -> np.ndarray:
    """Right-aligned decimal digits (ASCII) of unsigned integers, zero-padded to ``width``
    (<= 21): three digits at a time through a table."""
    ng = -(-width // 3)
    g = np.empty((len(mag), ng), np.intp)
    r = mag.astype(np.uint64)
    thousand = np.uint64(1000)
    for j in range(ng - 1, -1, -1):                 # least significant group last
        q = r // thousand
        g[:, j] = r - q * thousand
        r = q
    chars = _GROUPS[g].view(np.uint8).reshape(len(mag), 3 * ng)
    return chars[:, 3 * ng - width:]


def _count_digits(mag: np.ndarray, most: int) -> np.ndarray:
    """Decimal digits of each unsigned integer (at least 1, at most ``most``)."""
    return np.searchsorted(_POW10_U[1:most], mag, side="right").astype(np.int64) + 1


_MINUS_CELL = np.frombuffer(b"-", np.uint8).reshape(1, 1)


def _repeats(values: np.ndarray):
    """Where a column repeats its values in runs (a dwell's time on each of its reports, a
    constant height): (first row of each run, run number of each row), else None.  Runs are
    told apart by their bits, so 0.0 and -0.0 differ and NaNs of one pattern are one run."""
    n = len(values)
    if n < 64:
        return None
    bits = values.view(np.int64) if values.dtype.itemsize == 8 else values
    head = np.empty(n, bool)
    head[0] = True
    np.not_equal(bits[1:], bits[:-1], out=head[1:])
    if np.count_nonzero(head) > n // 2:      # mostly distinct: formatting twice as few rows
        return None                          # would not pay for the gather
    return np.flatnonzero(head), np.cumsum(head) - 1


def _expand(field: Field, run: np.ndarray) -> Field:
    return [c.take(run) for c in field]


SHARED_MAX_ROWS = 1 << 18
SHARED_MAX_VALUES = 4_000_000
_LOCAL = threading.local()          # the active shared_columns of each thread


def _active() -> Optional[dict]:
    return getattr(_LOCAL, "shared", None)


@contextmanager
def shared_columns(max_values: int = SHARED_MAX_VALUES) -> Iterator[None]:
    """Inside the block, a column given whole to :func:`float_cells` / :func:`int_cells` with
    ``rows`` is formatted once and its text reused by every later call (the XML, CSV and
    GeoJSON of one table write the same numbers).  Memory stays bounded: only columns of at
    most :data:`SHARED_MAX_ROWS` rows are kept, at most ``max_values`` values in all (about 25
    bytes each); others are formatted a block at a time as without the block.  The columns must
    not change inside the block (they are known by identity).  The block holds for the thread
    that opens it."""
    outer = _active()
    _LOCAL.shared = {"room": int(max_values), "columns": {}}
    try:
        yield
    finally:
        _LOCAL.shared = outer


def _shared(kind: str, values, make):
    """The whole-column text of ``values`` (``make(values)``) kept by :func:`shared_columns`,
    or None (no block active, or the column does not fit)."""
    shared = _active()
    if shared is None or not isinstance(values, np.ndarray) or values.ndim != 1:
        return None
    columns = shared["columns"]
    hit = columns.get((kind, id(values)))
    if hit is not None and hit[0] is values:
        return hit[1]
    if len(values) > min(SHARED_MAX_ROWS, shared["room"]):
        return None
    text = make(values)
    columns[(kind, id(values))] = (values, text)       # holding values keeps its id unique
    shared["room"] -= len(values)
    return text


def int_cells(values, rows=None) -> Field:
    """Decimal integers (any int64, unsigned up to 2^64 - 1); of ``values[rows]`` when ``rows``
    (indices or a slice) is given, the column's text shared within :func:`shared_columns`."""
    if rows is not None:
        whole = _shared("int", values, lambda v: [c.compact() for c in _int_text(v)])
        if whole is not None:
            return [c.take(rows) for c in whole]
        values = np.asarray(values)[rows]
    return _int_text(values)


def _int_text(values) -> Field:
    v = np.asarray(values)
    if v.dtype.kind not in "iu":
        v = v.astype(np.int64)
    runs = _repeats(v)
    if runs is not None:                     # e.g. a dwell's id on each of its reports
        return _expand(_int_text(v[runs[0]]), runs[1])
    if v.dtype.kind == "u":
        mag, neg = v.astype(np.uint64), np.zeros(len(v), bool)
    else:
        v = v.astype(np.int64)
        neg = v < 0
        mag = v.astype(np.uint64)
        mag[neg] = ~mag[neg] + np.uint64(1)             # two's complement: |int64 min| too
    nd = _count_digits(mag, 20)
    w = int(nd.max()) if len(nd) else 1
    right = _digits(mag, w)
    if np.all(nd == w):                          # e.g. ids of one magnitude: already aligned
        return [Cells(_MINUS_CELL, neg.astype(np.int64)), Cells(right, nd)]
    left = np.zeros((len(mag), w), np.uint8)
    for k in np.unique(nd).tolist():             # left-align, a group of equal length at a time
        r = np.flatnonzero(nd == k)
        left[r, :k] = right[r, w - k:]
    return [Cells(_MINUS_CELL, neg.astype(np.int64)), Cells(left, nd)]


_EXP_TEXT = [f"e{k:+03d}" for k in range(-400, 401)]          # repr's exponents: e-05, e+16
_EXP_CELLS = from_strings(np.arange(801), _EXP_TEXT)


def _proof(ai: np.ndarray):
    """(digits, decimal exponent, proven) of positive normal doubles: the first of 15, 16, 17
    significant digits whose decimal D = m 10^(e-p+1) lies within 0.99 half-gaps of x, decided
    in extended precision (module docstring)."""
    n = len(ai)
    mant = np.zeros(n, np.uint64)
    e10 = np.zeros(n, np.int64)
    al = ai.astype(np.longdouble)
    e = np.floor(np.log10(ai)).astype(np.int64)
    e -= al < _POW10_LD[e + 400]                           # log10 rounded up: one less
    e += al >= _POW10_LD[e + 401]                          # rounded down: one more
    with np.errstate(over="ignore"):
        up = np.nextafter(ai, np.inf) - ai
    down = ai - np.nextafter(ai, 0.0)
    tol = (np.minimum(up, down) * 0.495).astype(np.longdouble)
    todo = np.arange(n)
    for p in (15, 16, 17):
        if not len(todo):
            break
        k = todo
        scale = _POW10_LD[p - 1 - e[k] + 400]
        prod = al[k] * scale                               # |x| 10^(p-1-e), 64-bit mantissa
        m = np.rint(prod)
        # D = m 10^(e-p+1) reads back as x if |D - x| < the half-gap: compared scaled
        good = np.abs(m - prod) < tol[k] * scale
        ek = e[k]
        carry = good & (m >= _POW10_LD[p + 400])           # rounded up to 10^p: 1 0...0
        if carry.any():
            m[carry] = m[carry] / 10
            ek = ek + carry
        g = k[good]
        mant[g] = m[good].astype(np.uint64)
        e10[g] = ek[good]
        todo = k[~good]
    proven = np.ones(n, bool)
    proven[todo] = False
    return mant, e10, proven


# 10^k (k = -400..400) as the sum of two doubles (exactly the extended-precision value), each
# split in halves of 26 bits for exact products (Dekker); used for -270 <= e <= 290 only
with np.errstate(over="ignore", invalid="ignore"):
    _P10_HI = _POW10_LD.astype(np.float64)
    _P10_LO = (_POW10_LD - _P10_HI.astype(np.longdouble)).astype(np.float64)
    _P10_HI_H = _P10_HI * 134217729.0 - (_P10_HI * 134217729.0 - _P10_HI)
    _P10_HI_L = _P10_HI - _P10_HI_H
_PROOF_ROWS = 1 << 13
_SCREEN_MARGIN = {p: 10.0 ** p * 2.0 ** -63 + 1e-12 for p in (15, 16, 17)}


def _proof_fast(ai: np.ndarray):
    """:func:`_proof`'s answer in double precision where it is certain: (digits, exponent,
    decided).  The scaled value |x| 10^(p-1-e) is formed exactly as a double-double (Dekker's
    product by 10^k held as two doubles), so its distance r to the nearest integer is known to
    1e-14, while the extended-precision product that :func:`_proof` rounds lies within
    10^p 2^-64 of it: where r is further than that margin from the tolerance (and from 1/2),
    both decide alike; the other values (a few in a hundred) are left undecided."""
    n = len(ai)
    mant = np.zeros(n, np.uint64)
    e10 = np.zeros(n, np.int64)
    done = np.zeros(n, bool)
    e = np.floor(np.log10(ai)).astype(np.int64)
    live = (e >= -270) & (e <= 290)
    e = np.clip(e, -270, 290)
    e -= (ai - _P10_HI[e + 400]) < _P10_LO[e + 400]       # ai < 10^e, as _proof compares
    e += (ai - _P10_HI[e + 401]) >= _P10_LO[e + 401]
    with np.errstate(over="ignore", invalid="ignore"):   # beyond the live range: unused
        return _screen(ai, e, live, mant, e10, done)


def _screen(ai, e, live, mant, e10, done):
    up = np.nextafter(ai, np.inf) - ai
    down = ai - np.nextafter(ai, 0.0)
    tol = np.minimum(up, down) * 0.495
    split = ai * 134217729.0
    a_h = split - (split - ai)
    a_l = ai - a_h
    j = 413 - e                                            # + 1: 10^(14-e), p = 15
    for p in (15, 16, 17):
        j += 1                                             # 10^(p-1-e): index p-1-e+400
        s_h, s_l, s_hh, s_hl = _P10_HI[j], _P10_LO[j], _P10_HI_H[j], _P10_HI_L[j]
        p1 = ai * s_h
        err = ((a_h * s_hh - p1) + a_h * s_hl + a_l * s_hh) + a_l * s_hl   # ai s_h - p1, exact
        n1 = np.rint(p1)
        f = (p1 - n1) + (err + ai * s_l)
        k = np.rint(f)
        r = np.abs(f - k)
        big = tol * s_h
        margin = _SCREEN_MARGIN[p]
        good = live & (r < big - margin) & (r < 0.5 - margin)
        m = n1.astype(np.int64) + k.astype(np.int64)
        carry = m >= 10 ** p                               # rounded up to 10^p: 1 0...0
        np.floor_divide(m, 10, out=m, where=carry)
        np.copyto(mant, m.view(np.uint64), where=good)
        np.copyto(e10, e + carry, where=good)
        done |= good
        live &= r > big + margin
        if not live.any():
            break
    return mant, e10, done


@dataclass
class _Floats:
    """Text of float64 values with the special ones apart, to be written per format: ``codes``
    0 = a number (in ``field``), 1 NaN, 2 inf, 3 -inf, 4 0.0, 5 -0.0, 6 + k ``other[k]``."""

    field: Field
    codes: Optional[np.ndarray] = None
    other: Sequence[str] = ()

    def take(self, rows) -> "_Floats":
        return _Floats([c.take(rows) for c in self.field],
                       None if self.codes is None else self.codes[rows], self.other)

    def compact(self) -> "_Floats":
        codes = self.codes
        if codes is not None and len(self.other) < 250:
            codes = codes.astype(np.uint8)
        return _Floats([c.compact() for c in self.field], codes, self.other)

    def text(self, nan: str, inf: str) -> Field:
        if self.codes is None:
            return list(self.field)
        neg_inf = inf if inf == "null" else "-" + inf
        return self.field + [from_strings(self.codes, ["", nan, inf, neg_inf, "0.0", "-0.0",
                                                       *self.other])]


def float_cells(values, nan: str = "nan", inf: str = "inf", rows=None) -> Field:
    """Decimal text of float64 values that reads back exactly (module docstring).  NaN is
    ``nan``, ±inf ``inf``/``-inf`` (give ``nan="null", inf="null"`` for JSON, where the sign is
    dropped too).  With ``rows`` (indices or a slice): the text of ``values[rows]``, the
    column's text shared within :func:`shared_columns`."""
    if rows is not None:
        whole = _shared("float", values, lambda v: _float_text(v).compact())
        if whole is not None:
            return whole.take(rows).text(nan, inf)
        values = np.asarray(values)[rows]
    return _float_text(values).text(nan, inf)


def _float_text(values) -> _Floats:
    x = np.asarray(values, dtype=np.float64)
    runs = _repeats(x)
    if runs is not None:                     # e.g. a dwell's time on each of its reports
        return _float_text(x[runs[0]]).take(runs[1])
    n = len(x)
    a = np.abs(x)
    normal = np.isfinite(x) & (a >= np.finfo(np.float64).tiny)
    ok = np.zeros(n, bool)
    mant = np.zeros(n, np.uint64)
    e10 = np.zeros(n, np.int64)
    if _LD_EXTENDED and normal.any():
        idx = np.flatnonzero(normal)
        for c0 in range(0, len(idx), _PROOF_ROWS):   # temporaries that stay in the cache
            sub = idx[c0:c0 + _PROOF_ROWS]
            ai = a[sub]
            m_i, e_i, done = _proof_fast(ai)
            rest = np.flatnonzero(~done)         # beyond the screen: the proof itself
            if len(rest):
                m_i[rest], e_i[rest], done[rest] = _proof(ai[rest])
            mant[sub], e10[sub], ok[sub] = m_i, e_i, done
    # trailing zeros off: mant = d1 d2 ... d_nd (d_nd != 0)
    ten = np.uint64(10)
    cand = np.flatnonzero(ok & (mant % ten == 0))
    while len(cand):                             # most values have none: one pass
        mant[cand] //= ten
        cand = cand[mant[cand] % ten == 0]
    nd = _count_digits(mant, 18)
    left = _digits(mant * _POW10_U[17 - nd], 17)   # d1 .. d_nd, then '0's: left-aligned
    sci = ok & ((e10 < -4) | (e10 >= 16))
    low = ok & ~sci & (e10 < 0)
    field = [Cells(_MINUS_CELL, (ok & (x < 0)).astype(np.int64)),
             _body(left, nd, e10, ok, sci, low)]
    if sci.any():
        code = np.clip(e10 + 400, 0, 800)
        field.append(Cells(_EXP_CELLS.chars[code], np.where(sci, _EXP_CELLS.lens[code], 0)))
    special = ~ok
    if not special.any():
        return _Floats(field)
    # zeros, NaN, inf (masks), and what the proof did not cover (repr)
    codes = np.select([np.isnan(x), x == np.inf, x == -np.inf, (x == 0) & ~np.signbit(x),
                       x == 0], [1, 2, 3, 4, 5], 0)
    other = np.flatnonzero(special & (codes == 0))
    texts: list = []
    if len(other):
        uniq, inv = np.unique(np.array([repr(v) for v in x[other].tolist()]),
                              return_inverse=True)
        codes[other] = inv.reshape(-1) + 6
        texts = uniq.tolist()
    return _Floats(field, codes, texts)


_W = 22                                         # widest body: "0.000" + 17 digits


def _body(left, nd, e10, ok, sci, low) -> Cells:
    """repr's layout of the digits ``left`` (d1..d_nd then '0's) of |x| = d1.d2... × 10^e10,
    without the exponent: positional for -4 <= e10 < 16, else d1[.d2...d_nd]."""
    n = len(nd)
    chars = np.full((n, _W), 48, np.uint8)
    # a '.' after the first L digits: positional e10 >= 0 (L = e10 + 1), scientific (L = 1);
    # rows grouped by L, each group copied as two blocks
    L = np.where(sci, 1, np.clip(e10 + 1, 1, 17))
    hi = ok & ~low
    lens = np.where(sci, np.where(nd > 1, nd + 1, 1), L + 1 + np.maximum(nd - L, 1))
    for k in np.unique(L[hi]).tolist():
        r = np.flatnonzero(hi & (L == k))
        block = left[r]
        sub = np.empty((len(r), 18), np.uint8)
        sub[:, :k] = block[:, :k]
        sub[:, k] = ord(".")
        sub[:, k + 1:] = block[:, k:]
        chars[r, :18] = sub
    for z in range(4):                           # 0.000ddd: e10 = -1 .. -4
        r = np.flatnonzero(low & (e10 == -1 - z))
        if len(r):
            sub = np.full((len(r), _W), 48, np.uint8)
            sub[:, 1] = ord(".")
            sub[:, 2 + z:2 + z + 17] = left[r]
            chars[r] = sub
            lens[r] = 2 + z + nd[r]
    return Cells(chars, np.where(ok, lens, 0).astype(np.int64))


def join(pieces: Sequence[Union[Piece, Field]], n: int) -> bytes:
    """The bytes of ``n`` rows, each the concatenation of ``pieces`` (Cells, fields, or bytes
    that are the same on every row)."""
    return join_rows(pieces, n)[0]


def join_rows(pieces: Sequence[Union[Piece, Field]], n: int):
    """(bytes of ``n`` rows as :func:`join`, byte offset of each row and of the end)."""
    if n == 0:
        return b"", np.zeros(1, np.int64)
    # (chars, lens or None for literal text, start) per piece; consecutive literals merged
    parts: list = []
    text = b""
    nul = False
    for p in (q for piece in pieces for q in (piece if isinstance(piece, list) else [piece])):
        if isinstance(p, (bytes, str)):
            text += p.encode() if isinstance(p, str) else p
            continue
        if text:
            parts.append((np.frombuffer(text, np.uint8)[None, :], None, 0))
            text = b""
        if not p.lens.any():                    # e.g. no negative values: no sign piece
            continue
        st = np.asarray(p.start)
        lo = int(st.min()) if st.ndim else int(st)
        hi = int((st + p.lens).max())
        parts.append((p.chars[:, lo:hi], p.lens, st - lo if st.ndim else 0))
        nul |= p.nul
    if text:
        parts.append((np.frombuffer(text, np.uint8)[None, :], None, 0))
    row_len = np.zeros(n, np.int64)
    for chars, lens, _ in parts:
        row_len += chars.shape[1] if lens is None else lens
    offsets = np.concatenate([[0], np.cumsum(row_len)])
    if not parts:
        return b"", offsets
    nul |= any(lens is None and not chars.all() for chars, lens, _ in parts)
    # every piece side by side in one matrix, NUL where a row does not use a byte, then the
    # NULs dropped (text holds none; else a mask of the bytes used)
    width = sum(chars.shape[1] for chars, _, _ in parts)
    big = np.empty((n, width), np.uint8)
    use = np.ones((n, width), bool) if nul else None
    o = 0
    for chars, lens, first in parts:
        w = chars.shape[1]
        if lens is None or (np.ndim(first) == 0 and bool(np.all(lens == w))):
            big[:, o:o + w] = chars
        elif np.ndim(first) == 0:               # a prefix of each row: masked by a table
            keep = np.take(_prefix_masks(w), lens, axis=0)
            if use is not None:
                use[:, o:o + w] = keep != 0
            big[:, o:o + w] = np.bitwise_and(chars, keep, out=keep)
        else:
            col = np.arange(w)[None, :]
            keep = (col >= first[:, None]) & (col < first[:, None] + lens[:, None])
            big[:, o:o + w] = np.where(keep, chars, np.uint8(0))
            if use is not None:
                use[:, o:o + w] = keep
        o += w
    flat = big.reshape(-1)
    if use is None:
        return flat[flat != 0].tobytes(), offsets
    return flat[use.reshape(-1)].tobytes(), offsets


_PREFIX_MASKS: dict = {}


def _prefix_masks(w: int) -> np.ndarray:
    """Row k: 0xFF on the first k of ``w`` bytes, 0 after (k = 0 .. w)."""
    m = _PREFIX_MASKS.get(w)
    if m is None:
        m = _PREFIX_MASKS[w] = np.where(np.arange(w)[None, :] < np.arange(w + 1)[:, None],
                                        255, 0).astype(np.uint8)
    return m


def contiguous(rows: np.ndarray):
    """``rows`` as a slice when they are consecutive increasing indices (a table already in
    the order written: its columns' cells are then views, not copies), else ``rows``."""
    rows = np.asarray(rows)
    if len(rows) and rows[-1] - rows[0] == len(rows) - 1 and \
            (len(rows) == 1 or bool(np.all(rows[1:] - rows[:-1] == 1))):
        return slice(int(rows[0]), int(rows[-1]) + 1)
    return rows


def row_chunks(n: int, rows: int = 1 << 15):
    """(start, stop) of consecutive row ranges of at most ``rows`` rows (bounded memory)."""
    return [(a, min(a + rows, n)) for a in range(0, n, rows)]
