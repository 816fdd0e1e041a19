"""DEM readers: SRTM .hgt (real tile and synthetic stitched tiles), ESRI ASCII grids, voids."""
from __future__ import annotations

import logging
import os
from pathlib import Path

import numpy as np
import pytest

from gmtiflow.errors import InputFileError
from gmtiflow.scene import dem

# The project's shared data sit beside the repository checkout (shared/data); a checkout elsewhere
# (a git worktree) points GMTIFLOW_DATA_DIR at them, as the monaco preset does.
DATA = Path(os.environ.get("GMTIFLOW_DATA_DIR")
            or Path(__file__).resolve().parents[2].parent / "shared/data")
TILE = DATA / "N43E007.hgt"
needs_tile = pytest.mark.skipif(not TILE.is_file(),
                                reason=f"SRTM tile {TILE} absent: the project's shared/data beside the checkout, or set GMTIFLOW_DATA_DIR")


# ---------------------------------------------------------------------------------- bilinear
def test_bilinear_is_exact_on_planes():
    rng = np.random.default_rng(1)
    rows, cols = np.mgrid[0:7, 0:9].astype(float)
    a, b, c = rng.normal(size=3)
    grid = a + b * rows + c * cols
    r = rng.uniform(0, 6, 500)
    q = rng.uniform(0, 8, 500)
    np.testing.assert_allclose(dem.bilinear(grid, r, q), a + b * r + c * q, rtol=0, atol=1e-12)
    # the far edges are inside, one ulp beyond is not
    assert np.isfinite(dem.bilinear(grid, 6.0, 8.0))
    assert np.isnan(dem.bilinear(grid, 6.0 + 1e-9, 0.0))
    assert np.isnan(dem.bilinear(grid, 0.0, -1e-9))


def test_geogrid_and_enugrid_are_exact_on_planes():
    lat_max, lon_min, step = 44.0, 7.0, 1.0 / 1200
    i, j = np.mgrid[0:50, 0:60]
    lat, lon = lat_max - i * step, lon_min + j * step
    g = dem.GeoGrid(values=3.0 + 2000.0 * (lat - 43.9) - 500.0 * (lon - 7.0), lat_max_deg=lat_max,
                    lon_min_deg=lon_min, step_deg=step, source="plane")
    la = np.random.default_rng(2).uniform(g.lat_min_deg, lat_max, 200)
    lo = np.random.default_rng(3).uniform(lon_min, g.lon_max_deg, 200)
    np.testing.assert_allclose(g.at(la, lo), 3.0 + 2000.0 * (la - 43.9) - 500.0 * (lo - 7.0),
                               atol=1e-9)
    y, x = np.mgrid[0:20, 0:30]
    e = dem.EnuGrid(z=0.1 * (100 + 10 * x) - 0.3 * (-50 + 10 * y), x0_m=100, y0_m=-50, dx_m=10,
                    dy_m=10, source="plane")
    px, py = np.array([100.0, 123.4, 390.0]), np.array([-50.0, 77.7, 140.0])
    np.testing.assert_allclose(e.at(px, py), 0.1 * px - 0.3 * py, atol=1e-9)
    assert np.isnan(e.at(99.0, 0.0))


# ------------------------------------------------------------------------------ the real tile
@needs_tile
def test_tile_void_count_is_refused_with_file_and_count():
    with pytest.raises(InputFileError, match=r"N43E007\.hgt.*1595 void"):
        dem.read_hgt(TILE, voids="refuse")


@needs_tile
def test_tile_voids_are_filled_within_their_rim_and_logged(caplog):
    raw = np.fromfile(TILE, ">i2").reshape(1201, 1201)
    void = raw == dem.SRTM_VOID
    assert void.sum() == 1595
    with caplog.at_level(logging.INFO, logger="gmtiflow.scene.dem"):
        g = dem.read_hgt(TILE, voids="fill")
    assert "filled 1595 void samples" in caplog.text
    assert np.all(np.isfinite(g.values))
    np.testing.assert_array_equal(g.values[~void], raw[~void])  # valid samples untouched
    # a membrane stays within the range of the valid samples around it (maximum principle)
    from scipy import ndimage
    labels, n = ndimage.label(void)
    sizes = np.bincount(labels.ravel())[1:]
    assert n > 10
    for k in 1 + np.argsort(sizes)[-10:]:  # the ten largest holes
        sl = ndimage.find_objects((labels == k).astype(int))[0]
        sl = tuple(slice(max(s.start - 1, 0), s.stop + 1) for s in sl)
        hole = labels[sl] == k
        raw_w, val_w = raw[sl], g.values[sl]
        rim = ndimage.binary_dilation(hole) & ~hole
        assert raw_w[rim].min() - 1e-6 <= val_w[hole].min()
        assert val_w[hole].max() <= raw_w[rim].max() + 1e-6


@needs_tile
def test_tile_spot_checks_and_orientation():
    g = dem.read_hgt(TILE)
    assert g.values.shape == (1201, 1201)
    assert (g.lat_min_deg, g.lat_max_deg, g.lon_min_deg, g.lon_max_deg) == (43, 44, 7, 8)
    # Monaco Rocher, 43.7307 N 7.421392 E: the nearest sample is GraphHopper's 66 m. It sits on
    # the cliff edge: the bilinear value between the four surrounding samples (58 66 / 17 42) is
    # 58.6 m, and the sample just east reads 70 m (the data README's "about 70").
    lat, lon = 43.7307, 7.421392
    r, c = (44 - lat) * 1200, (lon - 7) * 1200
    assert g.values[int(round(r)), int(round(c))] == 66
    assert g.values[int(r), int(c) + 2] == 70
    four = g.values[int(r):int(r) + 2, int(c):int(c) + 2]
    fr, fc = r - int(r), c - int(c)
    by_hand = ((1 - fr) * ((1 - fc) * four[0, 0] + fc * four[0, 1])
               + fr * ((1 - fc) * four[1, 0] + fc * four[1, 1]))
    assert g.at(lat, lon) == pytest.approx(by_hand, abs=1e-9)
    assert g.at(lat, lon) == pytest.approx(58.63, abs=0.01)
    # Mont Agel: 1,109 m at the sample 43.774167 N 7.424167 E; the massif tops out near 1,140 m
    assert g.at(44 - 271 / 1200, 7 + 509 / 1200) == pytest.approx(1109, abs=1e-6)
    box = g.values[int((44 - 43.79) * 1200):int((44 - 43.76) * 1200),
                   int((7.40 - 7) * 1200):int((7.44 - 7) * 1200)]
    assert 1100 <= box.max() <= 1150
    # the sea south of Monaco is at 0, the alps north are high: north is row 0
    assert abs(g.at(43.70, 7.42)) <= 1
    assert g.at(43.95, 7.45) > 500


@needs_tile
def test_tile_whole_range_matches_the_data_readme():
    g = dem.read_hgt(TILE)
    assert g.values.min() == -11 and g.values.max() == 2064


# ------------------------------------------------------------------------- synthetic tiles
def _plane(lat, lon):
    return 1000.0 + 1200.0 * (lat - 43.0) + 2400.0 * (lon - 7.0)


def _write_tile(folder: Path, lat0: int, lon0: int, n: int = 1201, func=_plane) -> Path:
    i, j = np.mgrid[0:n, 0:n]
    step = 1.0 / (n - 1)
    values = func(lat0 + 1 - i * step, lon0 + j * step)
    name = f"{'N' if lat0 >= 0 else 'S'}{abs(lat0):02d}{'E' if lon0 >= 0 else 'W'}{abs(lon0):03d}.hgt"
    dem.write_hgt(folder / name, values)
    return folder / name


def test_stitched_tiles_are_continuous_across_the_seams(tmp_path):
    west = _write_tile(tmp_path, 43, 7)
    east = _write_tile(tmp_path, 43, 8)
    north = _write_tile(tmp_path, 44, 7)
    ne = _write_tile(tmp_path, 44, 8)
    g = dem.read_hgt_tiles([ne, east, west, north])  # order does not matter
    assert g.values.shape == (2401, 2401)  # shared edges held once
    assert (g.lat_min_deg, g.lat_max_deg, g.lon_min_deg, g.lon_max_deg) == (43, 45, 7, 9)
    rng = np.random.default_rng(4)
    lat = rng.uniform(43, 45, 2000)
    lon = rng.uniform(7, 9, 2000)
    np.testing.assert_allclose(g.at(lat, lon), _plane(lat, lon), atol=1e-6)
    # right on and either side of both seams
    for d in (-1e-7, 0.0, 1e-7):
        np.testing.assert_allclose(g.at(43.5, 8 + d), _plane(43.5, 8 + d), atol=1e-3)
        np.testing.assert_allclose(g.at(44 + d, 7.5), _plane(44 + d, 7.5), atol=1e-3)


def test_stitch_takes_a_seam_void_from_the_other_tile_and_leaves_missing_tiles_empty(tmp_path):
    west = _write_tile(tmp_path, 43, 7)
    east = _write_tile(tmp_path, 43, 8)
    raw = np.fromfile(east, ">i2").reshape(1201, 1201).copy()
    raw[600, 0] = dem.SRTM_VOID  # on the shared edge lon = 8
    raw.tofile(east)
    g = dem.read_hgt_tiles([west, east])
    assert g.values[600, 1200] == _plane(43.5, 8.0)
    with pytest.raises(InputFileError, match=r"N43E008\.hgt: 1 void"):
        dem.read_hgt_tiles([west, east], voids="refuse")
    diag = _write_tile(tmp_path, 44, 8)
    g = dem.read_hgt_tiles([west, diag])
    assert np.isnan(g.at(44.5, 7.5)) and np.isnan(g.at(43.5, 8.5))
    assert g.at(43.5, 7.5) == pytest.approx(_plane(43.5, 7.5))


def test_srtm1_size_and_southern_western_names(tmp_path):
    p = tmp_path / "S34W071.hgt"
    np.full((3601, 3601), 100, ">i2").tofile(p)
    assert p.name == "S34W071.hgt"
    g = dem.read_hgt(p)
    assert g.values.shape == (3601, 3601) and g.step_deg == pytest.approx(1 / 3600)
    assert (g.lat_min_deg, g.lon_min_deg) == (-34, -71)


def test_files_that_are_not_tiles(tmp_path):
    bad = tmp_path / "N43E007.hgt"
    bad.write_bytes(b"\0" * 1000)
    with pytest.raises(InputFileError, match=r"N43E007\.hgt: 1000 B is not an SRTM"):
        dem.read_hgt(bad)
    named = tmp_path / "monaco.hgt"
    named.write_bytes(b"\0" * (2 * 1201 * 1201))
    with pytest.raises(InputFileError, match=r"monaco\.hgt: not an SRTM tile name"):
        dem.read_hgt(named)
    with pytest.raises(InputFileError, match="not found"):
        dem.read_hgt(tmp_path / "N10E010.hgt")
    a = _write_tile(tmp_path, 43, 7)
    b = tmp_path / "N43E008.hgt"
    np.zeros((3601, 3601), ">i2").tofile(b)
    with pytest.raises(InputFileError, match="cannot be stitched"):
        dem.read_hgt_tiles([a, b])
    with pytest.raises(InputFileError, match="given twice"):
        dem.read_hgt_tiles([a, a])


def test_all_void_tile_cannot_be_filled(tmp_path):
    p = _write_tile(tmp_path, 43, 7, func=lambda la, lo: np.nan + la)
    with pytest.raises(InputFileError, match="every sample is void"):
        dem.read_hgt(p)


def test_fill_reproduces_a_plane_in_interior_holes():
    y, x = np.mgrid[0:40, 0:50].astype(float)
    truth = 5.0 + 0.7 * x - 1.3 * y
    holes = np.zeros_like(truth, bool)
    holes[10:15, 20:31] = True
    holes[30, 5] = True
    values = np.where(holes, -32768.0, truth)
    dem.fill_voids(values, holes)
    np.testing.assert_allclose(values, truth, atol=1e-9)


# ------------------------------------------------------------------------------- ASCII grids
def _grid():
    y, x = np.mgrid[0:5, 0:7].astype(float)
    return dem.EnuGrid(z=10.0 + x * 1.5 - y * 0.25, x0_m=-300.0, y0_m=200.0, dx_m=50.0, dy_m=50.0,
                       source="mem")


def test_ascii_grid_round_trip(tmp_path):
    g = _grid()
    path = tmp_path / "g.asc"
    dem.write_ascii_grid(path, g)
    back = dem.read_ascii_grid(path)
    np.testing.assert_array_equal(back.z, g.z)
    assert (back.x0_m, back.y0_m, back.dx_m, back.dy_m) == (-300.0, 200.0, 50.0, 50.0)
    text = path.read_text().splitlines()
    assert text[2] == "xllcorner -325.0" and text[3] == "yllcorner 175.0"
    # first data row is the north edge
    assert float(text[6].split()[0]) == g.z[-1, 0]


def test_ascii_grid_center_header_and_wrapped_rows(tmp_path):
    path = tmp_path / "c.asc"
    path.write_text("NCOLS 3\nNROWS 2\nXLLCENTER 0\nYLLCENTER 0\nCELLSIZE 10\n"
                    "1 2\n3\n4 5 6\n")
    g = dem.read_ascii_grid(path)
    np.testing.assert_array_equal(g.z, [[4, 5, 6], [1, 2, 3]])
    assert g.at(0.0, 10.0) == 1 and g.at(20.0, 0.0) == 6 and g.at(5.0, 5.0) == pytest.approx(3.0)


@pytest.mark.parametrize("text, pattern", [
    ("ncols 3\nnrows 2\nxllcorner 0\nyllcorner 0\ncellsize ten\n1 2 3\n4 5 6\n",
     r"line 5: cellsize must be a number, got 'ten'"),
    ("nrows 2\nxllcorner 0\nyllcorner 0\ncellsize 1\n1 2 3\n4 5 6\n", r"no ncols line"),
    ("ncols 3\nnrows 2\nxllcorner 0\nyllcorner 0\ncellsize 1\n1 2 3\n4 x 6\n",
     r"line 7: 'x' is not a number"),
    ("ncols 3\nnrows 2\nxllcorner 0\nyllcorner 0\ncellsize 1\n1 2 3\n4 5\n",
     r"line 7: 2 values, but the header says ncols=3"),
    ("ncols 3\nnrows 3\nxllcorner 0\nyllcorner 0\ncellsize 1\n1 2 3\n4 5 6\n",
     r"2 data rows of 3 values, but the header says nrows=3"),
    ("ncols 3\nnrows 2\nxllcorner 0\nyllcorner 0\ncellsize -1\n1 2 3\n4 5 6\n",
     r"line 5: cellsize must be > 0"),
    ("ncols 2.5\nnrows 2\nxllcorner 0\nyllcorner 0\ncellsize 1\n1 2 3\n4 5 6\n",
     r"line 1: ncols must be an integer"),
    ("ncols 3\nnrows 2\nxllcorner 0\nxllcenter 0\nyllcorner 0\ncellsize 1\n1 2 3\n4 5 6\n",
     r"exactly one of xllcorner, xllcenter"),
    ("ncols 3\nnrows 2\nxllcorner 0\nyllcorner 0\nzoom 1\ncellsize 1\n1 2 3\n4 5 6\n",
     r"line 5: unknown header key 'zoom'"),
    ("1 2 3\n", r"no ncols line"),
])
def test_malformed_ascii_grids_name_file_and_line(tmp_path, text, pattern):
    path = tmp_path / "bad.asc"
    path.write_text(text)
    with pytest.raises(InputFileError, match=r"bad\.asc.*" + pattern):
        dem.read_ascii_grid(path)


def test_ascii_nodata_fill_and_refuse(tmp_path):
    path = tmp_path / "v.asc"
    path.write_text("ncols 3\nnrows 3\nxllcorner 0\nyllcorner 0\ncellsize 1\nNODATA_value -9999\n"
                    "1 2 3\n4 -9999 6\n7 8 9\n")
    g = dem.read_ascii_grid(path)
    assert g.z[1, 1] == pytest.approx(5.0)
    with pytest.raises(InputFileError, match=r"v\.asc: 1 void"):
        dem.read_ascii_grid(path, voids="refuse")


def test_binary_file_is_not_an_ascii_grid(tmp_path):
    path = tmp_path / "b.asc"
    path.write_bytes(b"\xff\xfe\x00\x81" * 10)
    with pytest.raises(InputFileError, match=r"b\.asc"):
        dem.read_ascii_grid(path)


def test_a_byte_swapped_or_damaged_tile_is_refused_with_its_heights(tmp_path):
    """SRTM is big-endian; a tile written little-endian (numpy's default '<i2') gave heights of
    tens of kilometres (Monaco: 22 % of the samples beyond -1000..9000 m) and a run whose
    vehicles were all hidden, exit 0."""
    p = tmp_path / "N43E007.hgt"
    heights = np.full((1201, 1201), 150, np.int16)
    heights.astype("<i2").tofile(p)                       # 150 m read back as 38,400 -> -27136
    with pytest.raises(InputFileError, match=r"N43E007\.hgt: .*-27136 m .*row 0, column 0.*"
                                             r"byte-swapped"):
        dem.read_hgt(p)
    heights[600, 700] = 9500                              # a spike above Everest, big-endian
    heights.astype(">i2").tofile(p)
    with pytest.raises(InputFileError, match=r"9500 m .*row 600, column 700"):
        dem.read_hgt(p)
    heights[600, 700] = -430                              # the Dead Sea shore is a real height
    heights.astype(">i2").tofile(p)
    assert dem.read_hgt(p).values[600, 700] == -430


@pytest.mark.parametrize("height", [1e30, -1e7, 2.1e6])
def test_ascii_grid_heights_off_the_earth_are_refused(tmp_path, height):
    """1e30 m ran to exit 0 with nothing visible; -1e7 m ended the run with "tracker
    NNKalmanTracker: row 1: negative variance" (blaming the tracker); 2.1e6 is 2,100 m in mm."""
    p = tmp_path / "grid.asc"
    rows = [[10.0] * 4 for _ in range(3)]
    rows[1][2] = height
    p.write_text("ncols 4\nnrows 3\nxllcorner 0\nyllcorner 0\ncellsize 10\n"
                 + "".join(" ".join(f"{v:g}" for v in r) + "\n" for r in rows))
    with pytest.raises(InputFileError, match=r"grid\.asc: 1 heights outside -11000\.\.11000 m"
                                             r", the first .* at row 1, column 2"):
        dem.read_ascii_grid(p)
