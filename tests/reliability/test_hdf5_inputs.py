"""Damaged, foreign and incomplete HDF5 files given where a run file is expected.

``store.open_run``/``read_table`` raise StoreError and nothing else; ``gmtiflow-convert``,
``gmtiflow-evaluate`` and ``gmtiflow-report --runs`` exit 1 with one ``error:`` line naming the
file, no traceback, and write no output next to it.
"""
from __future__ import annotations

import shutil

import h5py
import numpy as np
import pytest

from gmtiflow import convert, pipeline, store
from gmtiflow.compose import compose
from gmtiflow.errors import StoreError
from gmtiflow.evaluate import cli as evaluate_cli
from gmtiflow.report import cli as report_cli


@pytest.fixture(scope="module")
def good_run(tmp_path_factory):
    d = tmp_path_factory.mktemp("good")
    pipeline.run(compose(["scene.duration_s=10", "export=csv", "report=none",
                          "progress=false", "cache.enabled=false"]), d)
    return d


TABLES = ["truth", "platform", "dwells", "detections", "looks", "tracks", "vehicles",
          "roads/nodes", "roads/edges", "detection_ancestors"]


def _truncated(frac):
    def make(src, dst):
        data = src.read_bytes()
        dst.write_bytes(data[:int(len(data) * frac)])
    return make


def _flipped(seed):
    def make(src, dst):
        b = bytearray(src.read_bytes())
        rng = np.random.default_rng(seed)
        lo = 2048                      # keep the superblock: damage objects, not the signature
        for i in rng.integers(lo, len(b), 64):
            b[i] = int(rng.integers(0, 256))
        dst.write_bytes(bytes(b))
    return make


def _edit_attrs(**attrs):
    def make(src, dst):
        shutil.copy(src, dst)
        with h5py.File(dst, "r+") as f:
            for k, v in attrs.items():
                f.attrs[k] = v
    return make


def _foreign(src, dst):
    with h5py.File(dst, "w") as f:
        f["data"] = np.arange(10.0)


def _hollow(src, dst):                 # says it is a complete run, holds no tables
    with h5py.File(dst, "w") as f:
        f.attrs["layout_version"] = store.LAYOUT_VERSION
        f.attrs["complete"] = True


def _ragged(src, dst):                 # a complete run whose table columns disagree in length
    shutil.copy(src, dst)
    with h5py.File(dst, "r+") as f:
        del f["truth/x_m"]
        f["truth/x_m"] = np.zeros(3)


VARIANTS = {
    **{f"truncated_{f}": _truncated(f) for f in (0.0, 0.01, 0.2, 0.5, 0.9, 0.999)},
    **{f"flipped_{s}": _flipped(s) for s in range(3)},
    "layout_999": _edit_attrs(layout_version=999),
    "incomplete": _edit_attrs(complete=False),
    "complete_is_a_string": _edit_attrs(complete="no"),
    "foreign_hdf5": _foreign,
    "hollow_run": _hollow,
    "ragged_table": _ragged,
    "text": lambda src, dst: dst.write_text("seed,complete\n1,true\n"),
}


@pytest.mark.parametrize("variant", sorted(VARIANTS))
def test_bad_run_files_raise_store_error_and_clis_fail_cleanly(good_run, tmp_path, capsys,
                                                               variant):
    bad_dir = tmp_path / "job"
    bad_dir.mkdir()
    bad = bad_dir / "run.h5"
    VARIANTS[variant](good_run / "run.h5", bad)

    try:                                            # the library: StoreError or a whole run
        with store.open_run(bad) as f:
            for name in TABLES:
                store.read_table(f, name)
            store.read_text(f, "config")
    except StoreError:
        pass

    before = sorted(p.name for p in tmp_path.rglob("*"))
    capsys.readouterr()
    runs = [
        ("gmtiflow-convert", lambda: convert.main([str(bad), "--to", "csv", "--table", "truth",
                                                   "-o", str(tmp_path / "out.csv")])),
        ("gmtiflow-evaluate", lambda: evaluate_cli.main([str(good_run / "tracks.csv"), str(bad),
                                                         "-o", str(tmp_path / "m.h5")])),
        ("gmtiflow-report", lambda: report_cli.main([str(bad_dir), "--runs", "-q",
                                                     "-o", str(tmp_path / "sweep.pdf")])),
    ]
    for prog, call in runs:
        code = call()
        err = capsys.readouterr().err
        errors = [ln for ln in err.splitlines() if "error" in ln.lower()]
        assert code == 1, (prog, err)
        assert errors and "run.h5" in errors[0], (prog, err)
        assert "Traceback" not in err, (prog, err)
    after = sorted(p.name for p in tmp_path.rglob("*"))
    new = set(after) - set(before)
    assert new <= {"sweep.pdf"}, new    # the sweep report lists a failed job; nothing else
