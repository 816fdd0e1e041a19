"""False alarms over the field of view and in clutter regions (paper §5.4, DESIGN §5.7)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from omegaconf import OmegaConf
from scipy import stats

from gmtiflow.errors import ConfigError
from gmtiflow.sensor import clutter as cl
from gmtiflow.sensor import regions as geo
from gmtiflow.sensor import scan
from gmtiflow.sensor.config import SensorConfig
from gmtiflow.sensor.effects import FalseAlarms
from gmtiflow.sensor.model import simulate
from sensor_fakes import ORIGIN, FlatTerrain, LevelPlatform, grid_fleet

CONF = Path(__file__).resolve().parents[2] / "conf" / "clutter"
LAKE = [[1500, 1500], [3500, 1200], [4200, 2500], [3000, 3500], [1600, 3000]]
N_DWELLS = 3000
ALPHA = 1e-3  # per statistical check; fixed seeds make every run identical anyway


def _box(x0, y0, x1, y1):
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], float)


def _clip_half_plane_x_below(poly, x_cut):
    """Sutherland-Hodgman clip of a polygon to x < x_cut (reference for intersection areas)."""
    out = []
    pts = [tuple(p) for p in poly]
    for k, (a, b) in enumerate(zip(pts, pts[1:] + pts[:1])):
        ina, inb = a[0] < x_cut, b[0] < x_cut
        if ina:
            out.append(a)
        if ina != inb:
            t = (x_cut - a[0]) / (b[0] - a[0])
            out.append((x_cut, a[1] + t * (b[1] - a[1])))
    return np.array(out)


def _counts(table, n_dwells, region_index=None):
    d = table["dwell_id"] if region_index is None else table["dwell_id"][table["region_index"] == region_index]
    return np.bincount(d, minlength=n_dwells)


def _assert_poisson(counts, mean):
    n = len(counts)
    m = counts.mean()
    z = stats.norm.isf(ALPHA / 2)
    assert abs(m - mean) <= z * np.sqrt(mean / n), (m, mean)
    # Index of dispersion: (n-1) s² / mean ~ chi²(n-1) for Poisson counts.
    d = (n - 1) * counts.var(ddof=1) / mean
    assert stats.chi2.ppf(ALPHA / 2, n - 1) <= d <= stats.chi2.isf(ALPHA / 2, n - 1), d / (n - 1)


def _load(name):
    merged = OmegaConf.merge(OmegaConf.structured(cl.ClutterConfig), OmegaConf.load(CONF / f"{name}.yaml"))
    return OmegaConf.to_object(merged)


# ---------------------------------------------------------------- nothing to do costs nothing

def test_none_preset_runs_no_clutter_code(monkeypatch):
    cfg = _load("none")
    assert not cl.is_active(cfg)

    def boom(*a, **k):
        raise AssertionError("clutter code ran although the config has no false alarms")

    monkeypatch.setattr(cl, "_draw_source", boom)
    monkeypatch.setattr(cl.rng, "counter_key", boom)
    monkeypatch.setattr(cl.geo, "stack_polygons", boom)
    out = cl.false_alarms(cfg, 1, np.arange(5), fov_polygons=None)
    assert all(len(col) == 0 for col in out.values())
    assert set(out) == {"dwell_id", "x_m", "y_m", "clutter_range_rate_mps", "snr", "snr_db", "region_index"}
    # Regions with zero density are inactive too.
    idle = cl.ClutterConfig(regions=[cl.ClutterRegionConfig(name="lake", vertices_m=LAKE)])
    assert not cl.is_active(idle)
    assert not cl.is_active(None)


# ---------------------------------------------------------------- counts and positions

def test_circle_counts_are_poisson_and_positions_uniform_in_area():
    centre, radius, density = (2000.0, -1000.0), 400.0, 6.0
    region = cl.ClutterRegionConfig(name="c", shape="circle", centre_m=list(centre), radius_m=radius,
                                    density_per_km2=density)
    cfg = cl.ClutterConfig(regions=[region])
    fov = _box(-10_000, -10_000, 10_000, 10_000)
    t = cl.false_alarms(cfg, 11, np.arange(N_DWELLS), [fov] * N_DWELLS)
    _assert_poisson(_counts(t, N_DWELLS), density * np.pi * radius ** 2 / 1e6)
    r2 = ((t["x_m"] - centre[0]) ** 2 + (t["y_m"] - centre[1]) ** 2) / radius ** 2
    assert r2.max() < 1.0
    assert stats.kstest(r2, "uniform").pvalue > ALPHA
    bearing = np.mod(np.arctan2(t["x_m"] - centre[0], t["y_m"] - centre[1]), 2 * np.pi) / (2 * np.pi)
    assert stats.kstest(bearing, "uniform").pvalue > ALPHA


def test_polygon_cut_by_the_fov_is_poisson_with_the_intersection_area():
    density, x_cut = 2.0, 2600.0
    cfg = cl.ClutterConfig(regions=[cl.ClutterRegionConfig(name="lake", vertices_m=LAKE, density_per_km2=density)])
    fov = _box(-5000, -5000, x_cut, 9000)
    t = cl.false_alarms(cfg, 3, np.arange(N_DWELLS), [fov] * N_DWELLS)
    area = geo.polygon_area_m2(_clip_half_plane_x_below(np.array(LAKE, float), x_cut))
    assert 0 < area < geo.polygon_area_m2(LAKE)
    _assert_poisson(_counts(t, N_DWELLS), density * area / 1e6)
    assert np.all(t["x_m"] < x_cut)
    assert np.all(geo.points_in_polygon(t["x_m"], t["y_m"], LAKE))


def test_rectangle_region_cut_by_the_fov_gives_uniform_coordinates():
    rect = _box(0, 0, 1000, 500).tolist()
    cfg = cl.ClutterConfig(regions=[cl.ClutterRegionConfig(name="r", vertices_m=rect, density_per_km2=20.0)])
    fov = _box(-100, -100, 600, 900)
    t = cl.false_alarms(cfg, 8, np.arange(N_DWELLS), [fov] * N_DWELLS)
    _assert_poisson(_counts(t, N_DWELLS), 20.0 * 0.6 * 0.5)
    assert stats.kstest(t["x_m"] / 600.0, "uniform").pvalue > ALPHA
    assert stats.kstest(t["y_m"] / 500.0, "uniform").pvalue > ALPHA


def test_ring_positions_stay_in_the_ring_and_are_uniform_in_area():
    region = cl.ClutterRegionConfig(name="ring", shape="ring", centre_m=[0.0, 0.0], inner_radius_m=300.0,
                                    outer_radius_m=500.0, density_per_km2=10.0)
    t = cl.false_alarms(cl.ClutterConfig(regions=[region]), 4, np.arange(N_DWELLS),
                        [_box(-600, -600, 600, 600)] * N_DWELLS)
    r2 = t["x_m"] ** 2 + t["y_m"] ** 2
    assert np.all((r2 >= 300.0 ** 2) & (r2 < 500.0 ** 2))
    assert stats.kstest((r2 - 300.0 ** 2) / (500.0 ** 2 - 300.0 ** 2), "uniform").pvalue > ALPHA
    _assert_poisson(_counts(t, N_DWELLS), 10.0 * np.pi * (0.5 ** 2 - 0.3 ** 2))


def test_fov_density_fills_each_footprint_and_nothing_outside():
    density = 0.3
    n = 2000
    centres = np.column_stack([np.linspace(0, 5000, n), np.zeros(n)])
    footprints = np.stack([cl.annular_sector_polygon(c, 10_000, 20_000, 0.1, 0.4) for c in centres])
    # An extra predicate the sensor might apply (say, a terrain mask): keep y < 15 km.
    in_fov = lambda d, x, y: y < 15_000.0  # noqa: E731
    cfg = cl.ClutterConfig(fov_density_per_km2=density)
    t = cl.false_alarms(cfg, 21, np.arange(n) + 100, footprints, in_fov=in_fov)
    assert np.all(geo.points_in_polygons(t["x_m"], t["y_m"], footprints, t["dwell_id"] - 100))
    assert np.all(t["y_m"] < 15_000.0) and np.all(t["region_index"] == -1)
    cut = np.array([[-1e5, -1e5], [1e5, -1e5], [1e5, 15_000.0], [-1e5, 15_000.0]])
    # Area of footprint ∩ {y < 15 km}: the footprint is the same shape shifted along x.
    fp0 = footprints[0]
    xs = np.random.default_rng(0).uniform(fp0[:, 0].min(), fp0[:, 0].max(), 400_000)
    ys = np.random.default_rng(1).uniform(fp0[:, 1].min(), fp0[:, 1].max(), 400_000)
    frac = np.mean(geo.points_in_polygon(xs, ys, fp0) & geo.points_in_polygon(xs, ys, cut))
    area = frac * (np.ptp(fp0[:, 0]) * np.ptp(fp0[:, 1]))
    _assert_poisson(np.bincount(t["dwell_id"] - 100, minlength=n), density * area / 1e6)


HEXAGON = np.array([[0, 0], [3000, -500], [5000, 1000], [4500, 3500], [1500, 4000], [-800, 2000]], float)
L_SHAPE = np.array([[0, 0], [4000, 0], [4000, 1000], [1000, 1000], [1000, 4000], [0, 4000]], float)


def test_footprint_fans_are_exact_for_star_shaped_polygons_only():
    sector = cl.annular_sector_polygon([0, 0], 15_000, 30_000, -0.1, 0.1)
    polys = geo.stack_polygons([sector, HEXAGON, HEXAGON[::-1], L_SHAPE, _box(0, 0, 5, 7)])
    fan = cl.fan_triangles(polys)
    assert fan["star"].tolist() == [True, True, True, False, True]
    for i in (0, 1, 2, 4):
        assert fan["area"][i] == pytest.approx(geo.polygon_area_m2(polys[i]), rel=1e-12)
    assert np.all(np.diff(fan["cum"]) >= 0)


@pytest.mark.parametrize("shape", ["hexagon", "L"])
def test_fov_density_in_polygon_footprints_is_uniform_over_each(shape):
    """FoV-wide draws in polygon footprints: Poisson with mean density x polygon area, every
    point inside, positions with the law of uniform points in the polygon (two-sample KS
    against rejection sampling).  The hexagon is drawn through its fan of triangles, the L
    (not star-shaped from its centroid) in its box and thinned."""
    poly = HEXAGON if shape == "hexagon" else L_SHAPE
    n = N_DWELLS
    shift = np.column_stack([np.linspace(0, 9000, n), np.linspace(0, -3000, n)])
    footprints = poly[None, :, :] + shift[:, None, :]
    density = 1.0
    t = cl.false_alarms(cl.ClutterConfig(fov_density_per_km2=density), 12, np.arange(n), footprints)
    area = geo.polygon_area_m2(poly)
    _assert_poisson(_counts(t, n), density * area / 1e6)
    assert np.all(geo.points_in_polygons(t["x_m"], t["y_m"], footprints, t["dwell_id"]))
    x = t["x_m"] - shift[t["dwell_id"], 0]
    y = t["y_m"] - shift[t["dwell_id"], 1]
    g = np.random.default_rng(3)
    rx = g.uniform(poly[:, 0].min(), poly[:, 0].max(), 400_000)
    ry = g.uniform(poly[:, 1].min(), poly[:, 1].max(), 400_000)
    inside = geo.points_in_polygon(rx, ry, poly)
    for a, b in ((x, rx[inside]), (y, ry[inside]), (x + y, (rx + ry)[inside]),
                 (x - y, (rx - ry)[inside])):
        assert stats.ks_2samp(a, b).pvalue > ALPHA


def test_region_outside_every_footprint_gives_nothing():
    cfg = cl.ClutterConfig(regions=[cl.ClutterRegionConfig(name="lake", vertices_m=LAKE, density_per_km2=50.0)])
    t = cl.false_alarms(cfg, 1, np.arange(100), [_box(10_000, 10_000, 20_000, 20_000)] * 100)
    assert len(t["x_m"]) == 0


def test_in_fov_alone_thins_regions_but_cannot_bound_the_fov_density():
    cfg = cl.ClutterConfig(regions=[cl.ClutterRegionConfig(name="lake", vertices_m=LAKE, density_per_km2=5.0)])
    t = cl.false_alarms(cfg, 2, np.arange(200), in_fov=lambda d, x, y: x > 3000.0)
    assert len(t["x_m"]) > 0 and np.all(t["x_m"] > 3000.0)
    with pytest.raises(ValueError, match="fov_polygons"):
        cl.false_alarms(cl.ClutterConfig(fov_density_per_km2=1.0), 2, np.arange(3), in_fov=lambda d, x, y: x > 0)
    with pytest.raises(ValueError, match="field of view"):
        cl.false_alarms(cfg, 2, np.arange(3))


# ---------------------------------------------------------------- streams

def test_adding_a_region_leaves_the_other_regions_bit_identical():
    lake = cl.ClutterRegionConfig(name="lake", vertices_m=LAKE, density_per_km2=3.0,
                                  range_rate=cl.RangeRateConfig(sigma_mps=1.5))
    mill = cl.ClutterRegionConfig(name="mill", shape="circle", centre_m=[2500.0, 2500.0], radius_m=300.0,
                                  density_per_km2=40.0, range_rate=cl.RangeRateConfig(kind="windfarm", half_width_mps=40.0))
    fov = [_box(0, 0, 5000, 4000)] * 300
    a = cl.false_alarms(cl.ClutterConfig(regions=[lake]), 9, np.arange(300), fov)
    b = cl.false_alarms(cl.ClutterConfig(fov_density_per_km2=0.5, regions=[mill, lake]), 9, np.arange(300), fov)
    sel = b["region_index"] == 1
    assert sel.sum() == len(a["x_m"]) > 100
    for col in ("dwell_id", "x_m", "y_m", "clutter_range_rate_mps", "snr"):
        assert np.array_equal(a[col], b[col][sel]), col
    c = cl.false_alarms(cl.ClutterConfig(regions=[lake]), 10, np.arange(300), fov)
    assert not np.array_equal(a["x_m"][:10], c["x_m"][:10])


def test_same_seed_same_false_alarms():
    cfg = _load("lake")
    fov = [_box(0, 0, 5000, 4000)] * 50
    a = cl.false_alarms(cfg, 5, np.arange(50), fov)
    b = cl.false_alarms(cfg, 5, np.arange(50), fov)
    assert all(np.array_equal(a[k], b[k]) for k in a)


# ---------------------------------------------------------------- marks

def test_range_rate_and_snr_distributions():
    fov = [_box(-1000, -1000, 1000, 1000)] * 500

    def draw(rr, snr=None):
        region = cl.ClutterRegionConfig(name="x", shape="circle", centre_m=[0.0, 0.0], radius_m=500.0,
                                        density_per_km2=100.0, range_rate=rr, snr=snr)
        return cl.false_alarms(cl.ClutterConfig(regions=[region]), 13, np.arange(500), fov)

    g = draw(cl.RangeRateConfig(kind="gaussian", mean_mps=1.0, sigma_mps=1.5))
    assert stats.kstest((g["clutter_range_rate_mps"] - 1.0) / 1.5, "norm").pvalue > ALPHA
    u = draw(cl.RangeRateConfig(kind="uniform", mean_mps=-2.0, half_width_mps=40.0))
    assert stats.kstest((u["clutter_range_rate_mps"] + 42.0) / 80.0, "uniform").pvalue > ALPHA
    w = draw(cl.RangeRateConfig(kind="windfarm", half_width_mps=40.0), cl.SnrConfig(kind="uniform_db", low_db=13, high_db=30))
    assert np.all(np.abs(w["clutter_range_rate_mps"]) <= 40.0) and np.abs(w["clutter_range_rate_mps"]).max() > 35.0
    assert np.all((w["snr_db"] >= 13.0) & (w["snr_db"] <= 30.0))
    # Default SNR: threshold exceedance of square-law noise z = eta + Exp(1), eta = ln(1/Pfa),
    # reported z - 1 like a target's (sensor.pfa's threshold, 1e-6 by default here).
    eta = np.log(1e6)
    assert np.all(g["snr"] > eta - 1.0)
    assert stats.kstest(g["snr"] - (eta - 1.0), "expon").pvalue > ALPHA
    # a looser detector threshold moves the clutter's reported SNR with it
    region = cl.ClutterRegionConfig(name="x", shape="circle", centre_m=[0.0, 0.0], radius_m=500.0,
                                    density_per_km2=100.0)
    h = cl.false_alarms(cl.ClutterConfig(regions=[region]), 13, np.arange(500), fov, pfa=1e-15)
    assert stats.kstest(h["snr"] - (np.log(1e15) - 1.0), "expon").pvalue > ALPHA


# ---------------------------------------------------------------- validation

def _problem_keys(cfg):
    with pytest.raises(ConfigError) as err:
        cl.check(cfg)
    return str(err.value)


@pytest.mark.parametrize("region, key", [
    (dict(name="bow", vertices_m=[[0, 0], [1, 1], [1, 0], [0, 1]], density_per_km2=1.0), "clutter.regions[0].vertices_m"),
    (dict(name="two", vertices_m=[[0, 0], [1, 1]], density_per_km2=1.0), "clutter.regions[0].vertices_m"),
    (dict(name="line", vertices_m=[[0, 0], [1, 1], [2, 2]], density_per_km2=1.0), "clutter.regions[0].vertices_m"),
    (dict(name="neg", vertices_m=LAKE, density_per_km2=-1.0), "clutter.regions[0].density_per_km2"),
    (dict(name="ring", shape="ring", centre_m=[0, 0], inner_radius_m=50.0, outer_radius_m=50.0), "clutter.regions[0].inner_radius_m"),
    (dict(name="c", shape="circle", centre_m=[0, 0], radius_m=0.0), "clutter.regions[0].radius_m"),
    (dict(name="c", shape="circle", radius_m=5.0), "clutter.regions[0].centre_m"),
    (dict(name="", vertices_m=LAKE), "clutter.regions[0].name"),
    (dict(name="fov", vertices_m=LAKE), "clutter.regions[0].name"),
    (dict(name="h", shape="hexagon"), "clutter.regions[0].shape"),
    (dict(name="rr", vertices_m=LAKE, range_rate=cl.RangeRateConfig(kind="gaussian", sigma_mps=-1.0)),
     "clutter.regions[0].range_rate.sigma_mps"),
])
def test_invalid_regions_name_their_key(region, key):
    assert key in _problem_keys(cl.ClutterConfig(regions=[cl.ClutterRegionConfig(**region)]))


def test_invalid_top_level_and_duplicate_names():
    assert "clutter.fov_density_per_km2" in _problem_keys(cl.ClutterConfig(fov_density_per_km2=-0.1))
    dup = [cl.ClutterRegionConfig(name="a", vertices_m=LAKE), cl.ClutterRegionConfig(name="a", vertices_m=LAKE)]
    assert "clutter.regions[1].name" in _problem_keys(cl.ClutterConfig(regions=dup))
    # clutter.snr.pfa was removed (the threshold is sensor.pfa's): setting it is an error saying so
    msg = _problem_keys(cl.ClutterConfig(snr=cl.SnrConfig(pfa=1e-6)))
    assert "clutter.snr.pfa" in msg and "sensor.pfa" in msg


@pytest.mark.parametrize("name", ["none", "lake", "windfarm", "urban"])
def test_presets_load_into_the_schema_and_validate(name):
    cfg = _load(name)
    cl.check(cfg)
    assert cl.is_active(cfg) == (name != "none")


def test_lake_preset_gives_a_handful_per_dwell_over_the_lake():
    cfg = _load("lake")
    assert cfg.regions[0].area_m2() == pytest.approx(4.38e6)
    t = cl.false_alarms(cfg, 1, np.arange(400), [_box(0, 0, 6000, 5000)] * 400)
    assert 2.0 < len(t["x_m"]) / 400 < 10.0


# ---------------------------------------------------------------- geometry helpers

def test_shoelace_area_and_self_intersection():
    assert geo.polygon_area_m2(_box(0, 0, 3, 2)) == 6.0
    assert geo.polygon_area_m2(_box(0, 0, 3, 2)[::-1]) == 6.0
    assert geo.polygon_area_m2(LAKE) == pytest.approx(4.38e6)
    assert not geo.polygon_self_intersects(LAKE)
    assert geo.polygon_self_intersects([[0, 0], [2, 0], [2, 2], [1, -1]])
    assert geo.polygon_self_intersects([[0, 0], [2, 0], [1, 0], [1, 1]])  # edge folds back on itself
    sector = cl.annular_sector_polygon([0, 0], 1000.0, 2000.0, 0.0, np.pi / 2, n_arc=200)
    assert geo.polygon_area_m2(sector) == pytest.approx(np.pi / 4 * (2000.0 ** 2 - 1000.0 ** 2), rel=1e-4)


def test_fov_density_drawn_directly_in_annular_sectors():
    """fov_sectors: Poisson count with mean density x sector area, points uniform over the
    annulus (g^2 uniform, azimuth uniform), every point inside its own dwell's sector."""
    n = 400
    x0 = np.linspace(0.0, 4000.0, n)
    sectors = np.column_stack([x0, np.full(n, -30_000.0), np.full(n, 20_000.0),
                               np.full(n, 30_000.0), np.full(n, -0.05), np.full(n, 0.1)])
    cfg = cl.ClutterConfig(fov_density_per_km2=0.05)
    t = cl.false_alarms(cfg, 4, np.arange(n), fov_sectors=sectors,
                        in_fov=lambda d, x, y: np.ones(len(x), bool))
    area_km2 = 0.5 * 0.1 * (30_000.0 ** 2 - 20_000.0 ** 2) / 1e6     # 25 km^2
    mean = 0.05 * area_km2 * n
    assert abs(len(t["x_m"]) - mean) < 4.5 * np.sqrt(mean)
    dx = t["x_m"] - x0[t["dwell_id"]]
    dy = t["y_m"] + 30_000.0
    g = np.hypot(dx, dy)
    a = np.arctan2(dx, dy)
    assert np.all((g >= 20_000.0 - 1e-6) & (g <= 30_000.0 + 1e-6))
    assert np.all((a >= -0.05 - 1e-12) & (a <= 0.05 + 1e-12))
    assert stats.kstest((g ** 2 - 20_000.0 ** 2) / (30_000.0 ** 2 - 20_000.0 ** 2), "uniform").pvalue > ALPHA
    assert stats.kstest((a + 0.05) / 0.1, "uniform").pvalue > ALPHA
    # the boxes bound the sectors
    bx0, by0, bx1, by1 = cl.sector_boxes(sectors)
    assert np.all((t["x_m"] >= bx0[t["dwell_id"]]) & (t["x_m"] <= bx1[t["dwell_id"]]))
    assert np.all((t["y_m"] >= by0[t["dwell_id"]]) & (t["y_m"] <= by1[t["dwell_id"]]))


# ---------------------------------------------------------------- regions drawn in the sectors

# Regions around the default fake scene (platform flying west along y = -30 km at 6 km, looking
# north at the origin): a concave polygon cut by the footprints, one that holds the platform, a
# C-shaped one wrapped round the platform (its azimuths span more than pi), a disc and a ring.
CONCAVE = [[-9000, -6000], [7000, -8000], [9000, 2000], [1000, -2000], [-3000, 6000], [-8000, 1000]]
AROUND = [[-20_000, -40_000], [20_000, -40_000], [20_000, -4_000], [-20_000, -4_000]]
C_SHAPE = [[-15_000, -45_000], [15_000, -45_000], [15_000, -5_000], [-2_000, -5_000],
           [-2_000, -8_000], [12_000, -8_000], [12_000, -42_000], [-12_000, -42_000],
           [-12_000, -18_000], [-15_000, -18_000]]
STAGE_REGIONS = [
    cl.ClutterRegionConfig(name="concave", vertices_m=CONCAVE),
    cl.ClutterRegionConfig(name="around", vertices_m=AROUND),
    cl.ClutterRegionConfig(name="c-shape", vertices_m=C_SHAPE),
    cl.ClutterRegionConfig(name="disc", shape="circle", centre_m=[1500.0, -2500.0], radius_m=3000.0),
    cl.ClutterRegionConfig(name="ring", shape="ring", centre_m=[-2000.0, 0.0], inner_radius_m=1500.0,
                           outer_radius_m=4000.0),
]


def _points_outside_windows(region, sectors, m, g):
    """Count of points of region ∩ sector (m quasi-uniform draws per sector) that fall outside
    the region's window in the sector, and the count of points in region ∩ sector."""
    cx, cy, g0, g1, a0, span = sectors.T
    w0, w1, b0, bspan = cl.region_windows(region, sectors)
    assert np.all((w0 >= g0) & (w1 <= g1) & (b0 >= a0 - 1e-12) & (b0 + bspan <= a0 + span + 1e-12))
    n = len(sectors)
    u1, u2 = g.uniform(size=(n, m)), g.uniform(size=(n, m))
    r = np.sqrt(g0[:, None] ** 2 + u1 * (g1 ** 2 - g0 ** 2)[:, None])
    a = a0[:, None] + u2 * span[:, None]
    x, y = cx[:, None] + r * np.sin(a), cy[:, None] + r * np.cos(a)
    inside = region.contains(x.ravel(), y.ravel()).reshape(n, m)
    in_window = ((r >= w0[:, None]) & (r <= w1[:, None]) & (a >= b0[:, None])
                 & (a <= (b0 + bspan)[:, None]))
    return int(np.sum(inside & ~in_window)), int(inside.sum())


@pytest.mark.parametrize("region", STAGE_REGIONS, ids=lambda r: r.name)
def test_region_windows_hold_every_point_of_region_and_sector(region):
    """The window a region's draws use in a dwell's sector contains all of region ∩ sector
    (checked on a dense uniform cover of random sectors), and is no larger than the sector."""
    g = np.random.default_rng(5)
    n = 600
    cx, cy = g.uniform(-25_000, 25_000, n), g.uniform(-45_000, 10_000, n)
    g0 = g.uniform(0.0, 20_000, n)
    g1 = g0 + g.uniform(500.0, 30_000, n)
    a0 = g.uniform(-np.pi, np.pi, n)
    span = g.uniform(0.001, 1.2, n)
    sectors = np.column_stack([cx, cy, g0, g1, a0, span])
    missed, hits = _points_outside_windows(region, sectors, 4000, g)
    assert hits > 10_000 and missed == 0
    # and the windows cut the sectors (which reach far beyond every region)
    w0, w1, _, bspan = cl.region_windows(region, sectors)
    area = lambda s0, s1, sp: 0.5 * sp * (s1 ** 2 - s0 ** 2)  # noqa: E731
    assert area(w0, w1, bspan).sum() < 0.9 * area(g0, g1, span).sum()
    assert np.sum(bspan == 0) > 10


@pytest.mark.parametrize("reverse", [False, True], ids=["ccw", "cw"])
def test_region_windows_with_an_edge_grazing_the_sector_centre(reverse):
    """An edge passing metres from the sector's centre subtends almost pi, from behind the
    sector to inside it: its azimuth interval must be taken the right way round (either
    winding of the polygon).  A strip 5 m wide, so that both its long edges do (any direction
    into a region crosses its boundary twice: one edge taken wrongly would go unnoticed)."""
    strip = [[-10_000, 0], [10_000, 0], [10_000, 5], [-10_000, 5]]
    region = cl.ClutterRegionConfig(name="strip", vertices_m=strip[::-1] if reverse else strip)
    g = np.random.default_rng(6)
    n = 400
    cx = g.uniform(-3000, 3000, n)
    cy = -g.uniform(1.0, 20.0, n)                      # just below the strip's lower edge
    psi = np.where(g.uniform(size=n) < 0.5, 0.5, -0.5) * np.pi + g.normal(0, 0.05, n)
    span = g.uniform(0.02, 0.4, n)
    sectors = np.column_stack([cx, cy, np.zeros(n), np.full(n, 3000.0), psi - span / 2, span])
    missed, hits = _points_outside_windows(region, sectors, 4000, g)
    assert hits > 10_000 and missed == 0


def _stage_false_alarms(ccfg, duration_s=40.0):
    cfg = SensorConfig(noise_false_alarms=False)
    out = simulate(cfg, grid_fleet(0), LevelPlatform(), FlatTerrain(), 3, duration_s, ORIGIN,
                   effects=[FalseAlarms(cfg, ccfg, 3)])
    return out["detections"], out["dwells"]


@pytest.mark.parametrize("region", STAGE_REGIONS, ids=lambda r: r.name)
def test_region_in_the_stage_matches_the_fov_density_on_the_region(region):
    """In the sensor stage a region at density d gives what the FoV-wide density d gives on the
    region: the FoV-wide points inside it are Poisson with mean d x area(region ∩ cells), so the
    two counts are independent Poisson with the same mean (given their sum, one is binomial
    with p = 1/2), and the positions have the same law (two-sample KS on x and y).  Nothing
    falls outside the region or outside its dwell's cell (the world azimuth of a level
    platform's cell, the slant-range window)."""
    density = 20.0
    fov, dw = _stage_false_alarms(cl.ClutterConfig(fov_density_per_km2=density))
    reg_cfg = cl.ClutterRegionConfig(**{**vars(region), "density_per_km2": density})
    det, dw2 = _stage_false_alarms(cl.ClutterConfig(regions=[reg_cfg]))
    assert np.array_equal(dw["dwell_id"], dw2["dwell_id"])
    ref = region.contains(fov["x_m"], fov["y_m"])
    a, b = len(det["x_m"]), int(ref.sum())
    assert b > 500, b
    assert stats.binomtest(a, a + b, 0.5).pvalue > ALPHA, (a, b)
    assert np.all(region.contains(det["x_m"], det["y_m"]))
    for c in ("x_m", "y_m"):
        assert stats.ks_2samp(det[c], fov[c][ref]).pvalue > ALPHA, c
    cfg_range = (20_000.0, 36_000.0)
    assert np.all((det["range_m"] >= cfg_range[0]) & (det["range_m"] <= cfg_range[1]))
    # inside the dwell's cell: the scan angle's sine within the beam's cell (level flight
    # heading west, so the antenna's scan axis is horizontal, as in test_noise.py)
    k = det["dwell_id"] - dw["dwell_id"][0]
    half = np.sin(np.radians(10.0)) / scan.n_dwells(SensorConfig())
    u_b = np.sin(dw["beam_scan_rad"][k])
    to_world = dw["beam_az_rad"][k] - dw["beam_scan_rad"][k]
    los = np.array([det["x_m"] - dw["platform_x_m"][k], det["y_m"] - dw["platform_y_m"][k]])
    sin_scan = (los[0] * np.cos(to_world) - los[1] * np.sin(to_world)) / np.hypot(*los)
    assert np.all(np.abs(sin_scan - u_b) <= half + 1e-9)


def test_stage_region_draws_are_the_same_whatever_the_chunking():
    """A dwell's draws depend on its own sector only: chunks of one revisit or of all give the
    same false alarms, bit for bit."""
    cfg = SensorConfig(noise_false_alarms=False)
    ccfg = cl.ClutterConfig(fov_density_per_km2=0.5, regions=[
        cl.ClutterRegionConfig(**{**vars(r), "density_per_km2": 3.0}) for r in STAGE_REGIONS[:1]])
    outs = [simulate(cfg, grid_fleet(0), LevelPlatform(), FlatTerrain(), 3, 30.0, ORIGIN,
                     effects=[FalseAlarms(cfg, ccfg, 3)], chunk_pairs=n)["detections"]
            for n in (1, 10 ** 9)]
    assert len(outs[0]["x_m"]) > 100
    for c in ("dwell_id", "x_m", "y_m", "range_rate_mps", "snr_db"):
        assert np.array_equal(outs[0][c], outs[1][c]), c


def test_drawing_false_alarms_does_not_import_scipy_stats():
    """scipy.stats costs ~1 s of import (issue 18: it was most of what clutter cost a run): the
    Poisson counts come from scipy.special with scipy.stats' values.  Checked in a fresh
    interpreter, so the test does not depend on what else this process imported."""
    import subprocess
    import sys
    probe = ("import sys, numpy as np\n"
             "from gmtiflow.sensor import clutter as cl\n"
             "fp = [cl.annular_sector_polygon([0, 0], 1e4, 2e4, 0.0, 0.2)] * 5\n"
             "t = cl.false_alarms(cl.ClutterConfig(fov_density_per_km2=2.0), 1, np.arange(5), fp)\n"
             "assert len(t['x_m']) > 0\n"
             "print('scipy.stats' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "False"


def test_poisson_counts_are_scipy_stats_quantiles_bit_for_bit():
    g = np.random.default_rng(2)
    u = g.uniform(size=200_000)
    mean = 10 ** g.uniform(-4, 6, 200_000)
    from gmtiflow.sensor.noise import poisson_ppf
    assert np.array_equal(poisson_ppf(u, mean), stats.poisson.ppf(u, mean))


# ---------------------------------------------------------------- banked platform: tight sectors

class _TiltedPlatform(LevelPlatform):
    """LevelPlatform with a pitch too (nose up +, as a climb)."""

    def __init__(self, bank_deg, pitch_deg):
        super().__init__(bank_deg=bank_deg)
        self.pitch_deg = pitch_deg

    def state_at(self, time_s):
        s = super().state_at(time_s)
        s["pitch_rad"] = np.full(len(s["x_m"]), np.radians(self.pitch_deg))
        return s


def _banked_stage(bank_deg, seed, generous=False, pitch_deg=0.0):
    cfg = SensorConfig(noise_false_alarms=False)
    sectors = []

    class Spy(FalseAlarms):
        def footprint_sectors(self, ctx):
            s = super().footprint_sectors(ctx)
            sectors.append(s)
            return s

        def _tilted_cell_azimuths(self, ctx, rows, lo, hi, to_world, margin):
            a0, span = super()._tilted_cell_azimuths(ctx, rows, lo, hi, to_world, margin)
            return a0, (np.full_like(span, np.nan) if generous else span)

    ccfg = cl.ClutterConfig(fov_density_per_km2=20.0)
    out = simulate(cfg, grid_fleet(0), _TiltedPlatform(bank_deg, pitch_deg), FlatTerrain(), seed,
                   40.0, ORIGIN, effects=[Spy(cfg, ccfg, seed)])
    return out["detections"], out["dwells"], np.concatenate(sectors)


@pytest.mark.parametrize("bank_deg, pitch_deg", [(-15.0, 0.0), (5.0, 0.0), (-4.0, 6.0)])
def test_banked_platform_sectors_hold_the_cells_and_keep_the_law(bank_deg, pitch_deg):
    """With the antenna banked a cell's edges are not world azimuths: its sector comes from
    geolocated edge points instead of a pad of the bank angle.  The sector must still hold the
    whole cell: no false alarm within 0.5 mrad of its azimuth edges (a cut cell would put
    them right there), and the counts and positions have the law of the generous sectors'
    (independent seeds; binomial test on the totals, two-sample KS on x and y), while the
    sectors are far narrower."""
    det, dw, sec = _banked_stage(bank_deg, 3, pitch_deg=pitch_deg)
    ref, dw_ref, sec_ref = _banked_stage(bank_deg, 4, generous=True, pitch_deg=pitch_deg)
    assert np.array_equal(dw["dwell_id"], dw_ref["dwell_id"])
    assert sec[:, 5].sum() < 0.5 * sec_ref[:, 5].sum()
    k = det["dwell_id"] - dw["dwell_id"][0]
    s = sec[k]
    az = np.mod(np.arctan2(det["x_m"] - s[:, 0], det["y_m"] - s[:, 1]) - s[:, 4], 2 * np.pi)
    assert np.all((az >= 5e-4) & (az <= s[:, 5] - 5e-4))
    a, b = len(det["x_m"]), len(ref["x_m"])
    assert min(a, b) > 5000
    assert stats.binomtest(a, a + b, 0.5).pvalue > ALPHA, (a, b)
    for c in ("x_m", "y_m"):
        assert stats.ks_2samp(det[c], ref[c]).pvalue > ALPHA, c
