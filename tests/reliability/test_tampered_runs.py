"""Tampered run files (issue 17, item 12): every consumer ends cleanly.

A complete run file is edited in the ways a hand, a script or an attacker might: columns deleted
or turned into text, root attributes of the wrong shape or type, a ``/config`` with
``${oc.env:...}`` interpolations or broken YAML, external links, virtual datasets, a column that
claims 1.5e9 rows it does not store.  ``gmtiflow-convert`` (to 4607 and GeoJSON),
``gmtiflow-evaluate`` and ``gmtiflow-report --runs`` must each either succeed or exit 1 with one
``error:`` line naming the run file: never a traceback (any exception escaping ``main`` fails
the test).  The library's ``open_run`` raises StoreError for the structural cases.
"""
from __future__ import annotations

import os
import shutil

import h5py
import numpy as np
import pytest

from gmtiflow import convert, store
from gmtiflow.errors import StoreError
from gmtiflow.evaluate import cli as evaluate_cli
from gmtiflow.report import cli as report_cli

TABLES = ["truth", "detections", "dwells", "tracks", "platform", "looks", "vehicles",
          "roads/nodes", "roads/edges"]


def _drop(table, which):
    def make(f):
        cols = sorted(f[table])
        del f[f"{table}/{cols[which]}"]
    return make


def _to_text(table, which):
    def make(f):
        cols = sorted(k for k in f[table] if h5py.check_string_dtype(f[table][k].dtype) is None)
        name = f"{table}/{cols[which]}"
        n = f[name].shape[0]
        del f[name]
        f.create_dataset(name, data=np.asarray(["x"] * n, dtype=object),
                         dtype=h5py.string_dtype())
    return make


def _attr(key, value):
    def make(f):
        f.attrs[key] = value
    return make


def _del_attr(key):
    def make(f):
        del f.attrs[key]
    return make


def _config(text):
    def make(f):
        del f["config"]
        f.create_dataset("config", data=text, dtype=h5py.string_dtype())
    return make


def _config_group(f):
    del f["config"]
    f.create_group("config")


def _external_link(f):
    other = os.path.join(os.path.dirname(f.filename), "secret.h5")
    with h5py.File(other, "w") as o:
        o["x"] = np.arange(10.0)
    del f["truth/x_m"]
    f["truth/x_m"] = h5py.ExternalLink("secret.h5", "/x")


def _soft_link(f):
    del f["truth/x_m"]
    f["truth/x_m"] = h5py.SoftLink("/truth/y_m")


def _virtual(f):
    n = f["truth/y_m"].shape[0]
    layout = h5py.VirtualLayout(shape=(n,), dtype="f8")
    layout[:] = h5py.VirtualSource(".", "truth/y_m", shape=(n,))
    del f["truth/x_m"]
    f.create_virtual_dataset("truth/x_m", layout)


def _bomb(f):
    del f["detections/snr_db"]
    f.create_dataset("detections/snr_db", shape=(1_500_000_000,), dtype="f8",
                     chunks=(65536,), compression="gzip")


def _two_d(f):
    n = f["truth/x_m"].shape[0]
    del f["truth/x_m"]
    f["truth/x_m"] = np.zeros((n, 2))


def _table_as_dataset(f):
    del f["truth"]
    f["truth"] = np.arange(5.0)


def _compound(f):
    n = f["truth/x_m"].shape[0]
    del f["truth/x_m"]
    f["truth/x_m"] = np.zeros(n, dtype=[("a", "f8"), ("b", "i4")])


VARIANTS = {
    **{f"drop_{t}_{w}": _drop(t, w) for t in TABLES for w in (0, -1)},
    **{f"text_{t}_{w}": _to_text(t, w) for t in TABLES for w in (0, -1)},
    "origin_as_array": _attr("origin_lat_deg", np.array([43.7, 7.4])),
    "origin_as_text": _attr("origin_lon_deg", "east"),
    "origin_nan": _attr("origin_lat_deg", np.nan),
    "origin_out_of_range": _attr("origin_lat_deg", 500.0),
    "no_origin": _del_attr("origin_lat_deg"),
    "epoch_garbage": _attr("scene_epoch_utc", "yesterday"),
    "epoch_number": _attr("scene_epoch_utc", 5),
    "seed_text": _attr("seed", "one"),
    "config_env_interpolation": _config("seed: ${oc.env:HOME}\nmetrics:\n  enabled: true\n"),
    "config_nested_interpolation": _config("metrics:\n  gate_m: ${oc.env:PATH}\n"),
    "config_not_yaml": _config("seed: [1, 2\n"),
    "config_a_list": _config("- 1\n- 2\n"),
    "config_group": _config_group,
    "external_link": _external_link,
    "soft_link": _soft_link,
    "virtual_dataset": _virtual,
    "bomb_1.5e9_rows": _bomb,
    "column_2d": _two_d,
    "table_as_dataset": _table_as_dataset,
    "compound_column": _compound,
}
STRUCTURAL = {"external_link", "soft_link", "virtual_dataset", "bomb_1.5e9_rows", "column_2d",
              "config_env_interpolation", "config_nested_interpolation", "config_not_yaml",
              "config_a_list", "config_group", "origin_as_array", "origin_as_text", "origin_nan",
              "origin_out_of_range", "epoch_garbage", "epoch_number", "seed_text",
              "compound_column"}


def make_variant(src_dir, job_dir, variant):
    job_dir.mkdir()
    bad = job_dir / "run.h5"
    shutil.copy(src_dir / "run.h5", bad)
    with h5py.File(bad, "r+") as f:
        VARIANTS[variant](f)
    return bad


def consumers(bad, out, tracks):
    return [
        ("convert-4607", lambda: convert.main([str(bad), "--to", "4607", "-o",
                                               str(out / "d.4607")])),
        ("convert-geojson", lambda: convert.main([str(bad), "--to", "geojson", "-o",
                                                  str(out / "s.geojson")])),
        ("evaluate", lambda: evaluate_cli.main([str(tracks), str(bad), "-o",
                                                str(out / "m.h5")])),
        ("report", lambda: report_cli.main([str(bad.parent), "--runs", "-q", "-o",
                                            str(out / "sweep.pdf")])),
    ]


@pytest.mark.parametrize("variant", sorted(VARIANTS))
def test_tampered_run_file_is_a_clean_error_or_a_clean_run(small_run_dir, tmp_path, capsys,
                                                           variant):
    bad = make_variant(small_run_dir, tmp_path / "job", variant)
    if variant in STRUCTURAL:
        with pytest.raises(StoreError, match="run.h5"):
            store.open_run(bad)
    outcomes = {}
    for prog, call in consumers(bad, tmp_path, small_run_dir / "tracks.csv"):
        capsys.readouterr()
        code = call()                       # any exception escaping main fails the test
        err = capsys.readouterr().err
        assert "Traceback" not in err, (prog, err)
        assert code in (0, 1), (prog, code, err)
        if code == 1:
            first = [ln for ln in err.splitlines() if "error" in ln.lower()]
            assert first and "run.h5" in first[0], (prog, err)
            assert "/home" not in err and os.environ.get("HOME", "/root") not in err, err
        outcomes[prog] = code
    if variant in STRUCTURAL:
        assert all(c == 1 for c in outcomes.values()), outcomes
