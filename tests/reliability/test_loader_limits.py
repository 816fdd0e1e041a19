"""Loaders refuse nonsense, bound their resources and never echo a file's content
(issue 17, items 6, 9, 13)."""
from __future__ import annotations

import os
import time

import numpy as np
import pytest

from gmtiflow import config
from gmtiflow.compose import compose
from gmtiflow.errors import ConfigError, InputFileError, RoadMapError
from gmtiflow.scene import dem
from gmtiflow.scene.geojson_roads import load_geojson
from gmtiflow.scene.osm import load_osm
from gmtiflow.sensor import rcs

SECRET = "root:$6$s3cr3tSalt$9aXhashhashhash:19000:0:99999:7:::"


# ---- RCS tables --------------------------------------------------------------------------
def test_rcs_table_on_a_device_is_refused_unread():
    start = time.process_time()
    with pytest.raises(InputFileError, match="not a regular file"):
        rcs.load_table("/dev/zero")
    assert time.process_time() - start < 1.0


def test_rcs_table_over_the_size_cap_is_refused_unread(tmp_path):
    big = tmp_path / "big.csv"
    with open(big, "wb") as f:                  # sparse: costs no disk
        f.truncate(rcs.MAX_TABLE_BYTES + 1)
    with pytest.raises(InputFileError, match="over the 16 MiB"):
        rcs.load_table(str(big))


@pytest.mark.parametrize("value", ["1e308", "-1e308", "101"])
def test_rcs_beyond_100_dbsm_is_refused(tmp_path, value):
    t = tmp_path / "t.csv"
    t.write_text(f"aspect_deg,rcs_dbsm\n0,10\n90,{value}\n")
    with pytest.raises(InputFileError, match="line 3: rcs_dbsm .* beyond"):
        rcs.load_table(str(t))


@pytest.mark.parametrize("body", [SECRET + "\n", "aspect_deg,rcs_dbsm\n0," + SECRET + "\n",
                                  "aspect_deg,rcs_dbsm\n" + SECRET.replace(":", ",") + "\n"])
def test_rcs_errors_never_echo_the_file(tmp_path, body):
    t = tmp_path / "shadow"
    t.write_text(body)
    with pytest.raises(InputFileError) as info:
        rcs.load_table(str(t))
    assert "s3cr3t" not in str(info.value) and "99999" not in str(info.value), info.value


def test_secret_file_as_rcs_table_is_not_echoed_by_the_cli(tmp_path, capsys):
    import subprocess
    import sys
    t = tmp_path / "shadow"
    t.write_text(SECRET + "\n")
    out = tmp_path / "run"
    res = subprocess.run([sys.executable, "-m", "gmtiflow.cli", f"hydra.run.dir={out}",
                          f"sensor.rcs.car.table={t}", "scene.duration_s=5", "export=none",
                          "report=none", "progress=false"], capture_output=True, text=True,
                         cwd=tmp_path, timeout=300)
    assert res.returncode == 1 and "RCS table" in res.stderr, res.stderr
    assert "s3cr3t" not in res.stderr + res.stdout
    log = out / "gmtiflow.log"     # a run that fails before any stage leaves no run dir
    assert not log.exists() or "s3cr3t" not in log.read_text()


# ---- DEM ---------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["N99E999.hgt", "N90E000.hgt", "S91W000.hgt", "N00E180.hgt"])
def test_srtm_tile_name_outside_the_globe_is_refused(tmp_path, name):
    with pytest.raises(InputFileError, match="no SRTM tile"):
        dem.hgt_corner(tmp_path / name)


def test_srtm_tile_names_at_the_edges_are_accepted(tmp_path):
    assert dem.hgt_corner(tmp_path / "S90W180.hgt") == (-90, -180)
    assert dem.hgt_corner(tmp_path / "N89E179.hgt") == (89, 179)


def test_ascii_grid_errors_never_echo_the_file(tmp_path):
    g = tmp_path / "grid.asc"
    g.write_text(SECRET.replace(":", " ", 1) + "\n")
    with pytest.raises(InputFileError) as info:
        dem.read_ascii_grid(g)
    assert "s3cr3t" not in str(info.value)


def test_void_fill_is_per_hole_and_equals_the_global_solve():
    rng = np.random.default_rng(0)
    values = rng.normal(100.0, 5.0, (60, 70))
    void = np.zeros(values.shape, bool)
    void[5:15, 5:20] = True
    void[30:50, 40:45] = True
    void[0, 69] = True
    per_hole = dem.fill_voids(values.copy(), void)
    whole = dem._laplace_solve(values.copy(), void)      # the former single global system
    np.testing.assert_allclose(per_hole, whole, rtol=0, atol=1e-9)


def test_void_larger_than_the_cap_is_refused_quickly():
    values = np.zeros((1201, 1201))
    void = np.zeros(values.shape, bool)
    void[:, :700] = True                                  # a half-void SRTM3 tile
    start = time.process_time()
    with pytest.raises(ValueError, match="larger than the 100000 samples"):
        dem.fill_voids(values, void)
    assert time.process_time() - start < 5.0


def test_many_holes_are_solved_in_bounded_batches(monkeypatch):
    monkeypatch.setattr(dem, "MAX_VOID_COMPONENT", 50)
    calls = []
    real = dem._laplace_solve
    monkeypatch.setattr(dem, "_laplace_solve", lambda v, m: calls.append(int(m.sum())) or
                        real(v, m))
    values = np.random.default_rng(1).normal(0, 1, (40, 40))
    void = np.zeros(values.shape, bool)
    void[2:38:4, 2:38:4] = True                           # 81 single-sample holes
    filled = dem.fill_voids(values.copy(), void)
    assert np.isfinite(filled).all() and max(calls) <= 50 and sum(calls) == 81


# ---- OSM ---------------------------------------------------------------------------------
OSM = """<?xml version='1.0'?>
<osm version='0.6'>
  {bounds}
  <node id='1' lat='43.70' lon='7.40'/>
  <node id='2' lat='43.71' lon='7.41'/>
  {extra}
  <way id='10'><nd ref='1'/><nd ref='2'/><tag k='highway' v='primary'/></way>
</osm>
"""


@pytest.mark.parametrize("bounds", [
    "<bounds minlat='500' minlon='7.3' maxlat='43.8' maxlon='7.5'/>",
    "<bounds minlat='43.6' minlon='7.3' maxlat='43.8' maxlon='181'/>",
    "<bounds minlat='43.9' minlon='7.3' maxlat='43.8' maxlon='7.5'/>",
    "<bounds minlat='nan' minlon='7.3' maxlat='43.8' maxlon='7.5'/>",
])
def test_osm_bounds_out_of_range_are_refused(tmp_path, bounds):
    p = tmp_path / "m.osm"
    p.write_text(OSM.format(bounds=bounds, extra=""))
    with pytest.raises(RoadMapError, match="<bounds> .* out of range|lacks numeric"):
        load_osm(p)


def test_osm_duplicate_node_with_another_position_is_refused(tmp_path):
    p = tmp_path / "m.osm"
    p.write_text(OSM.format(bounds="", extra="<node id='2' lat='44.0' lon='7.41'/>"))
    with pytest.raises(RoadMapError, match="node 2 appears twice"):
        load_osm(p)


def test_osm_duplicate_node_with_the_same_position_is_accepted(tmp_path):
    p = tmp_path / "m.osm"
    p.write_text(OSM.format(bounds="", extra="<node id='2' lat='43.71' lon='7.41'/>"))
    assert len(load_osm(p).nodes["node_id"]) == 2


# ---- GeoJSON road maps --------------------------------------------------------------------
def _gj(coords: str) -> str:
    return ('{"type": "FeatureCollection", "features": [{"type": "Feature", "properties": {}, '
            '"geometry": {"type": "LineString", "coordinates": ' + coords + '}}]}')


@pytest.mark.parametrize("coords", ["[[7.4, 43.7], [7.41, true]]", "[[7.4, 43.7], [null, 43.71]]",
                                    '[[7.4, 43.7], ["7.41", 43.71]]'])
def test_geojson_coordinates_must_be_numbers(tmp_path, coords):
    p = tmp_path / "r.geojson"
    p.write_text(_gj(coords))
    with pytest.raises(RoadMapError, match="must be .* numbers"):
        load_geojson(p)


def test_geojson_5000_digit_number_is_a_roadmap_error(tmp_path):
    p = tmp_path / "r.geojson"
    p.write_text(_gj("[[7.4, 43.7], [7.41, " + "4" * 5000 + "]]"))
    with pytest.raises(RoadMapError, match="too long"):
        load_geojson(p)


def test_geojson_on_a_device_is_refused(tmp_path):
    with pytest.raises(InputFileError):
        load_geojson("/dev/zero")


# ---- config: the epoch ---------------------------------------------------------------------
@pytest.mark.parametrize("epoch", ["9999-12-31T23:59:00Z", "1969-12-31T23:59:59Z"])
def test_epoch_whose_scene_leaves_years_1970_9999_is_refused(epoch):
    with pytest.raises(ConfigError, match="scene.epoch_utc"):
        config.validate(compose(["scene.duration_s=300", f"scene.epoch_utc={epoch}"]))


def test_epoch_late_in_9999_with_a_short_scene_is_accepted():
    config.validate(compose(["scene.duration_s=60", "scene.epoch_utc=9999-12-31T23:00:00Z"]))


# ---- gmtiflow-convert: an empty file --------------------------------------------------------
@pytest.mark.parametrize("suffix", [".4607", ".xml", ".csv", ".geojson"])
def test_empty_file_does_not_convert_to_an_empty_run(tmp_path, capsys, suffix):
    from gmtiflow import convert
    src = tmp_path / f"empty{suffix}"
    src.write_bytes(b"")
    code = convert.main([str(src), "--to", "h5", "-o", str(tmp_path / "out.h5")])
    assert code == 1 and "empty (0 bytes)" in capsys.readouterr().err
    assert not (tmp_path / "out.h5").exists()
