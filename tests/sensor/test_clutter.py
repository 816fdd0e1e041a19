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
