"""Terrain: config checks, ENU heights (pymap3d consistency), draping, coverage, line of sight."""
from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pymap3d
import pytest
from omegaconf import OmegaConf

from gmtiflow import frames
from gmtiflow.errors import InputFileError
from gmtiflow.scene import dem
from gmtiflow.scene import terrain as T
from gmtiflow.scene.hills import HillConfig

REPO = Path(__file__).resolve().parents[2]
DATA = Path(os.environ.get("GMTIFLOW_DATA_DIR") or REPO.parent / "shared/data")
TILE = DATA / "N43E007.hgt"
needs_tile = pytest.mark.skipif(not TILE.is_file(), reason=f"SRTM tile {TILE} absent: the project's "
                                "shared/data beside the checkout, or set GMTIFLOW_DATA_DIR")
ROCHER = frames.Origin(43.7307, 7.421392, 0.0)
N_MONACO = 50.0


def preset(name: str) -> T.TerrainConfig:
    cfg = OmegaConf.merge(OmegaConf.structured(T.TerrainConfig),
                          OmegaConf.load(REPO / "conf/terrain" / f"{name}.yaml"))
    return OmegaConf.to_object(cfg)


@pytest.fixture(scope="module")
def hills():
    return T.build_terrain(preset("hills"), ROCHER)


@pytest.fixture(scope="module")
def monaco():
    if not TILE.is_file():
        pytest.skip(f"SRTM tile {TILE} absent")
    cfg = T.TerrainConfig(kind=T.TerrainKind.srtm, paths=[str(TILE)], geoid_offset_m=N_MONACO)
    return T.build_terrain(cfg, ROCHER)


# ------------------------------------------------------------------------------------ config
def test_presets_validate():
    for name in ("flat", "hills"):
        assert preset(name).problems() == []
    assert preset("hills").kind is T.TerrainKind.hills


@needs_tile
def test_monaco_preset_works_from_any_directory(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("GMTIFLOW_DATA_DIR", str(DATA))
    cfg = preset("monaco")
    assert cfg.problems() == [] and cfg.geoid_offset_m == N_MONACO
    ter = T.build_terrain(cfg, ROCHER)
    assert ter.height_at(0.0, 0.0) == pytest.approx(58.63 + N_MONACO, abs=0.05)


def test_config_problems_name_the_key():
    keys = {p.key for p in T.TerrainConfig(kind=T.TerrainKind.srtm).problems()}
    assert keys == {"paths", "geoid_offset_m"}
    bad = T.TerrainConfig(kind=T.TerrainKind.hills, hills=[T.HillConfig(sigma_m=-1)],
                          clearance_m=-2.0, grid_spacing_m=0.0)
    keys = {p.key for p in bad.problems()}
    assert {"hills[0].sigma_m", "clearance_m", "grid_spacing_m"} <= keys
    assert T.TerrainConfig(kind=T.TerrainKind.ascii_grid).problems()[0].key == "path"
    assert T.TerrainConfig(kind=T.TerrainKind.srtm, paths=["x.hgt"],
                           geoid_offset_m=500.0).problems()[0].key == "geoid_offset_m"


def test_missing_dem_file_is_an_input_file_error(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    cfg = T.TerrainConfig(kind=T.TerrainKind.srtm, paths=["N43E007.hgt"], geoid_offset_m=50.0)
    with pytest.raises(InputFileError, match=r"N43E007\.hgt: SRTM tile not found.*absolute path"):
        T.build_terrain(cfg, ROCHER)


# ---------------------------------------------------------------------------------- heights
@needs_tile
def test_height_at_lies_on_the_dem_surface_through_pymap3d(monaco):
    rng = np.random.default_rng(5)
    x = rng.uniform(-30e3, 40e3, 300)
    y = rng.uniform(-20e3, 25e3, 300)
    z = monaco.height_at(x, y)
    assert np.all(np.isfinite(z))
    # map z is the height above the ellipsoid minus the origin's, at the map point's lat/lon
    lat, lon, h = frames.enu_to_geodetic(ROCHER, x, y, z)
    ground = dem.read_hgt(TILE).at(lat, lon) + N_MONACO
    np.testing.assert_allclose(h, ground, atol=1e-3)
    # the earth's curvature is in the geometry, not in z: sea level 30 km out is at z = N
    sea = monaco.height_at(np.array([0.0]), np.array([-30e3]))  # over the sea south of Monaco
    assert sea[0] == pytest.approx(N_MONACO, abs=1e-6)
    # ... and lies d²/2R below the origin's tangent plane (pymap3d's ENU of that point)
    _, _, u = pymap3d.geodetic2enu(*frames.enu_to_geodetic(ROCHER, 0.0, -30e3, sea[0]),
                                   ROCHER.lat_deg, ROCHER.lon_deg, ROCHER.height_m)
    assert float(u) == pytest.approx(N_MONACO - 30e3 ** 2 / (2 * 6.37e6), abs=1.5)


@needs_tile
def test_height_at_known_point_matches_geodetic2enu(monaco):
    lat, lon = 43.774167, 7.424167  # a Mont Agel sample (1,109 m above the geoid)
    x, y, z = frames.geodetic_to_enu(ROCHER, lat, lon, 1109 + N_MONACO)
    assert z == pytest.approx(1109 + N_MONACO)
    assert monaco.height_at(x, y) == pytest.approx(z, abs=0.05)
    higher = frames.Origin(ROCHER.lat_deg, ROCHER.lon_deg, 100.0)
    cfg = T.TerrainConfig(kind=T.TerrainKind.srtm, paths=[str(TILE)], geoid_offset_m=N_MONACO)
    assert T.build_terrain(cfg, higher).height_at(x, y) == pytest.approx(z - 100.0, abs=0.05)


def test_hills_grid_matches_the_analytic_shape(hills):
    cfg = preset("hills")
    rng = np.random.default_rng(6)
    x = rng.uniform(-4000, 4000, 2000)
    y = rng.uniform(-1000, 2000, 2000)
    exact = T.hills_height(cfg.hills, x, y, cfg.hills_base_height_m)
    # bilinear error <= h'' dx² / 8: 200 m / (150 m)² * 25² / 8 = 0.7 m at the crest
    assert np.max(np.abs(hills.height_at(x, y) - exact)) < 0.75
    assert hills.height_at(0.0, 500.0) == pytest.approx(200.0, abs=0.5)
    assert hills.height_at(50e3, 50e3) == cfg.hills_base_height_m  # base plane off the grid
    hills.check_covers(-1e5, 1e5, -1e5, 1e5)  # defined everywhere


def test_ascii_grid_terrain_is_exact_on_a_plane_and_errors_off_it(tmp_path):
    yy, xx = np.mgrid[0:21, 0:31]
    g = dem.EnuGrid(z=20.0 + 0.02 * (xx * 100.0) + 0.01 * (yy * 100.0), x0_m=0, y0_m=0, dx_m=100,
                    dy_m=100, source="g")
    path = tmp_path / "plane.asc"
    dem.write_ascii_grid(path, g)
    ter = T.build_terrain(T.TerrainConfig(kind=T.TerrainKind.ascii_grid, path=str(path)), ROCHER)
    x, y = np.array([0.0, 1234.5, 3000.0]), np.array([0.0, 987.6, 2000.0])
    np.testing.assert_allclose(ter.height_at(x, y), 20 + 0.02 * x + 0.01 * y, atol=1e-9)
    np.testing.assert_allclose(T.drape_points(ter, x, y), 20 + 0.02 * x + 0.01 * y, atol=1e-9)
    assert np.isnan(ter.height_at(-1.0, 0.0))
    with pytest.raises(InputFileError, match=r"plane\.asc: 1 of 2 points lie outside the DEM"):
        ter.drape([10.0, 5000.0], [10.0, 10.0])
    with pytest.raises(InputFileError, match=r"plane\.asc: the DEM does not cover"):
        ter.check_covers(0, 4000, 0, 1000)
    ter.check_covers(0, 3000, 0, 2000)


@needs_tile
def test_monaco_coverage(monaco):
    monaco.check_covers(-3000, 3000, -3000, 3000)
    with pytest.raises(InputFileError, match=r"N43E007\.hgt: the DEM does not cover.*43..44 N"):
        monaco.check_covers(-3000, 3000, 0, 40e3)  # reaches 44.09 N
    with pytest.raises(InputFileError, match="outside the DEM"):
        monaco.drape([0.0, 0.0], [0.0, 60e3])


# ----------------------------------------------------------------------------- line of sight
def _on_ground(ter, x, y):
    x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
    return np.c_[x, y, ter.height_at(x, y)]


def test_vehicle_behind_the_ridge_is_hidden_and_one_on_the_ridge_is_seen(hills):
    aircraft = np.array([0.0, -30e3, 6000.0])  # grazing ~11 deg
    behind = _on_ground(hills, [-2000.0, 0.0, 2000.0], [1200.0, 1200.0, 1200.0])
    crest = _on_ground(hills, [-2000.0, 0.0, 2000.0], [500.0, 500.0, 500.0])
    front = _on_ground(hills, [0.0], [-500.0])
    assert not hills.line_of_sight(aircraft, behind, 10.0).any()
    assert hills.line_of_sight(aircraft, crest, 10.0).all()
    assert hills.line_of_sight(aircraft, front, 10.0).all()
    # beyond the ridge's end the same road is in the open
    assert hills.line_of_sight(aircraft, _on_ground(hills, [4500.0], [1200.0]), 10.0).all()


def test_road_in_the_valley_appears_as_the_aircraft_comes_overhead(hills):
    road = _on_ground(hills, np.zeros(1), [1200.0])
    ys = np.arange(-40e3, 1201.0, 250.0)
    aircraft = np.c_[np.zeros_like(ys), ys, np.full_like(ys, 6000.0)]
    seen = hills.line_of_sight(aircraft, np.repeat(road, len(ys), axis=0), 10.0)
    assert not seen[0] and seen[-1]
    flip = np.nonzero(np.diff(seen.astype(int)))[0]
    assert len(flip) == 1  # hidden, then seen for good
    # the exact answer from the analytic ridge: the ray (from height 6000 m at distance D) is
    # seen once it clears every point of the ground by the clearance; the 25 m grid and the
    # 250 m spacing of the aircraft positions allow ~1.5 %
    cfg = preset("hills")
    yy = np.linspace(1200.0 - 25.0, 0.0, 5000)
    ground = T.hills_height(cfg.hills, 0.0, yy)

    def clears(dist):
        ray = road[0, 2] + (6000.0 - road[0, 2]) * (1200.0 - yy) / dist
        return np.all(ground <= ray + cfg.clearance_m)
    lo, hi = 10e3, 40e3  # clears at lo, not at hi
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if clears(mid) else (lo, mid)
    d_first_seen = 1200.0 - ys[flip[0] + 1]
    assert d_first_seen == pytest.approx(lo, rel=0.015)
    assert 19e3 < lo < 22e3  # ~ the knife-edge estimate 6000 * 700 / 200 = 21 km


def test_flat_terrain_never_marches(monkeypatch):
    def boom(*args, **kwargs):
        raise AssertionError("ray marching on flat terrain")
    monkeypatch.setattr(T, "march", boom)
    ter = T.build_terrain(preset("flat"), ROCHER)
    assert ter.flat
    seen = ter.line_of_sight(np.array([0.0, -30e3, 6000.0]), np.zeros((1000, 3)), 1.0)
    assert seen.shape == (1000,) and seen.all()
    assert ter.height_at(np.zeros((2, 3)), 1.0).shape == (2, 3)


def test_march_is_called_on_a_dem(hills, monkeypatch):
    calls = []
    real = T.march
    monkeypatch.setattr(T, "march", lambda *a: calls.append(1) or real(*a))
    hills.line_of_sight([0.0, -30e3, 6000.0], [0.0, 1200.0, 0.0], 10.0)
    assert calls == [1]


def test_extreme_geometries(hills):
    # straight down (90 deg grazing) onto the ridge's steep flank: seen
    flank = _on_ground(hills, [0.0], [700.0])
    assert hills.line_of_sight(flank + [0, 0, 6000.0], flank, 10.0).all()
    # grazing ~0 deg: a level ray 5 m over the base plane is clear, one through the ridge is not
    a, b = [-30e3, -15e3, 5.0], [30e3, -15e3, 5.0]
    assert hills.line_of_sight(a, b, 10.0).all()
    assert not hills.line_of_sight([0.0, -30e3, 5.0], [0.0, 30e3, 5.0], 10.0).any()
    # a ray grazing the crest: 0.5 m under it is within the 1 m clearance, 5 m under is not
    top = hills.height_at(0.0, 500.0)
    assert hills.line_of_sight([0, -5e3, top - 0.5], [0, 5e3, top - 0.5], 5.0).all()
    assert not hills.line_of_sight([0, -5e3, top - 5], [0, 5e3, top - 5], 5.0).any()
    # zero-length rays see themselves; non-finite ends are reported not visible
    p = _on_ground(hills, [0.0, 10.0], [1200.0, 500.0])
    assert hills.line_of_sight(p, p, 10.0).all()
    bad = np.array([[np.nan, 0.0, 0.0]])
    assert not hills.line_of_sight(bad, p[:1], 10.0).any()
    with pytest.raises(ValueError, match="step_m"):
        hills.line_of_sight(p, p, 0.0)
    with pytest.raises(ValueError, match="shape"):
        hills.line_of_sight(np.zeros((2, 2)), p, 10.0)


def test_chunking_does_not_change_the_answer():
    rng = np.random.default_rng(7)
    n = 3000
    tgt = np.c_[rng.uniform(-4e3, 4e3, n), rng.uniform(-1e3, 3e3, n), np.zeros(n)]
    ang = rng.uniform(0, 2 * np.pi, n)
    rng_m = rng.uniform(1e3, 40e3, n)
    air = np.c_[tgt[:, 0] + rng_m * np.sin(ang), tgt[:, 1] + rng_m * np.cos(ang),
                rng.uniform(100, 8000, n)]
    cfg = preset("hills")
    big = T.build_terrain(cfg, ROCHER)
    tgt[:, 2] = big.height_at(tgt[:, 0], tgt[:, 1])
    cfg.chunk_samples = 1000
    small = T.build_terrain(cfg, ROCHER)
    a = big.line_of_sight(air, tgt, 20.0)
    np.testing.assert_array_equal(a, small.line_of_sight(air, tgt, 20.0))
    assert 0.05 < a.mean() < 0.99  # both outcomes occur
    # brute force: every 20 m along the whole ray against the analytic hills (no skipping, no
    # grid), ends excluded as the terrain does; disagreements only where the ray passes within
    # the grid's ~1 m interpolation error of the clearance
    s = np.arange(0.0, 1.0, 1e-3)[None, :, None]
    d = air - tgt
    length = np.linalg.norm(d, axis=1)
    pts = tgt[:, None, :] + s * d[:, None, :]
    dist = s[..., 0] * length[:, None]
    test = (dist >= big.end_skip_m) & (dist <= length[:, None] - big.end_skip_m)
    margin = T.hills_height(cfg.hills, pts[..., 0], pts[..., 1]) - pts[..., 2] - big.clearance_m
    blocked = np.any(test & (margin > 0), axis=1)
    near = np.any(test & (np.abs(margin) < 1.0), axis=1)
    assert np.all((a == ~blocked) | near)


@needs_tile
def test_monaco_line_of_sight(monaco):
    # Monaco harbour seen from 30 km out to sea at 6 km; a valley north of the Mont Agel massif
    # (43.80 N 7.43 E, ~600 m) hidden from a low aircraft over the sea, seen from high above it
    harbour = _on_ground(monaco, *pymap3d.geodetic2enu(43.7350, 7.4230, 0, 43.7307, 7.421392, 0)[:2])
    assert monaco.line_of_sight([0.0, -30e3, 6000.0], harbour, 30.0).all()
    x, y, _ = pymap3d.geodetic2enu(43.800, 7.430, 0, 43.7307, 7.421392, 0)
    valley = _on_ground(monaco, x, y)
    assert not monaco.line_of_sight([x, y - 25e3, 1000.0], valley, 30.0).any()
    assert monaco.line_of_sight(valley + [0, -2000.0, 8000.0], valley, 30.0).all()


@needs_tile
def test_monaco_rays_agree_with_a_brute_force_enu_march(monaco):
    # the geodetic march (heights along the ellipsoid normal, knots every km) against sampling
    # height_at (pymap3d at every sample) along the same rays
    rng = np.random.default_rng(8)
    n = 150
    tgt = _on_ground(monaco, rng.uniform(-3e3, 3e3, n), rng.uniform(-1e3, 4e3, n))
    ang = rng.uniform(0, 2 * np.pi, n)
    air = np.c_[tgt[:, 0] + 20e3 * np.sin(ang), tgt[:, 1] + 20e3 * np.cos(ang),
                rng.uniform(300, 3000, n)]
    seen = monaco.line_of_sight(air, tgt, 30.0)
    assert 0.1 < seen.mean() < 0.95
    s = np.arange(0.0, 1.0, 30.0 / 20e3)[None, :, None]
    pts = tgt[:, None, :] + s * (air - tgt)[:, None, :]
    dist = s[..., 0] * np.linalg.norm(air - tgt, axis=1)[:, None]
    ground = monaco.height_at(pts[..., 0], pts[..., 1])
    margin = np.where(dist >= monaco.end_skip_m, ground - pts[..., 2] - monaco.clearance_m, -1e9)
    blocked = np.any(margin > 0, axis=1)
    near = np.any(np.abs(margin) < 2.0, axis=1)
    assert np.all((seen == ~blocked) | near)


@needs_tile
def test_rays_off_the_dem_are_not_blocked_by_unknown_ground(monaco):
    # both ends and the whole ray north of the tile (44.3 N): no data, nothing blocks
    x, y, _ = pymap3d.geodetic2enu(44.3, 7.4, 0, 43.7307, 7.421392, 0)
    assert np.isnan(monaco.height_at(x, y))
    assert monaco.line_of_sight([x, y, 10.0], [x + 5e3, y, 10.0], 30.0).all()


# ------------------------------------------------------------------ ground points of measurements
def test_intersect_finds_the_first_ground_point(hills):
    flat = T.build_terrain(T.TerrainConfig(flat_height_m=12.0), ROCHER)
    air = np.array([0.0, -30e3, 6000.0])
    np.testing.assert_allclose(flat.intersect(air, [0.0, 30e3, -5988.0]), [[0.0, 0.0, 12.0]],
                               atol=1e-6)
    assert np.isnan(flat.intersect(air, [0.0, 1.0, 0.0])).all()  # level ray never lands
    # aimed at a road hidden behind the ridge, the ray lands on the ridge's south face
    road = _on_ground(hills, [0.0], [1200.0])
    hit = hills.intersect(air, road - air)
    assert 0.0 < hit[0, 1] < 500.0
    assert hit[0, 2] == pytest.approx(hills.height_at(hit[0, 0], hit[0, 1])[()], abs=0.01)
    # aimed 0.5 m under a visible point, it lands within 0.5 / sin(grazing) of it
    front = _on_ground(hills, [300.0], [-800.0]) - [0, 0, 0.5]
    hit = hills.intersect(air, front - air)
    assert np.linalg.norm(hit - front) < 0.5 / math.sin(math.atan2(6000, 29.2e3)) + 0.01
    # pointing up, or from under the ground: no ground point
    assert np.isnan(hills.intersect([0, 0, 500.0], [0, 0, 1.0])).all()
    assert np.isnan(hills.intersect([0, 500.0, 10.0], [0, 1.0, -0.1])).all()


def test_geolocate_puts_a_report_back_on_the_ground(hills):
    rng = np.random.default_rng(9)
    tgt = _on_ground(hills, rng.uniform(-4e3, 4e3, 400), rng.uniform(-2e3, 3e3, 400))
    air = np.array([1000.0, -30e3, 6000.0])
    d = tgt - air
    rng_m = np.linalg.norm(d, axis=1)
    az = np.arctan2(d[:, 0], d[:, 1])
    got = hills.geolocate(air, rng_m, az)
    g = got - air
    np.testing.assert_allclose(np.linalg.norm(g, axis=1), rng_m, atol=1e-3)
    np.testing.assert_allclose(np.arctan2(g[:, 0], g[:, 1]), az, atol=1e-9)
    np.testing.assert_allclose(got[:, 2], hills.height_at(got[:, 0], got[:, 1]), atol=0.01)
    # a single point of the terrain at that range and azimuth for the visible targets
    seen = hills.line_of_sight(air, tgt, 10.0)
    assert np.mean(np.linalg.norm(got - tgt, axis=1)[seen] < 0.01) > 0.95
    # a range shorter than the height above ground reaches no ground
    assert np.isnan(hills.geolocate(air, 5000.0, 0.0)).all()


@needs_tile
def test_geolocate_on_the_monaco_tile(monaco):
    rng = np.random.default_rng(10)
    tgt = _on_ground(monaco, rng.uniform(-3e3, 3e3, 300), rng.uniform(-3e3, 3e3, 300))
    air = np.c_[tgt[:, 0] + 5e3, tgt[:, 1] - 30e3, np.full(300, 6000.0)]
    d = tgt - air
    got = monaco.geolocate(air, np.linalg.norm(d, axis=1), np.arctan2(d[:, 0], d[:, 1]))
    np.testing.assert_allclose(np.linalg.norm(got - air, axis=1), np.linalg.norm(d, axis=1),
                               atol=1e-3)
    np.testing.assert_allclose(got[:, 2], monaco.height_at(got[:, 0], got[:, 1]), atol=0.01)
    assert np.median(np.linalg.norm(got - tgt, axis=1)) < 0.01


@pytest.mark.parametrize("which", ["hills", "monaco"])
def test_skipping_segments_above_the_ground_does_not_change_the_answer(which, request,
                                                                       monkeypatch):
    ter = request.getfixturevalue(which)
    rng = np.random.default_rng(11)
    n = 4000
    tgt = _on_ground(ter, rng.uniform(-6e3, 6e3, n), rng.uniform(-6e3, 6e3, n))
    tgt[:, 2] += rng.uniform(-3, 20, n)
    ang = rng.uniform(0, 2 * np.pi, n)
    dist = rng.uniform(100, 40e3, n)
    air = np.c_[tgt[:, 0] + dist * np.sin(ang), tgt[:, 1] + dist * np.cos(ang),
                rng.uniform(-100, 8000, n)]
    screened = ter.line_of_sight(air, tgt, 30.0)
    assert 0.05 < screened.mean() < 0.98
    monkeypatch.setattr(ter, "_ground_bound", lambda a, b, r: np.full(np.shape(a), np.inf))
    np.testing.assert_array_equal(screened, ter.line_of_sight(air, tgt, 30.0))


def test_intersect_from_off_the_dem_lands_on_it(tmp_path):
    yy, xx = np.mgrid[0:21, 0:21]
    path = tmp_path / "g.asc"
    dem.write_ascii_grid(path, dem.EnuGrid(z=np.full((21, 21), 30.0), x0_m=0, y0_m=0, dx_m=100,
                                           dy_m=100, source="g"))
    ter = T.build_terrain(T.TerrainConfig(kind=T.TerrainKind.ascii_grid, path=str(path)), ROCHER)
    hit = ter.intersect([1000.0, -20e3, 6000.0], [0.0, 21e3, -5970.0])
    np.testing.assert_allclose(hit, [[1000.0, 1000.0, 30.0]], atol=0.01)
    # a sloping grid: the ray crosses the ceiling off the DEM and lands further on
    dem.write_ascii_grid(path, dem.EnuGrid(z=30.0 + 1.0 * xx, x0_m=0, y0_m=0, dx_m=100, dy_m=100,
                                           source="g"))
    ter = T.build_terrain(T.TerrainConfig(kind=T.TerrainKind.ascii_grid, path=str(path)), ROCHER)
    hit = ter.intersect([1000.0, -20e3, 6000.0], [0.0, 21e3, -5960.0])
    np.testing.assert_allclose(hit, [[1000.0, 1000.0, 40.0]], atol=0.01)


def test_rays_are_straight_on_the_earth_of_the_radius_given():
    """A low ray over a thin 22 m ridge halfway along 40 km: a straight line on an earth of
    radius a sits t(1 − t)d²/(2a) below the map-straight line (z linear along the ray), at the
    middle 50 − d²/(8a) m: 18.6 m on the true earth (blocked by the ridge less its 1 m
    clearance), 26.5 m on the sensor's 4/3 earth (clear, standard refraction) and 50 m with
    no curvature at all (clear)."""
    ridge = HillConfig(x_m=0.0, y_m=0.0, height_m=22.0, sigma_m=40.0, length_m=20_000.0,
                       azimuth_deg=90.0)
    ter = T.build_terrain(T.TerrainConfig(kind=T.TerrainKind.hills, hills=[ridge],
                                          grid_spacing_m=10.0), ROCHER)
    radius = frames.sphere_radius_m(ROCHER)
    aircraft = np.array([0.0, -20_000.0, 100.0])
    target = np.array([[0.0, 20_000.0, 0.0]])
    assert not ter.line_of_sight(aircraft, target, 5.0, earth_radius_m=radius).any()
    assert ter.line_of_sight(aircraft, target, 5.0, earth_radius_m=4.0 / 3.0 * radius).all()
    assert ter.line_of_sight(aircraft, target, 5.0).all()
