"""The run file is written atomically and read back exactly (DESIGN §6)."""
import threading
import zlib

import h5py
import numpy as np
import pytest

from gmtiflow import chunk_codec, store
from gmtiflow.errors import StoreError


def table(n=10):
    rng = np.random.default_rng(0)
    return {"time_s": np.arange(n, dtype=float), "x_m": rng.normal(size=n),
            "vehicle_id": np.arange(n, dtype=np.int64), "invisible": rng.random(n) < 0.5,
            "name": np.array([f"v{i}" for i in range(n)])}


def test_round_trip_with_units(tmp_path):
    path = tmp_path / "run.h5"
    with store.RunWriter(path, seed=3) as w:
        w.write_table("truth", table(), {"x_m": "east"})
        w.write_text("config", "seed: 3\n")
        w.commit()
    back = store.read_table(path, "truth")
    for k, v in table().items():
        assert np.array_equal(back[k], v), k
    with h5py.File(path) as f:
        assert f["truth/x_m"].attrs["units"] == "m"
        assert f["truth/x_m"].attrs["description"] == "east"
        assert f["truth/vehicle_id"].attrs["units"] == ""
        assert f.attrs["seed"] == 3 and f.attrs["complete"]
    assert store.read_text(path, "config") == "seed: 3\n"


def test_append_grows_the_table(tmp_path):
    path = tmp_path / "run.h5"
    with store.RunWriter(path, seed=1) as w:
        w.append_table("truth", table(5))
        w.append_table("truth", table(7))
        w.commit()
    back = store.read_table(path, "truth")
    assert len(back["time_s"]) == 12
    assert np.array_equal(back["name"][5:], table(7)["name"])


def test_an_error_leaves_no_file(tmp_path):
    path = tmp_path / "run.h5"
    with pytest.raises(RuntimeError):
        with store.RunWriter(path, seed=1) as w:
            w.write_table("truth", table())
            raise RuntimeError("boom")
    assert list(tmp_path.iterdir()) == []


def test_incomplete_and_foreign_files_are_refused(tmp_path):
    partial = tmp_path / "partial.h5"
    with h5py.File(partial, "w") as f:
        f.attrs["layout_version"] = store.LAYOUT_VERSION
        f.attrs["complete"] = False
    with pytest.raises(StoreError, match="incomplete"):
        store.open_run(partial)
    old = tmp_path / "old.h5"
    with h5py.File(old, "w") as f:
        f.attrs["layout_version"] = 999
    with pytest.raises(StoreError, match="layout_version 999"):
        store.open_run(old)
    junk = tmp_path / "junk.h5"
    junk.write_bytes(b"not hdf5 at all")
    with pytest.raises(StoreError, match="not a readable HDF5"):
        store.open_run(junk)
    with pytest.raises(StoreError, match="no such run file"):
        store.open_run(tmp_path / "missing.h5")


def test_same_content_gives_identical_bytes(tmp_path):
    """Also with big tables compressed by threads (chunks are written in submission order)."""
    paths = []
    for i in range(2):
        path = tmp_path / f"run{i}.h5"
        with store.RunWriter(path, seed=1, deflate_workers=2) as w:
            w.write_table("truth", table(1000))
            w.append_table("looks", table(2 * store._CHUNK_ROWS + 5))
            w.append_table("looks", table(store._CHUNK_ROWS))
            w.commit()
        paths.append(path)
    assert paths[0].read_bytes() == paths[1].read_bytes()


def test_a_small_run_compresses_without_threads(tmp_path, monkeypatch):
    """By default the deflate threads start only once a run has handed over
    _INLINE_RUN_BYTES of columns (below that they cost more CPU than they save); the values
    are those written with threads from the start."""
    def deflate_threads():
        return [t for t in threading.enumerate() if t.name.startswith("deflate")]

    monkeypatch.setattr(store, "INLINE_RUN_BYTES", 2 * store._CHUNK_ROWS * (3 * 8 + 1))
    paths = []
    for workers in (None, 2):
        path = tmp_path / f"run_{workers}.h5"
        with store.RunWriter(path, seed=1, deflate_workers=workers) as w:
            w.append_table("looks", table(2 * store._CHUNK_ROWS))
            assert bool(deflate_threads()) == (workers == 2)
            w.append_table("looks", table(2 * store._CHUNK_ROWS))    # past the budget
            assert deflate_threads()
            w.commit()
        paths.append(path)
    assert not deflate_threads()
    a, b = (store.read_table(p, "looks") for p in paths)
    for column, values in table(2 * store._CHUNK_ROWS).items():
        assert np.array_equal(a[column], np.concatenate([values, values])), column
        assert np.array_equal(b[column], a[column]), column


@pytest.mark.parametrize("workers", [0, 2])
def test_big_tables_round_trip_through_the_chunk_deflater(tmp_path, workers):
    """Tables of whole chunks are compressed outside HDF5 (shuffle + deflate, written as
    chunks): appended in blocks that do not fall on chunk boundaries, written whole, with any
    number of threads, every value comes back exactly and the datasets carry the standard
    gzip + shuffle filters, so any HDF5 reader decodes them."""
    n = 3 * store._CHUNK_ROWS + 1234
    big = table(n)
    path = tmp_path / "run.h5"
    cuts = [0, 1000, store._CHUNK_ROWS + 7, 2 * store._CHUNK_ROWS + 1, n]
    with store.RunWriter(path, seed=1, deflate_workers=workers) as w:
        for a, b in zip(cuts[:-1], cuts[1:]):
            w.append_table("truth", {k: v[a:b] for k, v in big.items()})
        w.write_table("whole", big)
        w.commit()
    for name in ("truth", "whole"):
        back = store.read_table(path, name)
        for k, v in big.items():
            assert np.array_equal(back[k], v), (name, k)
    with h5py.File(path) as f:
        ds = f["truth/x_m"]
        assert (ds.compression, ds.compression_opts, ds.shuffle) == ("gzip", 1, True)
        assert ds.chunks == (store._CHUNK_ROWS,)
        assert ds.id.get_storage_size() < ds.size * ds.dtype.itemsize     # compressed
        assert f["whole/invisible"].dtype == bool


def _mixed_planes(n, seed=2):
    """uint32 values whose byte planes alternate: zeros, random bytes, zeros, random bytes."""
    rng = np.random.default_rng(seed)
    return (rng.integers(0, 256, n, dtype=np.uint32) << 8) | \
        (rng.integers(0, 256, n, dtype=np.uint32) << 24)


def _strategy_planes(n, seed=5):
    """uint64 values whose byte planes need each way of storing a plane: noise (stored),
    strings that repeat (period 10: deflated with matches), bytes of skewed frequencies but no
    repeated strings (run-length strategy), one byte value (a constant section)."""
    rng = np.random.default_rng(seed)
    planes = [rng.integers(0, 256, n), np.resize(rng.integers(0, 256, 10), n),
              rng.binomial(255, 0.5, n), np.full(n, 7), np.resize(rng.integers(0, 256, 10), n),
              rng.binomial(255, 0.3, n), rng.integers(0, 256, n), np.full(n, 200)]
    return np.stack(planes, axis=1).astype(np.uint8).view(np.uint64).ravel()


def test_deflated_chunk_is_what_the_hdf5_filters_decode(tmp_path):
    """Chunks made by _deflated_chunk, written raw, read back through HDF5's own shuffle and
    deflate filters as the values they were made of: element sizes 8, 4 and 1; byte planes
    that are noise (stored blocks) between planes that are deflated; and, for each dataset, a
    second chunk made by the same (reused) compressor, which must not refer back to the first
    (all-zero int64: every byte equals the one before)."""
    path = tmp_path / "c.h5"
    rng = np.random.default_rng(1)
    n = store._CHUNK_ROWS
    values = {"f": rng.normal(size=2 * n), "b": np.arange(2 * n) % 3 == 0,
              "u": rng.integers(0, 2**63, 2 * n, dtype=np.uint64),
              "mixed": _mixed_planes(2 * n), "zeros": np.zeros(2 * n, np.int64),
              "runs": np.repeat(rng.normal(size=n // 8), 16),
              "ids": np.arange(2 * n, dtype=np.int64), "minus_one": np.full(2 * n, -1.0),
              "signed_zero": np.where(np.arange(2 * n) % 2 == 0, 0.0, -0.0),
              "small": np.arange(2 * n, dtype=np.int16) % 7,
              "periodic": np.resize(rng.normal(size=10), 2 * n),
              "strategies": _strategy_planes(2 * n)}
    with h5py.File(path, "w") as f:
        for name, v in values.items():
            ds = f.create_dataset(name, shape=v.shape, dtype=v.dtype,
                                  chunks=(store._CHUNK_ROWS,), compression="gzip",
                                  compression_opts=1, shuffle=True)
            for i in (0, 1):
                ds.id.write_direct_chunk((i * n,), chunk_codec._deflated_chunk(v[i * n:(i + 1) * n]))
    with h5py.File(path) as f:
        for name, v in values.items():
            assert np.array_equal(f[name][()], v), name


def test_a_padded_last_chunk_inflates_to_its_rows_and_zeros():
    """A dataset's last, partial chunk is deflated from its rows alone, each plane followed by
    a cached section of zeros: it inflates to the bytes of the rows padded with zero values
    (what HDF5 stores for an edge chunk), checksum included, whatever the rows' planes (noise,
    constant, zero) or pieces; the padding costs no deflate of its own (a chunk of noise and
    zeros stores the noise, it does not deflate it)."""
    n = store._CHUNK_ROWS
    rng = np.random.default_rng(11)
    for values in (rng.normal(size=20_000), np.arange(3, dtype=np.int64), np.full(700, 2.5),
                   rng.random(9000) < 0.5, np.zeros(5, np.int64), rng.integers(0, 9, 40_000),
                   [rng.normal(size=100), rng.normal(size=30_000)]):
        pieces = values if isinstance(values, list) else [values]
        joined = np.concatenate(pieces)
        padded = np.zeros(n, joined.dtype)
        padded[:len(joined)] = joined
        raw = zlib.decompress(chunk_codec._deflated_chunk(values, n - len(joined)))
        assert raw == zlib.decompress(chunk_codec._deflated_chunk(padded))
    noise = rng.integers(0, 2**63, 30_000, dtype=np.uint64)
    assert len(chunk_codec._deflated_chunk(noise, n - len(noise))) < noise.nbytes + 1000


def test_chunks_deflated_together_are_the_bytes_of_each_alone():
    """A table's chunks are judged together (one analysis of all their planes' samples): the
    same streams as each chunk deflated alone, whatever their element sizes, lengths (too
    short to sample, under _SMALL_BYTES), padding, pieces and constant planes."""
    n = store._CHUNK_ROWS
    rng = np.random.default_rng(12)
    chunks = [(rng.normal(size=20_000), 0), (np.arange(31_134, dtype=np.int64), 0),
              (np.full(9000, 2.5), 0), (rng.random(40_000) < 0.2, 0),
              (np.arange(10, dtype=np.int64), 0), (rng.integers(0, 9, 3000), 0),
              (_strategy_planes(n), 0), (_mixed_planes(n), 0),
              ([rng.normal(size=100), rng.normal(size=30_000)], n - 30_100),
              (np.repeat(rng.normal(size=500), 30).astype(np.float32), 0),
              (np.zeros(5, np.int64), n - 5), (rng.integers(0, 2**63, 4000, dtype=np.uint64), 0)]
    alone = [chunk_codec._deflated_chunk(values, pad) for values, pad in chunks]
    assert chunk_codec._deflated_chunks(chunks) == alone
    assert chunk_codec._deflated_chunks(chunks[::-1]) == alone[::-1]
    assert chunk_codec._deflated_chunks([]) == []


def test_constant_planes_are_found_and_checksummed_without_their_bytes():
    """Byte planes that hold one byte value (ids' high bytes, constant columns) are sections
    made once; the stream's checksum over them is zlib's (the inflater checks it)."""
    n = 1000
    assert chunk_codec._constant_planes(np.arange(n, dtype=np.int64)).tolist() == \
        [False, False] + [True] * 6
    assert chunk_codec._constant_planes(np.full(n, -1.0)).all()
    assert chunk_codec._constant_planes(np.array([0.0, -0.0])).tolist() == [True] * 7 + [False]
    assert chunk_codec._constant_planes(np.ones(n, bool)).tolist() == [True]
    rng = np.random.default_rng(4)
    for byte, count in ((0, 1), (255, 5552), (7, 5553), (128, 300_000)):
        adler = zlib.adler32(rng.bytes(77))
        assert chunk_codec._adler32_run(adler, byte, count) == \
            zlib.adler32(bytes((byte,)) * count, adler)
    for values in (np.full(n, 3.5), np.arange(n, dtype=np.int64), np.zeros(n, bool)):
        raw = zlib.decompress(chunk_codec._deflated_chunk(values))
        k = values.dtype.itemsize
        back = np.frombuffer(raw, np.uint8).reshape(k, n).T.copy().view(values.dtype).ravel()
        assert back.tobytes() == values.tobytes()
    small = np.arange(10, dtype=np.int64)          # under _SMALL_BYTES: one section
    raw = zlib.decompress(chunk_codec._deflated_chunk(small))
    assert raw == np.ascontiguousarray(small.view(np.uint8).reshape(-1, 8).T).tobytes()


def test_a_root_attribute_that_cannot_be_written_is_not_left_behind(tmp_path):
    """Root attributes are written with h5py's low-level calls; one whose value cannot be
    stored (text that is not UTF-8) raises as ``attrs[...] =`` does and leaves no empty
    attribute of that name."""
    with h5py.File(tmp_path / "a.h5", "w", track_order=True) as f:
        for set_attr in (lambda: f.attrs.__setitem__("x", "\udc80"),
                         lambda: store._set_root_attr(f, "x", "\udc80")):
            with pytest.raises(UnicodeEncodeError):
                set_attr()
            assert "x" not in f.attrs
        store._set_root_attr(f, "x", "m")
        store._set_root_attr(f, "x", True)             # replaced, as attrs[...] = replaces
        assert f.attrs["x"].dtype == bool and bool(f.attrs["x"])


def test_noise_planes_are_stored_and_the_rest_deflated():
    """Byte planes that are noise (random low bytes of measured values) cost deflate's time for
    nothing, so they go into the stream as stored blocks; planes with any structure are still
    deflated (runs of equal values even when their bytes look random)."""
    rng = np.random.default_rng(3)
    n = store._CHUNK_ROWS

    def planes(v):
        return np.ascontiguousarray(v.view(np.uint8).reshape(-1, v.dtype.itemsize).T)

    u = rng.integers(0, 2**63, n, dtype=np.uint64)
    assert chunk_codec._noise_planes(planes(u))[:7].all()
    assert len(chunk_codec._deflated_chunk(u)) < u.nbytes + 100        # stored, not expanded
    assert chunk_codec._noise_planes(planes(_mixed_planes(n))).tolist() == [False, True, False, True]
    time_s = np.arange(n) * 0.1
    assert not chunk_codec._noise_planes(planes(time_s)).any()
    assert len(chunk_codec._deflated_chunk(time_s)) < 0.5 * time_s.nbytes
    runs = np.repeat(rng.normal(size=n // 16), 16)
    assert not chunk_codec._noise_planes(planes(runs)).any()
    assert len(chunk_codec._deflated_chunk(runs)) < 0.3 * runs.nbytes
    x = rng.normal(size=n)       # low mantissa bytes stored, sign and exponent deflated
    assert chunk_codec._noise_planes(planes(x)).tolist() == [True] * 6 + [False] * 2
    assert len(chunk_codec._deflated_chunk(x)) < 0.9 * x.nbytes


def test_each_plane_is_deflated_the_way_that_stores_it_in_fewer_bytes(monkeypatch):
    """A plane whose strings repeat (a periodic column: vehicles on laps, a beam scan) is
    deflated with zlib-ng's matches, one whose bytes only have skewed frequencies with zlib's
    run-length strategy (zlib-ng's quick deflate codes every byte it cannot match in 8-9
    bits), and so is one of one dominant byte, whose repeated strings are its runs; a chunk
    of all these comes out smaller than with either way alone."""
    if chunk_codec._MATCH_STRATEGY is None:
        pytest.skip("zlib-ng is not installed: every plane is deflated with Z_RLE")
    n = store._CHUNK_ROWS
    rng = np.random.default_rng(6)
    periodic = np.resize(rng.normal(size=10), n)
    dominant = np.where(rng.random(n) < 0.05, rng.integers(0, 256, n), 0).astype(np.uint8)
    mixed = _strategy_planes(n)
    chosen = {name: len(chunk_codec._deflated_chunk(v)) for name, v in
              (("periodic", periodic), ("dominant", dominant), ("mixed", mixed))}
    sizes = {}
    for way, literal_bits in (("run-length", 1e9), ("matches", -1.0)):     # every plane one way
        monkeypatch.setattr(chunk_codec, "_LITERAL_BITS", literal_bits)
        sizes[way] = {name: len(chunk_codec._deflated_chunk(v)) for name, v in
                      (("periodic", periodic), ("dominant", dominant), ("mixed", mixed))}
    assert chosen["periodic"] < 0.05 * periodic.nbytes < sizes["run-length"]["periodic"]
    assert chosen["dominant"] == sizes["run-length"]["dominant"] < \
        0.7 * sizes["matches"]["dominant"]
    assert chosen["mixed"] < 0.95 * min(sizes["run-length"]["mixed"], sizes["matches"]["mixed"])


def test_a_chunk_given_in_pieces_deflates_to_the_bytes_of_its_joined_rows():
    """The writer hands a chunk of a table given in parts (a sink's block) as pieces, joined
    by the shuffle itself: the same deflated bytes as the joined column, whatever the cuts,
    dtypes and constant planes; and the deflater cuts pieces into the chunks of the joined
    rows."""
    n = store._CHUNK_ROWS
    rng = np.random.default_rng(9)
    columns = [rng.normal(size=n), np.arange(n, dtype=np.int64), rng.random(n) < 0.3,
               rng.integers(0, 7, n).astype(np.uint8), np.full(n, 2.5),
               np.repeat(rng.normal(size=n // 8), 8).astype(np.float32), np.arange(600)]
    for values in columns:
        for cuts in ([len(values) // 2], [1, 2, 3, len(values) - 5], [0, 0, 17]):
            pieces = np.split(values, cuts)
            assert chunk_codec._deflated_chunk(pieces) == chunk_codec._deflated_chunk(values)
            assert chunk_codec._constant_planes(pieces).tolist() == \
                chunk_codec._constant_planes(values).tolist()
    pieces = [np.arange(0, 5), np.arange(5, 12), np.arange(12, 13), np.arange(13, 30)]
    chunks, rest = chunk_codec._cut(pieces, 8, 24)
    assert [np.concatenate(c).tolist() for c in chunks] == \
        [list(range(0, 8)), list(range(8, 16)), list(range(16, 24))]
    assert np.concatenate(rest).tolist() == list(range(24, 30))
    chunks, rest = chunk_codec._cut(pieces, 64, 0)
    assert chunks == [] and np.concatenate(rest).tolist() == list(range(30))


def test_planes_of_short_runs_are_deflated_huffman_only(monkeypatch):
    """A plane whose runs are too short to repay Z_RLE's matches (one value for most rows,
    between them values of their own: a σ column with false alarms among targets) is deflated
    Huffman-only, into no more bytes than Z_RLE would; a plane of long runs stays with Z_RLE,
    which codes a run in a match."""
    n = store._CHUNK_ROWS
    rng = np.random.default_rng(8)
    short = np.where(rng.random(n) < 0.4, 1.2345, np.round(rng.normal(size=n), 1))
    long_runs = np.repeat(rng.integers(0, 256, n // 64), 64).astype(np.uint8)
    chosen = {name: len(chunk_codec._deflated_chunk(v)) for name, v in
              (("short", short), ("long", long_runs))}
    sizes = {}
    for way, margin in (("huffman", np.inf), ("run-length", -np.inf)):    # every plane one way
        monkeypatch.setattr(chunk_codec, "_HUFFMAN_MARGIN_BITS", margin)
        sizes[way] = {name: len(chunk_codec._deflated_chunk(v)) for name, v in
                      (("short", short), ("long", long_runs))}
    assert chosen["short"] == sizes["huffman"]["short"] < 0.95 * sizes["run-length"]["short"]
    assert chosen["long"] == sizes["run-length"]["long"] < 0.2 * sizes["huffman"]["long"]
    raw = zlib.decompress(chunk_codec._deflated_chunk(short))
    back = np.frombuffer(raw, np.uint8).reshape(8, n).T.copy().view(np.float64).ravel()
    assert back.tobytes() == short.tobytes()


def test_a_dominant_value_in_short_runs_is_judged_by_the_bytes_its_runs_leave():
    """A σ column of a scene with false alarms: one value for the false alarms, in short runs
    between the targets' own values.  Its runs are mostly of the dominant bytes, so the bytes
    they leave (Z_RLE's literals) are spread more evenly than the whole plane: judged by their
    own entropy, its low planes go Huffman-only, which stores them in fewer bytes than Z_RLE;
    its exponent plane, nearly one byte, stays with Z_RLE."""
    n = store._CHUNK_ROWS
    rng = np.random.default_rng(13)
    lengths = rng.geometric(0.4, n)                 # false alarms, targets, false alarms ...
    false_alarm = np.repeat(np.arange(len(lengths)) % 2 == 0, lengths)[:n]
    sigma = np.where(false_alarm, 0.58421364, 0.5 + 0.1 * rng.random(n))
    planes = np.ascontiguousarray(sigma.view(np.uint8).reshape(-1, 8).T)
    ways = chunk_codec._plane_ways(chunk_codec._plane_samples(planes), 8)
    assert ways[:6] == [zlib.Z_HUFFMAN_ONLY] * 6 and ways[7] == zlib.Z_RLE

    def size(plane, strategy):
        z = zlib.compressobj(1, zlib.DEFLATED, -15, 9, strategy)
        return len(z.compress(plane) + z.flush(zlib.Z_FULL_FLUSH))
    for plane in planes[:6]:
        assert size(plane, zlib.Z_HUFFMAN_ONLY) < 0.98 * size(plane, zlib.Z_RLE)


def test_a_plane_huffman_only_would_shrink_by_little_is_stored():
    """A plane of 128 byte values spread evenly (7 bits a byte: the top mantissa bytes of
    measured values) is not noise, and its runs are too short for Z_RLE, but Huffman-only
    would save an eighth of it for ~2.6 ms a MB: it is stored.  One of 32 values (5 bits)
    is still deflated Huffman-only; the chunk of both inflates to its bytes."""
    n = store._CHUNK_ROWS
    rng = np.random.default_rng(15)
    planes = np.stack([rng.integers(0, 128, n), rng.integers(0, 32, n)]).astype(np.uint8)
    ways = chunk_codec._plane_ways(chunk_codec._plane_samples(planes), 2)
    assert ways == [chunk_codec._STORED, zlib.Z_HUFFMAN_ONLY]
    values = planes.T.copy().view(np.uint16).ravel()
    raw = zlib.decompress(chunk_codec._deflated_chunk(values))
    assert raw == planes.tobytes()


def test_without_zlib_ng_the_chunks_are_deflated_by_cpythons_zlib(monkeypatch):
    """zlib-ng is a dependency, but the run file needs only the deflate streams: with
    CPython's zlib every deflated plane is run-length coded, and the values come back."""
    monkeypatch.setattr(chunk_codec, "zlib", zlib)
    monkeypatch.setattr(chunk_codec, "_MATCH_STRATEGY", None)
    monkeypatch.setattr(chunk_codec, "_local", threading.local())     # compressors of zlib's own
    monkeypatch.setattr(chunk_codec, "_SECTIONS", {})
    n = store._CHUNK_ROWS
    for values in (_strategy_planes(n), np.random.default_rng(7).normal(size=n),
                   np.arange(n, dtype=np.int64), np.arange(10, dtype=np.int64)):
        raw = zlib.decompress(chunk_codec._deflated_chunk(values))
        k = values.dtype.itemsize
        back = np.frombuffer(raw, np.uint8).reshape(k, -1).T.copy().view(values.dtype).ravel()
        assert back.tobytes() == values.tobytes()
    assert type(chunk_codec._local.z3) is type(zlib.compressobj())


def test_a_sink_closed_before_its_first_block_writes_exact_chunks(tmp_path):
    """A streamed table whose rows all arrive before a block is due is written once, in a
    chunk of its own size (no padding to a full streaming chunk); a longer one streams in full
    chunks.  Either way every row comes back."""
    from gmtiflow.stages import TableSink
    path = tmp_path / "run.h5"
    small, big = table(1000), table(3 * store._CHUNK_ROWS + 17)
    with store.RunWriter(path, seed=1) as w:
        for name, t, step in (("small", small, 300), ("big", big, 70_000)):
            sink = TableSink(w, name, block_rows=2 * store._CHUNK_ROWS)
            n = len(t["time_s"])
            for a in range(0, n, step):
                sink.append({k: v[a:a + step] for k, v in t.items()})
            sink.close()
        w.commit()
    with h5py.File(path) as f:
        assert f["small/x_m"].chunks == (1000,)
        assert f["big/x_m"].chunks == (store._CHUNK_ROWS,)
    for name, t in (("small", small), ("big", big)):
        back = store.read_table(path, name)
        for k, v in t.items():
            assert np.array_equal(back[k], v), (name, k)


def test_a_sink_keeps_no_rows_it_has_written(tmp_path):
    """A streamed sink (``keep=False``) lets go of the rows it has written: the first table's
    zero-row columns it remembers (for an empty table's dtypes) are not views of the rows,
    which would keep every column of that table alive until the run ends."""
    import gc
    import weakref
    from gmtiflow.stages import TableSink
    with store.RunWriter(tmp_path / "run.h5", seed=1) as w:
        sink = TableSink(w, "t")
        t = table(1000)
        columns = [weakref.ref(v) for v in t.values()]
        sink.append(t)
        del t
        sink.close()
        gc.collect()
        assert all(ref() is None for ref in columns)
        w.commit()


def test_a_text_dataset_is_the_one_h5pys_create_dataset_makes(tmp_path):
    """``write_text`` makes /config with h5py's low-level calls: the same type, shape, layout,
    creation properties and value as ``create_dataset(data=text, dtype=str)``; a path with
    groups in it goes through h5py."""
    text = "seed: 3\nname: é\n"
    with h5py.File(tmp_path / "hl.h5", "w", track_order=True) as f:
        f.create_dataset("config", data=text, dtype=store._STR, track_times=False)
    with store.RunWriter(tmp_path / "ll.h5", seed=3) as w:
        w.write_text("config", text)
        w.write_text("notes/config", text)
        w.commit()
    with h5py.File(tmp_path / "hl.h5") as a, h5py.File(tmp_path / "ll.h5") as b:
        for ds in (b["config"], b["notes/config"]):
            assert ds.id.get_type() == a["config"].id.get_type()
            assert ds.shape == a["config"].shape == ()
            assert ds[()] == a["config"][()] == text.encode()
            mine, theirs = ds.id.get_create_plist(), a["config"].id.get_create_plist()
            assert mine.get_layout() == theirs.get_layout()
            assert mine.get_obj_track_times() == theirs.get_obj_track_times()
            assert mine.get_attr_creation_order() == theirs.get_attr_creation_order()
            assert mine.equal(theirs)
