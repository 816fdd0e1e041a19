"""The stage cache serves only what it stored for exactly these inputs (issue 17, items 2, 3, 10).

* A key fingerprints the file the loaders read: ``~`` expanded, symlinks resolved, content hashed,
  so editing an input (even keeping its size and mtime) changes the key.
* Entries carry a SHA-256 trailer verified before unpickling: flipped or cut entries, single
  values or streams, are misses that are logged and rewritten.
* A cache directory that cannot be written (full disk) never fails a run.
"""
from __future__ import annotations

import errno
import os
import pickle

import numpy as np
import pytest

from gmtiflow import cache as cache_mod
from gmtiflow.cache import StageCache, stage_key


def _key(path_text):
    return stage_key("sensor", seed=1, rcs={"car": {"table": path_text}})


def test_tilde_path_is_fingerprinted_by_the_file_it_names(tmp_path, monkeypatch):
    monkeypatch.setenv("HOME", str(tmp_path))
    table = tmp_path / "car.csv"
    table.write_text("aspect_deg,rcs_dbsm\n0,-30\n180,-30\n")
    st = table.stat()
    before = _key("~/car.csv")
    table.write_text("aspect_deg,rcs_dbsm\n0,+30\n180,+30\n")   # same size
    os.utime(table, ns=(st.st_atime_ns, st.st_mtime_ns))        # same mtime
    assert table.stat().st_size == st.st_size
    assert _key("~/car.csv") != before
    # a symlink to the file is keyed by the file's content, the same as the file itself
    link = tmp_path / "link.csv"
    link.symlink_to(table)
    assert cache_mod._file_print(str(link)) == cache_mod._file_print(str(table))
    assert cache_mod._file_print("~/car.csv") == cache_mod._file_print(str(table))


def _flip(path, n=64, seed=0):
    data = bytearray(path.read_bytes())
    rng = np.random.default_rng(seed)
    start = int(rng.integers(0, max(1, len(data) - n)))
    for i in range(start, min(len(data), start + n)):
        data[i] ^= 0xFF
    path.write_bytes(bytes(data))


def test_flipped_value_entry_is_a_logged_miss_and_rewritten(tmp_path, caplog):
    c = StageCache(tmp_path, True)
    c.get_or_compute("truth", "k", lambda: np.arange(10_000.0))
    entry = tmp_path / "truth" / "k.pkl"
    _flip(entry)
    value = c.get_or_compute("truth", "k", lambda: np.arange(10_000.0) + 1)
    assert np.array_equal(value, np.arange(10_000.0) + 1)     # recomputed, not served
    assert "checksum mismatch" in caplog.text
    assert c.misses == ["truth", "truth"]
    again = StageCache(tmp_path, True)
    assert np.array_equal(again.get_or_compute("truth", "k", lambda: None),
                          np.arange(10_000.0) + 1)             # the rewritten entry hits
    assert again.hits == ["truth"]


def _chunks(offset=0.0):
    return [np.arange(5000.0) + offset + i for i in range(4)]


@pytest.mark.parametrize("damage", ["flip", "truncate", "empty"])
def test_damaged_stream_entry_is_a_miss_not_an_error(tmp_path, caplog, damage):
    c = StageCache(tmp_path, True)
    assert len(list(c.stream("sensor", "k", lambda: iter(_chunks())))) == 4
    entry = tmp_path / "sensor" / "k.pkl"
    if damage == "flip":
        _flip(entry, seed=3)
    elif damage == "truncate":
        entry.write_bytes(entry.read_bytes()[: entry.stat().st_size // 2])
    else:
        entry.write_bytes(b"")
    c2 = StageCache(tmp_path, True)
    got = list(c2.stream("sensor", "k", lambda: iter(_chunks(100.0))))
    assert all(np.array_equal(a, b) for a, b in zip(got, _chunks(100.0))) and len(got) == 4
    assert c2.misses == ["sensor"] and "damaged" in caplog.text
    c3 = StageCache(tmp_path, True)
    got = list(c3.stream("sensor", "k", lambda: iter(())))
    assert len(got) == 4 and c3.hits == ["sensor"]


def _enospc(*args, **kwargs):
    raise OSError(errno.ENOSPC, "No space left on device")


def test_full_cache_disk_never_fails_a_run(tmp_path, caplog, monkeypatch):
    monkeypatch.setattr(cache_mod._EntryWriter, "write", _enospc)
    c = StageCache(tmp_path, True)
    got = list(c.stream("sensor", "k", lambda: iter(_chunks())))
    assert len(got) == 4
    assert np.array_equal(c.get_or_compute("truth", "k", lambda: np.arange(3)), np.arange(3))
    assert "No space left on device" in caplog.text
    assert not list(tmp_path.rglob("*.pkl")) and not list(tmp_path.rglob("*.partial"))


def test_unwritable_cache_dir_never_fails_a_run(tmp_path, caplog, monkeypatch):
    monkeypatch.setattr(cache_mod.tempfile, "mkstemp", _enospc)
    c = StageCache(tmp_path, True)
    assert len(list(c.stream("sensor", "k", lambda: iter(_chunks())))) == 4
    assert c.get_or_compute("truth", "k", lambda: 7) == 7
    assert "could not write cache entry" in caplog.text


def test_entry_is_pickle_plus_trailer(tmp_path):
    c = StageCache(tmp_path, True)
    c.get_or_compute("truth", "k", lambda: {"a": 1})
    data = (tmp_path / "truth" / "k.pkl").read_bytes()
    assert pickle.loads(data[: -cache_mod._TRAILER_BYTES]) == {"a": 1}
