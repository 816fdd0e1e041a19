"""Many named random streams at once: ``rng.stream(seed, *prefix, name, *suffix)`` for a list
of names, bit for bit, at a fraction of the cost.

A :func:`gmtiflow.rng.stream` builds a :class:`numpy.random.SeedSequence` (~11 µs: its entropy
hash runs word by word) and seeds a PCG64 from it; the fleet builds one to three per vehicle.
Here the SeedSequence hash (numpy's ``mix_entropy`` and ``generate_state``, a fixed algorithm:
numpy keeps seeded streams reproducible across versions) runs on uint32 arrays across all the
names at once, and each PCG64 is seeded from its precomputed state words.  Every batch checks
its first stream against :func:`gmtiflow.rng.stream`; on any difference (or a name whose key
is not one 32-bit word) the streams are made one by one by :func:`gmtiflow.rng.stream`.
:func:`first_words` goes one step further for streams read only a few words (the random
fleet's specs): PCG64 itself stepped on all streams at once, no generator made.
"""
from __future__ import annotations

import functools
from typing import List, Sequence

import numpy as np
from numpy.random.bit_generator import ISeedSequence

from gmtiflow import rng

# numpy/random/bit_generator.pyx
_INIT_A, _MULT_A = 0x43B0D7E5, 0x931E8875
_INIT_B, _MULT_B = 0x8B51F9DD, 0x58F38DED
_MIX_L, _MIX_R = 0xCA01F9DD, 0x4973F715
_POOL = 4
_M32 = 0xFFFFFFFF


def _int_words(n: int) -> List[int]:
    """An int >= 0 as little-endian 32-bit words (numpy's ``_int_to_uint32_array``)."""
    if n == 0:
        return [0]
    out = []
    while n > 0:
        out.append(n & _M32)
        n >>= 32
    return out


#: rng.name_key of a name, remembered: a fleet asks its streams by the same vehicle names two
#: or three times (spec, speed profile, wander); typed, so True and 1 stay apart.
_name_key = functools.lru_cache(maxsize=1 << 16, typed=True)(rng.name_key)


class _State(ISeedSequence):
    """A seed sequence whose state words are already known (the PCG64 seeding reads them)."""

    def __init__(self, words: np.ndarray):
        self.words = words

    def generate_state(self, n_words, dtype=np.uint32):
        if n_words != 4 or np.dtype(dtype) != np.dtype(np.uint64):
            raise ValueError("precomputed PCG64 state: 4 uint64 words only")
        return self.words


def _hashmix(value: np.ndarray, const: List[int]) -> np.ndarray:
    value = value ^ np.uint32(const[0])
    const[0] = (const[0] * _MULT_A) & _M32
    value = value * np.uint32(const[0])
    return value ^ (value >> np.uint32(16))


def _mix(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    r = np.uint32(_MIX_L) * x - np.uint32(_MIX_R) * y
    return r ^ (r >> np.uint32(16))


def _pcg_states(entropy: np.ndarray) -> np.ndarray:
    """SeedSequence(...).generate_state(4, uint64) of each row of assembled entropy (N, L)."""
    n, length = entropy.shape
    const = [_INIT_A]
    with np.errstate(over="ignore"):
        pool = [_hashmix(entropy[:, i] if i < length else np.zeros(n, np.uint32), const)
                for i in range(_POOL)]
        for i_src in range(_POOL):
            for i_dst in range(_POOL):
                if i_src != i_dst:
                    pool[i_dst] = _mix(pool[i_dst], _hashmix(pool[i_src], const))
        for i_src in range(_POOL, length):
            for i_dst in range(_POOL):
                pool[i_dst] = _mix(pool[i_dst], _hashmix(entropy[:, i_src], const))
        state = np.empty((n, 8), np.uint32)
        h = _INIT_B
        for i in range(8):
            data = pool[i % _POOL] ^ np.uint32(h)
            h = (h * _MULT_B) & _M32
            data = data * np.uint32(h)
            state[:, i] = data ^ (data >> np.uint32(16))
    return np.ascontiguousarray(state.astype("<u4")).view("<u8").astype(np.uint64)


def _states(seed: int, prefix: Sequence, names: List, suffix: Sequence):
    """The PCG64 seed words (N, 4) of ``rng.stream(seed, *prefix, name, *suffix)`` for each
    name, and the first stream made by :func:`gmtiflow.rng.stream` (the check); None when
    they cannot be computed here (a key wider than 32 bits, fewer than two names, or a first
    stream that differs: the caller makes them one by one)."""
    keys = [_name_key(x) for x in names]
    pre = [rng.name_key(x) for x in prefix]
    post = [rng.name_key(x) for x in suffix]
    run = _int_words(int(seed))
    if len(run) < _POOL:            # numpy pads the run entropy when there is a spawn key
        run = run + [0] * (_POOL - len(run))
    spawn = [w for k in pre for w in _int_words(k)], [w for k in post for w in _int_words(k)]
    if max(keys) > _M32 or len(names) < 2:
        return None
    entropy = np.empty((len(names), len(run) + len(spawn[0]) + 1 + len(spawn[1])), np.uint32)
    entropy[:] = np.asarray(run + spawn[0] + [0] + spawn[1], np.uint32)
    entropy[:, len(run) + len(spawn[0])] = keys
    states = _pcg_states(entropy)
    check = rng.stream(seed, *prefix, names[0], *suffix)
    if np.random.PCG64(_State(states[0])).state != check.bit_generator.state:
        return None
    return states, check


def streams(seed: int, prefix: Sequence, names: Sequence, suffix: Sequence = ()
            ) -> List[np.random.Generator]:
    """``[rng.stream(seed, *prefix, name, *suffix) for name in names]``, bit for bit."""
    names = list(names)
    if not names:
        return []
    made = _states(seed, prefix, names, suffix)
    if made is None:
        return [rng.stream(seed, *prefix, x, *suffix) for x in names]
    states, check = made
    return [check] + [np.random.Generator(np.random.PCG64(_State(s))) for s in states[1:]]


# PCG64 (numpy/random/src/pcg64: a 128-bit LCG, state = state * MULT + inc, each output the
# XSL-RR of the new state) on (high, low) uint64 pairs, all streams at once.
_PCG_MULT = (np.uint64(0x2360ED051FC65DA4), np.uint64(0x4385DF649FCCF645))
_LOW32 = np.uint64(0xFFFFFFFF)


def _mul_64x64(a: np.ndarray, b: np.uint64):
    """Full products a * b (128 bits) of uint64 arrays as (high, low) words."""
    a0, a1 = a & _LOW32, a >> np.uint64(32)
    b0, b1 = b & _LOW32, b >> np.uint64(32)
    p00, p01, p10 = a0 * b0, a0 * b1, a1 * b0
    mid = (p00 >> np.uint64(32)) + (p01 & _LOW32) + (p10 & _LOW32)
    low = (p00 & _LOW32) | (mid << np.uint64(32))
    high = a1 * b1 + (p01 >> np.uint64(32)) + (p10 >> np.uint64(32)) + (mid >> np.uint64(32))
    return high, low


def _pcg_step(hi: np.ndarray, lo: np.ndarray, inc_hi: np.ndarray, inc_lo: np.ndarray):
    """state * MULT + inc (mod 2^128) of (high, low) states."""
    m_hi, m_lo = _PCG_MULT
    p_hi, p_lo = _mul_64x64(lo, m_lo)
    p_hi += hi * m_lo + lo * m_hi                   # wraps mod 2^64, as the state does
    n_lo = p_lo + inc_lo
    return p_hi + inc_hi + (n_lo < p_lo).astype(np.uint64), n_lo


def first_words(seed: int, prefix: Sequence, names: Sequence, suffix: Sequence = (),
                n_words: int = 4) -> np.ndarray:
    """The first ``n_words`` raw 64-bit outputs (``bit_generator.random_raw``) of each stream
    ``rng.stream(seed, *prefix, name, *suffix)``, (N, n_words): PCG64 run on all streams at
    once from their seed words (numpy's seeding: state 0, inc = seq << 1 | 1, a step, state +=
    seed, a step), without making a generator each (~2 µs a stream); checked against the first
    stream's own words (made one by one on any difference)."""
    names = list(names)
    out = np.empty((len(names), n_words), np.uint64)
    made = _states(seed, prefix, names, suffix) if names else None
    if made is not None:
        states, check = made
        with np.errstate(over="ignore"):
            one = np.uint64(1)
            inc_hi = (states[:, 2] << one) | (states[:, 3] >> np.uint64(63))
            inc_lo = (states[:, 3] << one) | one
            hi, lo = _pcg_step(np.zeros_like(inc_hi), np.zeros_like(inc_lo), inc_hi, inc_lo)
            lo = lo + states[:, 1]
            hi = hi + states[:, 0] + (lo < states[:, 1]).astype(np.uint64)
            hi, lo = _pcg_step(hi, lo, inc_hi, inc_lo)
            for k in range(n_words):
                hi, lo = _pcg_step(hi, lo, inc_hi, inc_lo)
                value, rot = hi ^ lo, hi >> np.uint64(58)
                out[:, k] = (value >> rot) | (value << ((np.uint64(64) - rot) & np.uint64(63)))
        if out[0].tobytes() == check.bit_generator.random_raw(n_words).tobytes():
            return out
    for i, x in enumerate(names):
        out[i] = rng.stream(seed, *prefix, x, *suffix).bit_generator.random_raw(n_words)
    return out
