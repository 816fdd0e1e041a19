"""Column-wise number text (formats._text), used by the CSV, XML and GeoJSON writers: every
float64 reads back exactly, in repr's layout; integers and the ragged join are exact."""
from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from gmtiflow.formats import _text

EDGES = [0.0, -0.0, 5e-324, -2.2250738585072014e-308, 2.2250738585072014e-308,
         1.7976931348623157e308, -1.7976931348623157e308, 0.1, 0.3, 1 / 3, 100.0, 1e16,
         9999999999999998.0, 1e15, 1e-4, 1e-5, 0.00012345, 2.5, -7.0, 43.7, 7.42, 2.0 ** 53,
         123456789012345680.0, 9.999999999999999e22, 1e23, 0.1 + 0.2]


def lines(field, n) -> list:
    return _text.join([field, b"\n"], n).decode().split("\n")[:-1]


def test_edge_values_read_back_exactly_in_reprs_layout():
    x = np.array(EDGES + [np.nan, np.inf, -np.inf])
    got = lines(_text.float_cells(x), len(x))
    back = np.array([float(s) for s in got])
    np.testing.assert_array_equal(back, x)
    assert np.array_equal(np.signbit(back), np.signbit(x))
    # short decimals come out as repr writes them (a value that lies almost half-way between
    # two doubles, such as 1e23, may get 16 or 17 digits instead)
    nice = [0.0, -0.0, 0.1, 0.3, 100.0, 1e16, 1e15, 1e-4, 1e-5, 0.00012345, 2.5, -7.0, 43.7,
            7.42, 2.0 ** 53, 1e100, -1.2345e-100, 12345.678]
    assert lines(_text.float_cells(np.array(nice)), len(nice)) == [repr(v) for v in nice]


@settings(max_examples=60, deadline=None, derandomize=True, database=None)
@given(arrays(np.float64, st.integers(0, 300), elements=st.floats(allow_nan=True,
                                                                    allow_infinity=True)))
def test_any_float64_reads_back_exactly(x):
    got = lines(_text.float_cells(x), len(x))
    back = np.array([float(s) for s in got], dtype=np.float64)
    assert np.array_equal(back, x, equal_nan=True)
    num = ~np.isnan(x)                                   # NaN's sign bit is not carried
    assert np.array_equal(np.signbit(back[num]), np.signbit(x[num]))


def test_json_text_writes_null_for_nan_and_inf():
    x = np.array([1.5, np.nan, np.inf, -np.inf])
    assert lines(_text.float_cells(x, nan="null", inf="null"), 4) == ["1.5", "null", "null",
                                                                      "null"]


def test_integers_and_masks_and_literals_join_row_by_row():
    i = np.array([0, -1, -2 ** 63, 2 ** 63 - 1, 10, 99], np.int64)
    assert lines(_text.int_cells(i), 6) == [str(v) for v in i.tolist()]
    u = np.array([0, 2 ** 64 - 1], np.uint64)
    assert lines(_text.int_cells(u), 2) == ["0", str(2 ** 64 - 1)]
    keep = np.array([True, False, True])
    text, off = _text.join_rows(["<", _text.masked(_text.int_cells(np.arange(3)) + [",x"], keep),
                                 _text.choice(keep, "T", "F"), ">"], 3)
    assert text == b"<0,xT><F><2,xT>"
    assert off.tolist() == [0, 6, 9, 15]
    assert lines(_text.strings(np.array(['a"b', "c", 'a"b']), quote=repr), 3) == \
        ["'a\"b'", "'c'", "'a\"b'"]


def test_random_columns_match_float_parsing_at_scale():
    rng = np.random.default_rng(7)
    x = rng.normal(size=20000) * 10.0 ** rng.integers(-40, 40, 20000)
    back = np.array(lines(_text.float_cells(x), len(x)), dtype=np.float64)
    np.testing.assert_array_equal(back, x)


def test_without_extended_precision_every_value_falls_back_to_repr(monkeypatch):
    """Where numpy's longdouble is a plain double the proof is off: repr, value by value."""
    monkeypatch.setattr(_text, "_LD_EXTENDED", False)
    x = np.array(EDGES + [np.nan, -np.inf])
    assert lines(_text.float_cells(x), len(x)) == [repr(v) for v in x.tolist()]


def test_runs_of_equal_values_are_formatted_once_with_their_own_signs():
    """A column that repeats its values (a dwell's time on each report) is formatted per run;
    0.0 and -0.0 compare equal but are different runs."""
    x = np.repeat(np.array([0.0, -0.0, 0.0, 1.5, np.nan, -np.inf, 1e-300, -7.25]), 40)
    assert lines(_text.float_cells(x), len(x)) == [repr(v) for v in x.tolist()]
    i = np.repeat(np.array([3, -3, 0, 2 ** 63 - 1, -2 ** 63]), 30)
    assert lines(_text.int_cells(i), len(i)) == [str(v) for v in i.tolist()]


def test_shared_columns_give_each_formats_text_of_any_rows():
    """Within shared_columns a column is formatted once, whole, and its rows taken from that:
    the text is the same as formatting the rows alone, for each format's NaN/inf words."""
    rng = np.random.default_rng(3)
    x = rng.normal(size=3000) * 10.0 ** rng.integers(-8, 20, 3000)
    x[rng.random(3000) < 0.2] = np.nan
    x[rng.random(3000) < 0.1] = -np.inf
    x[rng.random(3000) < 0.1] = -0.0
    ids = rng.integers(-10 ** 9, 10 ** 9, 3000)
    picks = [rng.permutation(3000)[:1000], slice(17, 2500), np.arange(3000)]
    with _text.shared_columns():
        for rows in picks:
            for words in ({}, {"nan": "null", "inf": "null"}, {"inf": "INF"}):
                want = lines(_text.float_cells(x[rows], **words), len(x[rows]))
                assert lines(_text.float_cells(x, rows=rows, **words), len(x[rows])) == want
            assert lines(_text.int_cells(ids, rows), len(ids[rows])) == \
                [str(v) for v in ids[rows].tolist()]
        assert len(_text._active()["columns"]) == 2           # each column formatted once


def test_shared_columns_keep_bounded_memory(monkeypatch):
    """Columns longer than SHARED_MAX_ROWS, or beyond the budget of values, are not kept."""
    monkeypatch.setattr(_text, "SHARED_MAX_ROWS", 500)
    small, big = np.arange(400.0) + 0.5, np.arange(600.0) + 0.25
    with _text.shared_columns(max_values=700):
        assert lines(_text.float_cells(big, rows=slice(0, 3)), 3) == ["0.25", "1.25", "2.25"]
        _text.float_cells(small, rows=slice(0, 3))
        _text.float_cells(small + 1, rows=slice(0, 3))               # over the budget
        assert [k[0] for k in _text._active()["columns"]] == ["float"]
        assert _text._active()["room"] == 300
    assert _text._active() is None


def test_join_keeps_nul_bytes_of_the_text():
    """join_rows pads with NUL bytes and drops them; text that holds a NUL keeps it."""
    keep = np.array([True, False, True])
    for text in (b"a\0", b"ab"):
        cells = _text.from_strings(np.array([0, 1, 0]), [text, b"x"])
        got = _text.join([_text.masked([cells, b"\0" if text == b"ab" else b","], keep),
                          _text.float_cells(np.array([1.5, -2.0, 1e-7])), b"\n"], 3)
        sep = b"\0" if text == b"ab" else b","
        assert got == text + sep + b"1.5\n-2.0\n" + text + sep + b"1e-07\n"


def _near_decimals(rng, count):
    """Doubles at and beside p-digit decimals and their midpoints (p = 14..18): the values where
    the 15/16/17-digit decision is closest to its tolerance."""
    from decimal import Decimal, getcontext
    getcontext().prec = 60
    out = []
    for _ in range(count):
        p = int(rng.integers(14, 19))
        e = int(rng.integers(-30, 30)) if rng.random() < 0.8 else int(rng.integers(-300, 300))
        d = Decimal(int(rng.integers(10 ** (p - 1), 10 ** p)))
        if rng.random() < 0.5:
            d += Decimal(1) / 2
        x = float(d * Decimal(10) ** (e - p + 1))
        out += [x, np.nextafter(x, 0.0), np.nextafter(x, np.inf)]
    x = np.array(out)
    return x[np.isfinite(x) & (x > 2.2250738585072014e-308)]


def test_double_precision_screen_decides_as_the_extended_precision_proof():
    """Where _proof_fast decides a value's digits, they are _proof's, including values next to
    decimals and midpoints; it leaves only a small share of such values to _proof."""
    rng = np.random.default_rng(11)
    x = np.concatenate([_near_decimals(rng, 4000), np.abs(rng.normal(size=20000)) * 10.0 **
                        rng.integers(-30, 30, 20000), 2.0 ** np.arange(-1000, 1000)])
    m_fast, e_fast, done = _text._proof_fast(x)
    m, e, proven = _text._proof(x)
    assert proven[done].all()
    np.testing.assert_array_equal(m_fast[done], m[done])
    np.testing.assert_array_equal(e_fast[done], e[done])
    assert done.mean() > 0.9


def test_shared_columns_belong_to_the_thread_that_opens_them():
    import threading
    seen = []
    with _text.shared_columns():
        t = threading.Thread(target=lambda: seen.append(_text._active()))
        t.start()
        t.join()
        assert _text._active() is not None
    assert seen == [None]
