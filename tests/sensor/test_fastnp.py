"""The fast forms of numpy operations give numpy's values bit for bit (gmtiflow.sensor.fastnp)."""
import numpy as np
import pytest

from gmtiflow.sensor import fastnp
from gmtiflow.sensor.rcs import load_table


def _same(a, b):
    a, b = np.asarray(a), np.asarray(b)
    return (a.shape == b.shape and np.array_equal(a, b, equal_nan=True)
            and np.array_equal(np.signbit(a), np.signbit(b)))


def _edges(p):
    near = [np.nextafter(v, d) for v in (0.0, p, -p, 2 * p, -2 * p) for d in (-np.inf, np.inf)]
    return np.array([0.0, -0.0, p, -p, 2 * p, -2 * p, 3 * p, np.inf, -np.inf, np.nan, 1e300,
                     -1e300, 5e-324, -5e-324, 1e-20, -1e-20] + near)


@pytest.mark.parametrize("period", [60.0, 2 * np.pi, 0.7, 1e-3, 1e10])
def test_mod_is_np_mod(period):
    g = np.random.default_rng(1)
    x = np.concatenate([g.uniform(-5 * period, 5 * period, 200_000),
                        g.uniform(-period, 2 * period, 200_000), g.normal(0, 1e-300, 100),
                        _edges(period)])
    with np.errstate(invalid="ignore"):
        assert _same(fastnp.mod(x, period), np.mod(x, period))


def test_ratio_is_masked_division():
    g = np.random.default_rng(2)
    num = g.normal(size=1000)
    den = np.abs(g.normal(size=1000))
    assert _same(fastnp.ratio(num, den), num / den)
    den[::7] = 0.0
    den[3] = np.nan
    want = np.divide(num, den, out=np.full_like(num, 2.0), where=den > 0)
    assert _same(fastnp.ratio(num, den, fill=2.0), want)


def _tables():
    g = np.random.default_rng(3)
    fine = np.sort(g.choice(np.arange(0, 360, 0.001), 5000, replace=False))
    return [load_table("sensor/rcs/truck.csv"),
            (np.radians(fine), g.normal(10, 5, fine.size)),
            (np.radians([0.0, 180.0]), np.array([1.0, 2.0])),
            (np.radians([10.0, 20.0, 350.0]), np.array([1.0, 1e300, -1e300])),   # inf slopes
            (np.radians([5.0, 90.0, 200.0]), np.array([1.0, np.nan, 3.0]))]


@pytest.mark.parametrize("table", _tables())
def test_periodic_interp_is_np_interp(table):
    xp, fp = table
    period = 2 * np.pi
    g = np.random.default_rng(4)
    knots = np.concatenate([xp, xp + period, xp - period, np.nextafter(xp, 10),
                            np.nextafter(xp, -10)])
    x = np.concatenate([g.uniform(-3 * np.pi, 5 * np.pi, 200_000), knots,
                        [0.0, -0.0, period, -period, -1e-20, 1e-20, 1e5, -1e5]])
    f = fastnp.PeriodicInterp(xp, fp, period)
    assert _same(f(x), np.interp(x, xp, fp, period=period))
    odd = np.array([np.nan, np.inf, 1.0])
    with np.errstate(invalid="ignore"):
        assert _same(f(odd), np.interp(odd, xp, fp, period=period))


def test_hypot_with_a_zero_is_the_magnitude():
    """C99 F.9.4.3, which the candidate search's speed relies on (pairs._speed skips the
    outer hypot when every vz is 0)."""
    g = np.random.default_rng(6)
    x = np.concatenate([g.normal(0, 30, 100_000), [0.0, -0.0, np.inf, 5e-324, 1e308]])
    h = np.hypot(x, x[::-1])
    for zero in (0.0, -0.0):
        assert _same(np.hypot(h, zero), h)
        assert _same(np.hypot(x, zero), np.abs(x))


def test_beam_position_search_is_searchsorted():
    """pairs._searchsorted_uniform (the beams' position from their step, checked) gives
    np.searchsorted's positions, also for uneven steps, knots and non-finite values."""
    from gmtiflow.sensor.pairs import _searchsorted_uniform
    g = np.random.default_rng(7)
    for n in (2, 3, 14, 50):
        for u in (np.sin(np.linspace(-0.17, 0.17, n)), np.sort(g.uniform(-1, 1, n))):
            s = np.concatenate([g.uniform(-2.5, 2.5, 20_000), u, np.nextafter(u, 5),
                                np.nextafter(u, -5), [np.nan, np.inf, -np.inf, 2.0, -2.0]])
            assert np.array_equal(_searchsorted_uniform(u, s), np.searchsorted(u, s))


def test_fallback_rows_are_the_first_least_active_row_of_each_group():
    """pairs._nearest_rows (only the groups without a footprint row are read) gives the rows
    of the whole-array form it replaces: the first active row at the group's least distance
    (ties, inactive rows, 1e300 and NaN distances included)."""
    from gmtiflow.sensor.pairs import _first_in_group, _nearest_rows
    g = np.random.default_rng(8)
    count = g.integers(1, 6, 5000)
    starts = np.cumsum(count) - count
    group = np.repeat(np.arange(count.size), count)
    dist = np.round(g.uniform(0, 0.05, count.sum()), 3)        # rounded: many ties
    dist[g.random(dist.size) < 0.1] = 1e300
    dist[g.random(dist.size) < 0.01] = np.nan
    active = g.random(dist.size) < 0.8
    wanted = g.random(count.size) < 0.5
    gmin = np.minimum.reduceat(dist, starts)
    first = _first_in_group(group, active & (dist <= gmin[group]))
    expected = np.flatnonzero(wanted[group] & first)
    assert np.array_equal(_nearest_rows(dist, active, starts, np.flatnonzero(wanted)), expected)
    assert _nearest_rows(dist, active, starts, np.zeros(0, np.int64)).size == 0
