"""The run file is written atomically and read back exactly (DESIGN §6)."""
import h5py
import numpy as np
import pytest

from gmtiflow import store
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
    paths = []
    for i in range(2):
        path = tmp_path / f"run{i}.h5"
        with store.RunWriter(path, seed=1) as w:
            w.write_table("truth", table(1000))
            w.commit()
        paths.append(path)
    assert paths[0].read_bytes() == paths[1].read_bytes()
