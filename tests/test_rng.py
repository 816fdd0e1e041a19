"""Named and counter-based random streams (DESIGN §2)."""
import numpy as np
from scipy import stats

from gmtiflow import rng


def test_named_streams_depend_only_on_seed_and_names():
    a = rng.stream(1, "truth", "vehicle", "car-1").standard_normal(5)
    b = rng.stream(1, "truth", "vehicle", "car-1").standard_normal(5)
    c = rng.stream(1, "truth", "vehicle", "car-2").standard_normal(5)
    d = rng.stream(2, "truth", "vehicle", "car-1").standard_normal(5)
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c) and not np.array_equal(a, d)


def test_pair_draws_are_pure_functions_of_key_and_counters():
    key = rng.counter_key(7, "sensor", "pd")
    dwell, vehicle = np.arange(1000), np.arange(1000) % 37
    u = rng.pair_uniform(key, dwell, vehicle)
    # the same pair gives the same draw whatever else is in the batch, and scalars broadcast
    assert np.array_equal(u[::3], rng.pair_uniform(key, dwell[::3], vehicle[::3]))
    assert rng.pair_uniform(key, 5, 5) == u[5]
    assert np.all((u > 0) & (u < 1))
    other = rng.pair_uniform(rng.counter_key(7, "sensor", "errors"), dwell, vehicle)
    assert abs(np.corrcoef(u, other)[0, 1]) < 4.5 / np.sqrt(len(u))


def test_pair_uniform_and_normal_have_their_distributions():
    n = 200_000
    key = rng.counter_key(3, "test")
    u = rng.pair_uniform(key, np.arange(n), 0)
    z = rng.pair_normal(key, np.arange(n), 0)
    # KS at alpha = 1e-4 (fixed seed: a real defect fails by a wide margin)
    assert stats.kstest(u, "uniform").pvalue > 1e-4
    assert stats.kstest(z, "norm").pvalue > 1e-4
    assert abs(z.mean()) < 4.5 / np.sqrt(n)
    assert abs(z.var() - 1.0) < 4.5 * np.sqrt(2.0 / n)


def test_counters_mixed_once_give_the_pair_draws_bit_for_bit():
    """rng.Counters (counters mixed once, several draws, a subset taken) reproduces
    pair_uniform / pair_normal exactly: the sensor's draws do not change with it."""
    g = np.random.default_rng(3)
    d = g.integers(0, 10**9, 5000)
    v = g.integers(0, 10**6, 5000)
    key, key2 = rng.counter_key(7, "a"), rng.counter_key(7, "b")
    c = rng.Counters(d, v, 4)               # a scalar channel broadcasts as in pair_uniform
    assert np.array_equal(c.uniform(key), rng.pair_uniform(key, d, v, 4))
    assert np.array_equal(c.normal(key2), rng.pair_normal(key2, d, v, 4))
    sel = g.random(5000) < 0.3
    assert np.array_equal(c.take(sel).normal(key), rng.pair_normal(key, d[sel], v[sel], 4))
    idx = np.flatnonzero(sel)[::-1]
    assert np.array_equal(c.take(idx).uniform(key2), rng.pair_uniform(key2, d[idx], v[idx], 4))


def _splitmix_reference(key, *counters):
    """pair_hash written out as the module doc defines it: h = key; for each counter c,
    h = mix(h + G + mix(c·G + G)) (wrapping uint64), mix the SplitMix64 finaliser."""
    def mix(h):
        h = (h ^ (h >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        h = (h ^ (h >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        return h ^ (h >> np.uint64(31))
    g = np.uint64(0x9E3779B97F4A7C15)
    with np.errstate(over="ignore"):
        h = np.full(np.broadcast_shapes(*(np.shape(c) for c in counters)), key, np.uint64)
        for c in counters:
            h = mix(h + g + mix(np.asarray(c, np.int64).astype(np.uint64) * g + g))
    return h


def test_pair_hash_is_the_splitmix_chain_and_mixed_counters_gather():
    """The hash equals its definition (any grouping of the wrapping additions), and counters
    mixed per distinct value (rng.mix_counter) and gathered give the same draws."""
    g = np.random.default_rng(5)
    key = rng.counter_key(11, "x")
    d, v = g.integers(0, 10**9, 3000), g.integers(0, 10**6, 3000)
    for counters in [(d,), (d, v), (5, v), (d[:40, None], v[None, :50]), (d, 2, v)]:
        assert np.array_equal(rng.pair_hash(key, *counters), _splitmix_reference(key, *counters))
    dwells, vehicles = np.unique(d[:100]), np.unique(v[:100])
    i, j = g.integers(0, dwells.size, 500), g.integers(0, vehicles.size, 500)
    gathered = rng.Counters(mixed=[rng.mix_counter(dwells)[i], rng.mix_counter(vehicles)[j]])
    assert np.array_equal(gathered.normal(key), rng.pair_normal(key, dwells[i], vehicles[j]))


def test_counters_with_a_mixed_scalar_channel_are_pair_uniform_bit_for_bit():
    """noise.draw mixes (dwell, index) once and adds each channel's mixed scalar: the same
    values as rng.pair_uniform(key, dwell, index, channel)."""
    g = np.random.default_rng(3)
    d = np.sort(g.integers(0, 10**9, 2000))
    i = g.integers(0, 40, 2000)
    key = rng.counter_key(11, "sensor", "noise_false_alarms")
    mixed = [rng.mix_counter(d), rng.mix_counter(i)]
    draws = []
    for ch in range(5):
        got = rng.Counters(mixed=mixed + [rng.mix_counter(ch)]).uniform(key)
        assert got.tobytes() == rng.pair_uniform(key, d, i, ch).tobytes()
        draws.append(got)
    assert not np.array_equal(draws[0], draws[1])        # the channel does change the draw


def test_counters_with_a_leading_table_are_the_pair_draws_bit_for_bit():
    """Counters(lead=(mixed table, index)): the first counter gathered from a table of mixed
    values, its draw step taken per table value; the same draws as the gathered counters,
    for a small table (the lead kept) and a large one (gathered at once), and after take."""
    g = np.random.default_rng(9)
    key, key2 = rng.counter_key(5, "lead"), rng.counter_key(5, "lead2")
    v = g.integers(0, 10**6, 4000)
    for n_table in (30, 5000):
        dwells = g.integers(0, 10**9, n_table)
        at = g.integers(0, n_table, 4000)
        c = rng.Counters(mixed=[rng.mix_counter(v)], lead=(rng.mix_counter(dwells), at))
        assert (c.lead is not None) == (n_table == 30)
        assert c.uniform(key).tobytes() == rng.pair_uniform(key, dwells[at], v).tobytes()
        assert c.normal(key2).tobytes() == rng.pair_normal(key2, dwells[at], v).tobytes()
        idx = np.flatnonzero(g.random(4000) < 0.4)[::-1]
        assert (c.take(idx).normal(key).tobytes()
                == rng.pair_normal(key, dwells[at][idx], v[idx]).tobytes())
        sel = g.random(4000) < 0.5
        assert (c.take(sel).uniform(key2).tobytes()
                == rng.pair_uniform(key2, dwells[at][sel], v[sel]).tobytes())
        three = rng.Counters(mixed=[rng.mix_counter(v), rng.mix_counter(3)],
                             lead=(rng.mix_counter(dwells), at))
        assert three.uniform(key).tobytes() == rng.pair_uniform(key, dwells[at], v, 3).tobytes()
