"""Batched named streams (scene/streams.py) are rng.stream's, bit for bit."""
import numpy as np
import pytest

from gmtiflow import rng
from gmtiflow.scene import streams as st


@pytest.mark.parametrize("seed", [0, 1, 12345, 2**32 - 1, 2**32, 2**70 + 3])
@pytest.mark.parametrize("prefix, suffix", [(("truth", "vehicle"), ()),
                                            (("truth", "vehicle"), ("spec",)),
                                            ((), ()), (("a",), ("b", 7))])
def test_batched_streams_are_rng_streams(seed, prefix, suffix):
    names = [f"random-{i:04d}" for i in range(40)] + ["car-1", 3, 0, "é"]
    gens = st.streams(seed, prefix, names, suffix)
    assert len(gens) == len(names)
    for name, g in zip(names, gens):
        ref = rng.stream(seed, *prefix, name, *suffix)
        assert g.bit_generator.state == ref.bit_generator.state
        assert g.random((5, 6)).tobytes() == ref.random((5, 6)).tobytes()
        assert g.standard_normal(4).tobytes() == ref.standard_normal(4).tobytes()


def test_batched_streams_fall_back_one_by_one(monkeypatch):
    # an int name wider than 32 bits, one name, no names: made by rng.stream itself
    for names in ([2**40, "a"], ["only"], []):
        gens = st.streams(5, ("truth",), names)
        assert [g.bit_generator.state for g in gens] == [
            rng.stream(5, "truth", n).bit_generator.state for n in names]
    # a hash that no longer matches numpy's (checked on the first stream): one by one too
    monkeypatch.setattr(st, "_MULT_B", st._MULT_B ^ 1)
    names = ["a", "b", "c"]
    gens = st.streams(5, ("truth",), names)
    assert [g.bit_generator.state for g in gens] == [
        rng.stream(5, "truth", n).bit_generator.state for n in names]
    assert np.random.PCG64(st._State(st._pcg_states(np.zeros((1, 5), np.uint32))[0])).state \
        != np.random.PCG64(np.random.SeedSequence(0, spawn_key=(0,))).state


def test_batched_streams_build_one_seed_sequence_per_batch(monkeypatch):
    # the point of the batch: only its first stream (the check) goes through rng.stream
    calls = []
    real = rng.stream
    monkeypatch.setattr(rng, "stream", lambda *a: calls.append(a) or real(*a))
    gens = st.streams(9, ("truth", "vehicle"), [f"v{i}" for i in range(10)])
    assert len(calls) == 1 and len(gens) == 10


@pytest.mark.parametrize("seed", [0, 1, 2**32 - 1, 2**70 + 3])
def test_first_words_are_each_streams_raw_outputs(seed):
    """first_words (PCG64 stepped on all streams at once) gives each rng.stream's first raw
    64-bit outputs, bit for bit; made one by one for names it cannot batch."""
    names = [f"random-{i:04d}" for i in range(300)] + ["car-1", 3, 0, "é"]
    for n_words in (1, 4, 7):
        got = st.first_words(seed, ("truth", "vehicle"), names, ("spec",), n_words)
        assert got.shape == (len(names), n_words) and got.dtype == np.uint64
        for name, row in zip(names, got):
            ref = rng.stream(seed, "truth", "vehicle", name, "spec").bit_generator
            assert row.tobytes() == ref.random_raw(n_words).tobytes()
    for names in ([2**40, "a"], ["only"], []):
        got = st.first_words(seed, ("truth",), names)
        assert got.tolist() == [rng.stream(seed, "truth", n).bit_generator.random_raw(4).tolist()
                                for n in names]


def test_first_words_fall_back_when_the_step_differs(monkeypatch):
    # another PCG64 multiplier (as if numpy's differed): the first stream's check fails, and
    # every stream's words come from its own generator
    monkeypatch.setattr(st, "_PCG_MULT", (st._PCG_MULT[0], st._PCG_MULT[1] ^ np.uint64(2)))
    names = ["a", "b", "c"]
    got = st.first_words(5, ("truth",), names)
    assert got.tolist() == [rng.stream(5, "truth", n).bit_generator.random_raw(4).tolist()
                            for n in names]
