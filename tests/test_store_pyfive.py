"""The run file's chunks are compressed outside HDF5 (:mod:`gmtiflow.chunk_codec`: per-byte-plane
deflate sections, by zlib's run-length strategy or zlib-ng's matches, cached sections for
constant planes, stored blocks for noise planes, small chunks whole).  pyfive, a pure-Python
HDF5 reader written apart from the HDF5 library and h5py (its own chunk index, shuffle and
deflate handling), must read every column back exactly."""
import numpy as np
import pytest

from gmtiflow import store

pyfive = pytest.importorskip("pyfive")


def columns(n):
    """One column per kind of byte plane the writer treats apart."""
    rng = np.random.default_rng(5)
    return {
        "noise_f8": rng.normal(size=n),                                # low planes: stored
        "ids_i8": np.arange(n, dtype=np.int64),                        # high planes: constant
        "constant_f8": np.full(n, 2.5),                                # every plane constant
        "steps_f4": np.repeat(rng.normal(size=n // 100 + 1), 100)[:n].astype(np.float32),
        "flags_b1": rng.random(n) < 0.1,                               # one-byte planes
        "small_i2": np.arange(n, dtype=np.int16),
        "periodic_f8": np.resize(rng.normal(size=10), n),    # deflated with matches (zlib-ng)
        "skewed_u2": rng.binomial(600, 0.5, n).astype(np.uint16),   # run-length strategy
    }


@pytest.mark.parametrize("n", [37, 5000, 2 * store._CHUNK_ROWS + 123])
def test_an_independent_hdf5_reader_reads_every_column_exactly(tmp_path, n):
    table = columns(n)
    path = tmp_path / "run.h5"
    with store.RunWriter(path, seed=1, deflate_workers=0) as w:
        w.write_table("whole", table)
        cut = n // 3
        w.append_table("grown", {k: v[:cut] for k, v in table.items()})
        w.append_table("grown", {k: v[cut:] for k, v in table.items()})
        w.commit()
    f = pyfive.File(str(path))
    for group in ("whole", "grown"):
        for name, values in table.items():
            back = np.asarray(f[f"{group}/{name}"][()])
            # pyfive gives h5py's bool enum as its int8 base type: compare the stored bytes
            assert back.shape == values.shape, (group, name)
            assert back.dtype.itemsize == values.dtype.itemsize, (group, name)
            assert back.tobytes() == values.tobytes(), (group, name)
