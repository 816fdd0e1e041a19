"""Random streams derived by name from one root seed (DESIGN §2).

Two kinds of randomness are used:

* :func:`stream` gives a :class:`numpy.random.Generator` for a named entity
  (``stream(seed, "truth", "vehicle", "car-1")``).  The stream depends only on the root seed and
  the names, so changing vehicle B never changes vehicle A's draws, and changing the sensor never
  changes the truth.
* :func:`pair_uniform` / :func:`pair_normal` are *counter-based*: a draw is a pure hash of a key
  and integer counters (e.g. dwell id and vehicle id).  This gives every (dwell, target) pair its
  own random number without building one generator per pair, fully vectorised, and it makes the
  draws of one target independent of which other targets exist (common random numbers).

The hash is the SplitMix64 finaliser (Steele, Lea & Flood 2014), applied to a key mixed with each
counter in turn; it passes BigCrush as a generator and is ample for Monte-Carlo simulation.
"""
from __future__ import annotations

import functools
import hashlib

import numpy as np

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)


def name_key(name: str | int) -> int:
    """A stable 32-bit spawn-key word for a stream name (ints are used as they are)."""
    if isinstance(name, (int, np.integer)) and not isinstance(name, bool):
        if name < 0:
            raise ValueError(f"stream names that are integers must be >= 0, got {name}")
        return int(name)
    digest = hashlib.blake2b(str(name).encode("utf-8"), digest_size=4).digest()
    return int.from_bytes(digest, "big")


def seed_sequence(seed: int, *names: str | int) -> np.random.SeedSequence:
    """The SeedSequence of the stream named ``names`` under root ``seed``."""
    return np.random.SeedSequence(int(seed), spawn_key=tuple(name_key(n) for n in names))


def stream(seed: int, *names: str | int) -> np.random.Generator:
    """An independent PCG64 generator for the entity named ``names`` under root ``seed``."""
    return np.random.Generator(np.random.PCG64(seed_sequence(seed, *names)))


@functools.lru_cache(maxsize=4096)
def counter_key(seed: int, *names: str | int) -> np.uint64:
    """A 64-bit key for the counter-based draws of the stream named ``names`` (a pure function
    of its arguments, cached: a SeedSequence costs tens of µs and chunked stages ask again for
    every chunk)."""
    return np.uint64(seed_sequence(seed, *names).generate_state(1, np.uint64)[0])


def _mix(h: np.ndarray) -> np.ndarray:
    """SplitMix64 finaliser (bijective avalanche on uint64, wrapping arithmetic)."""
    h = (h ^ (h >> np.uint64(30))) * _M1
    h = (h ^ (h >> np.uint64(27))) * _M2
    return h ^ (h >> np.uint64(31))


def _mix_own(h: np.ndarray) -> np.ndarray:
    """:func:`_mix` in place on an array the caller owns (the same operations, fewer
    temporaries)."""
    if h.ndim == 0:
        return _mix(h)
    t = h >> np.uint64(30)
    h ^= t
    h *= _M1
    np.right_shift(h, np.uint64(27), out=t)
    h ^= t
    h *= _M2
    np.right_shift(h, np.uint64(31), out=t)
    h ^= t
    return h


def _mixed_counters(counters) -> list:
    """The per-counter half of :func:`pair_hash`, which does not depend on the key."""
    with np.errstate(over="ignore"):
        return [_mix(np.asarray(c, dtype=np.int64).astype(np.uint64) * _GOLDEN + _GOLDEN)
                for c in counters]


def mix_counter(counter) -> np.ndarray:
    """One counter array mixed (the per-counter half of :func:`pair_hash`): mixing each distinct
    value once (per dwell, per vehicle) and gathering gives ``Counters(mixed=...)`` for pairs."""
    return _mixed_counters([counter])[0]


def _hash_mixed(key: np.uint64, mixed: list, lead=None) -> np.ndarray:
    if lead is not None:
        # the first counter is table[index]: its step mix(key + G + m) taken once per table
        # value and gathered (the same values; the step depends on nothing else)
        table, index = lead
        with np.errstate(over="ignore"):
            h = np.take(_mix_own(np.asarray(table, np.uint64) + (np.uint64(key) + _GOLDEN)),
                        index)
        return _hash_more(h, mixed)
    shape = np.broadcast_shapes(*(m.shape for m in mixed)) if mixed else ()
    with np.errstate(over="ignore"):
        if not mixed:
            return np.full(shape, key, dtype=np.uint64)
        # (key + G) + m with wrapping uint64 addition is key + G + m in any order: the key's
        # part is one scalar, added to the first counter without a full array of keys
        h = np.asarray(mixed[0]) + (np.uint64(key) + _GOLDEN)
        h = _mix(np.broadcast_to(h, shape)) if h.shape != shape else _mix_own(h)
    return _hash_more(h, mixed[1:])


def _hash_more(h: np.ndarray, mixed: list) -> np.ndarray:
    """The chain's further steps, h = mix(h + G + m) per mixed counter m, on ``h`` (the
    caller's own array, or a scalar)."""
    with np.errstate(over="ignore"):
        if mixed and h.shape != np.broadcast_shapes(h.shape, *(m.shape for m in mixed)):
            h = np.array(np.broadcast_to(h, np.broadcast_shapes(h.shape,
                                                                *(m.shape for m in mixed))))
        for m in mixed:
            h += _GOLDEN           # h is this function's own array from here on
            h += m
            h = _mix_own(h)
    return h


def _unit(h: np.ndarray) -> np.ndarray:
    """53 random bits as a float in the open interval (0, 1)."""
    f = (h >> np.uint64(11)).astype(np.float64)
    if f.ndim == 0:
        return (f + 0.5) * (2.0 ** -53)
    f += 0.5
    f *= 2.0 ** -53
    return f


def pair_hash(key: np.uint64, *counters) -> np.ndarray:
    """uint64 hash of ``key`` and the integer counter arrays (broadcast together)."""
    return _hash_mixed(key, _mixed_counters(counters))


def pair_uniform(key: np.uint64, *counters: np.ndarray) -> np.ndarray:
    """Uniform draws in the open interval (0, 1), one per element of the broadcast counters.

    53 random bits, offset by half a unit so that neither 0 nor 1 occurs (safe for logs).
    """
    return _unit(pair_hash(key, *counters))


def pair_normal(key: np.uint64, *counters: np.ndarray) -> np.ndarray:
    """Standard normal draws, one per element of the broadcast counters (Box-Muller).

    The counters are mixed once and hashed with two keys (the same values as two
    :func:`pair_uniform` calls, at about two thirds of the cost).
    """
    return Counters(*counters).normal(key)


class Counters:
    """Counter arrays mixed once (the key-independent half of :func:`pair_hash`) for several
    draws on the same pairs: ``Counters(d, v).uniform(k)`` is ``pair_uniform(k, d, v)`` and
    ``.normal(k)`` is ``pair_normal(k, d, v)``, bit for bit, and :meth:`take` selects pairs
    without mixing them again (SplitMix64 on uint64 is most of a draw's cost).

    ``lead=(table, index)``: the first counter's mixed values are ``table[index]`` (one per
    dwell, say, gathered per pair) and ``mixed`` holds the others (1-d, as ``index``).  A
    draw's first step, which depends on the key and that counter alone, is then taken once
    per table value and gathered: the same draws, one SplitMix64 step fewer per pair."""

    def __init__(self, *counters, mixed=None, lead=None):
        self.mixed = _mixed_counters(counters) if mixed is None else mixed
        if lead is not None:
            table, index = np.asarray(lead[0], np.uint64), np.asarray(lead[1])
            if 2 * table.size >= index.size or index.ndim != 1:
                # as many table values as pairs: gathering first is as cheap
                self.mixed, lead = [np.take(table, index)] + list(self.mixed), None
            else:
                lead = (table, index)
        self.lead = lead

    def take(self, index) -> "Counters":
        """The draws of pairs ``index`` (an index or mask into the counters' broadcast shape)."""
        index = np.asarray(index)
        if self.lead is not None:
            if index.dtype.kind == "b":
                index = np.flatnonzero(index)
            table, at = self.lead
            return Counters(mixed=[np.take(np.broadcast_to(m, at.shape), index)
                                   for m in self.mixed], lead=(table, np.take(at, index)))
        shape = np.broadcast_shapes(*(m.shape for m in self.mixed))
        if index.dtype.kind in "iu" and index.ndim == 1 and len(shape) == 1:
            return Counters(mixed=[np.take(np.broadcast_to(m, shape), index)
                                   for m in self.mixed])       # as fancy indexing, cheaper
        return Counters(mixed=[np.broadcast_to(m, shape)[index] for m in self.mixed])

    def uniform(self, key: np.uint64) -> np.ndarray:
        return _unit(_hash_mixed(key, self.mixed, self.lead))

    def normal(self, key: np.uint64) -> np.ndarray:
        with np.errstate(over="ignore"):
            k2 = _mix(np.asarray(key, dtype=np.uint64) + _GOLDEN * np.uint64(7))
        u1 = _unit(_hash_mixed(key, self.mixed, self.lead))
        u2 = _unit(_hash_mixed(k2, self.mixed, self.lead))
        return np.sqrt(-2.0 * np.log(u1)) * np.cos(2.0 * np.pi * u2)
