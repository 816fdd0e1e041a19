"""The sorting helpers give what the numpy calls they replace give."""
import numpy as np
import pytest

from gmtiflow.evaluate.order import count_distinct, dense_ids, lexorder, small_key_order


def test_dense_ids_is_np_unique():
    # sorted input (runs), a narrow range (bitmap) and a wide one (np.unique): one answer
    rng = np.random.default_rng(2)
    for a in (np.sort(rng.integers(-5, 50, 300)), rng.integers(-5, 50, 300),
              rng.integers(-10 ** 12, 10 ** 12, 300), np.array([7]), np.zeros(0, np.int64),
              np.array([3, 3, 3])):
        ids, idx = dense_ids(a)
        assert count_distinct(a) == len(np.unique(a))
        want_ids, want_idx = np.unique(np.asarray(a, np.int64), return_inverse=True)
        assert np.array_equal(ids, want_ids) and np.array_equal(idx, want_idx)
        assert ids.dtype == want_ids.dtype and idx.dtype == want_idx.dtype


def test_lexorder_is_np_lexsort():
    # rows in (major, minor) order (no sort), in minor order (a stable sort by major, narrow or
    # wide ids), neither, with ties and NaN: np.lexsort's order every time
    rng = np.random.default_rng(8)
    ids = np.sort(rng.integers(0, 20, 400))
    t = rng.integers(0, 5, 400).astype(float)
    wide = rng.integers(-10 ** 12, 10 ** 12, 20)[rng.integers(0, 20, 400)]
    by_t = np.argsort(t, kind="stable")
    cases = [(ids, t), (ids, np.sort(t)), (rng.permutation(ids), t), (ids[by_t], t[by_t]),
             (wide[by_t], t[by_t]), (rng.permutation(ids), np.sort(t)),
             (ids, np.where(t > 3, np.nan, t)), (ids[:1], t[:1]), (ids[:0], t[:0])]
    for major, minor in cases:
        assert np.array_equal(lexorder(major, minor), np.lexsort((minor, major)))
    order = np.lexsort((t, ids))
    assert np.array_equal(lexorder(ids[order], t[order]), np.arange(400))


def test_small_key_order_is_the_stable_sort():
    step = np.random.default_rng(3).integers(0, 7, 400)
    for n_keys in (7, 1 << 17):
        assert np.array_equal(small_key_order(step, n_keys), np.argsort(step, kind="stable"))


@pytest.mark.parametrize("side", ["left", "right"])
def test_searchsorted_within_is_a_searchsorted_per_segment(side):
    from gmtiflow.evaluate.order import searchsorted_within
    g = np.random.default_rng(3)
    lengths = g.integers(0, 40, 200)                         # empty segments too
    values = np.concatenate([
        np.sort(np.r_[g.choice(np.arange(20) * 0.5, max(k - 1, 0)),
                      np.nan if g.random() < 0.2 else 9.5])[:k]          # NaN sorts last
        for k in lengths])
    bounds = np.r_[0, np.cumsum(lengths)]
    seg = g.integers(0, len(lengths), 3000)
    lo, hi = bounds[seg], bounds[seg + 1]
    queries = g.choice(np.r_[np.arange(-2, 22) * 0.5, 3.25, np.nan, np.inf, -np.inf], 3000)
    got = searchsorted_within(values, lo, hi, queries, side=side)
    want = [a + np.searchsorted(values[a:b], q, side=side) for a, b, q in zip(lo, hi, queries)]
    assert np.array_equal(got, want)
