"""Noise false alarms of the detector (gmtiflow.sensor.noise) against their formulas.

Counts against the Poisson mean P_FA x range cells x Doppler cells (normal bound at 4.5 sigma
of the total count), positions/range rates/SNRs against their uniform and exponential laws (KS
at alpha = 1e-3), fixed seeds.
"""
import math
from dataclasses import replace

import numpy as np
import pytest
from scipy import stats

from gmtiflow.errors import ConfigError
from gmtiflow.sensor import clutter, noise, scan
from gmtiflow.sensor.config import C_MPS, SensorConfig
from gmtiflow.sensor.effects import FalseAlarms, Merging, NoiseFalseAlarms, build_effects
from gmtiflow.sensor.model import simulate
from gmtiflow.sensor.outcome import Outcome
from sensor_fakes import (ORIGIN, RADIUS_M, FlatTerrain, LevelPlatform, WallTerrain, grid_fleet,
                          still)

ALPHA = 1e-3


def _run(cfg, fleet, *, duration_s, platform=None, terrain=None, effects=None, seed=3, **kw):
    if effects is None:
        effects = [NoiseFalseAlarms(cfg, seed)]
    return simulate(cfg, fleet, platform or LevelPlatform(), terrain or FlatTerrain(), seed,
                    duration_s, ORIGIN, effects=effects, **kw)


def _count_bound(mean_total):
    return 4.5 * math.sqrt(mean_total)


def test_default_cell_count_and_expected_false_alarms_per_dwell():
    cfg = SensorConfig()
    n_r, n_d, n_a = cfg.noise_cells
    dr = C_MPS / (2 * cfg.bandwidth_hz)
    assert n_r == pytest.approx(16_000.0 / dr)                  # 5 337 range cells
    assert n_d == pytest.approx(cfg.cpi_s / cfg.pri_s)          # 128 Doppler filters
    assert n_a == 1.0
    assert cfg.expected_false_alarms_per_dwell == pytest.approx(1e-6 * 16_000 / dr * 128)
    assert 0.68 < cfg.expected_false_alarms_per_dwell < 0.69    # docs/effects.md quotes 0.683
    # the window is cut at the unambiguous range c PRI / 2 (37.5 km here)
    far = replace(cfg, range_max_m=50_000.0)
    assert far.noise_cells[0] == pytest.approx((C_MPS * cfg.pri_s / 2 - 20_000.0) / dr)
    # without a PRI: one Doppler filter per integrated pulse
    no_prf = replace(cfg, pri_s=None, integration_gain_db=10 * math.log10(64))
    assert no_prf.noise_cells[1] == pytest.approx(64.0)


@pytest.mark.parametrize("pfa", [1e-5, 1e-4])
def test_count_per_dwell_is_poisson_with_the_formula_mean(pfa):
    cfg = SensorConfig(pfa=pfa)
    out = _run(cfg, grid_fleet(0), duration_s=60.0)
    n_dwells = len(out["dwells"]["dwell_id"])
    det = out["detections"]
    assert np.all(det["truth_id"] == -1)
    mean = cfg.expected_false_alarms_per_dwell
    total = len(det["det_id"])
    assert abs(total - mean * n_dwells) < _count_bound(mean * n_dwells), (total, mean * n_dwells)
    counts = np.bincount(det["dwell_id"] - out["dwells"]["dwell_id"][0], minlength=n_dwells)
    # index of dispersion of a Poisson count: (n - 1) s^2 / mean ~ chi2(n - 1)
    q = (n_dwells - 1) * counts.var(ddof=1) / mean
    assert stats.chi2.ppf(ALPHA / 2, n_dwells - 1) < q < stats.chi2.ppf(1 - ALPHA / 2, n_dwells - 1)


def test_positions_range_rates_and_snr_follow_their_laws():
    cfg = SensorConfig(pfa=1e-4)
    out = _run(cfg, grid_fleet(0), duration_s=30.0)
    det, dw = out["detections"], out["dwells"]
    k = det["dwell_id"] - dw["dwell_id"][0]
    # slant range uniform over the window
    r = (det["range_m"] - cfg.range_min_m) / (cfg.range_max_m - cfg.range_min_m)
    assert stats.kstest(r, "uniform").pvalue > ALPHA
    # antenna-frame scan angle uniform in sine space over the dwell's beam cell
    half = 0.5 * (2 * math.sin(math.radians(10.0))) / scan.n_dwells(cfg)
    u_b = np.sin(dw["beam_scan_rad"][k])
    # scan angle from the world azimuth (level flight heading west: scan = boresight offset)
    to_world = dw["beam_az_rad"][k] - dw["beam_scan_rad"][k]
    p = np.array([dw[f"platform_{c}_m"][k] for c in "xyz"])
    los = np.array([det["x_m"], det["y_m"], det["z_m"]]) - p
    los /= np.linalg.norm(los, axis=0)
    bore = np.array([np.sin(to_world), np.cos(to_world)])
    scan_axis = np.array([np.cos(to_world), -np.sin(to_world)])
    horiz = np.hypot(los[0], los[1])
    sin_scan = (los[0] * scan_axis[0] + los[1] * scan_axis[1]) / horiz
    assert np.all(bore[0] * los[0] + bore[1] * los[1] > 0)
    x = (sin_scan - (u_b - half)) / (2 * half)
    assert np.all((x > -1e-9) & (x < 1 + 1e-9))
    assert stats.kstest(x, "uniform").pvalue > ALPHA
    # own range rate (relative to the ground clutter) uniform over +-lambda PRF / 4
    v_p = np.array([dw[f"platform_v{c}_mps"][k] for c in "xyz"])
    own = det["range_rate_mps"] + np.sum(v_p * los, axis=0)
    w = cfg.wrap_velocity_mps
    assert stats.kstest((own + w) / (2 * w), "uniform").pvalue > ALPHA
    # reported SNR = z - 1, z = T + Exp(1): never below the threshold T - 1, exponential above
    t = -math.log(cfg.pfa)
    snr = 10 ** (det["snr_db"] / 10)
    assert np.all(snr >= t - 1 - 1e-9)
    assert stats.kstest(snr - (t - 1), "expon").pvalue > ALPHA
    # sigmas follow from the reported SNR as a target's do; the truth columns are the cell
    assert np.array_equal(det["true_range_m"], det["range_m"])
    assert np.all(det["rcs_dbsm"] != det["rcs_dbsm"])   # NaN: no scatterer


def test_targets_bit_identical_whatever_the_false_alarm_settings():
    """Common random numbers: noise false alarms and clutter regions use their own streams,
    so a target's detections do not move when only false-alarm settings change."""
    fleet = grid_fleet(300, seed=4)
    base = SensorConfig()
    lake = clutter.ClutterConfig(fov_density_per_km2=0.2, regions=[clutter.ClutterRegionConfig(
        name="lake", shape="circle", centre_m=[0.0, 0.0], radius_m=2000.0, density_per_km2=3.0)])
    runs = []
    for cfg, ccfg in ((replace(base, noise_false_alarms=False), None),
                      (base, None), (base, lake),
                      (replace(base, max_false_alarms_per_dwell=1e6), lake)):
        effects = build_effects(cfg, ccfg, 5, merge_iterate=False)
        runs.append(_run(cfg, fleet, duration_s=20.0, effects=effects, seed=5))
    ref = runs[0]["detections"]
    assert np.all(ref["truth_id"] >= 0)
    for out in runs[1:]:
        det = out["detections"]
        t = det["truth_id"] >= 0
        assert t.sum() == len(ref["det_id"])
        for name in ref:
            if name != "det_id":
                assert np.array_equal(det[name][t], ref[name], equal_nan=True), name
    assert np.sum(runs[1]["detections"]["truth_id"] < 0) > 0
    assert np.sum(runs[2]["detections"]["truth_id"] < 0) > np.sum(runs[1]["detections"]["truth_id"] < 0)


@pytest.mark.parametrize("pfa", [1e-15, 1e-9, 0.3, 0.9])
def test_any_pfa_runs_with_finite_bounded_sigmas(pfa):
    # a 300 m window keeps P_FA = 0.9 at 0.9 x 100 x 128 = 11 500 false alarms per dwell
    cfg = SensorConfig(pfa=pfa, range_min_m=30_000.0, range_max_m=30_300.0)
    fleet = grid_fleet(100)
    out = _run(cfg, fleet, duration_s=10.0)
    det = out["detections"]
    fa = det["truth_id"] < 0
    mean = cfg.expected_false_alarms_per_dwell * len(out["dwells"]["dwell_id"])
    assert abs(fa.sum() - mean) <= max(_count_bound(mean), 3.0), (fa.sum(), mean)
    for c in ("range_m", "azimuth_rad", "range_rate_mps", "snr_db", "sigma_range_m",
              "sigma_azimuth_rad", "sigma_range_rate_mps", "x_m", "y_m", "z_m"):
        assert np.all(np.isfinite(det[c])), c
    assert np.all(det["sigma_range_m"] <= cfg.range_resolution_m / math.sqrt(12) + 1e-12)
    bw_max = scan.broadened_beamwidth_rad(cfg, math.radians(10.0))
    assert np.all(det["sigma_azimuth_rad"] <= bw_max / math.sqrt(12) + 1e-12)
    # every report sits at or above the detection threshold in the reported-SNR convention
    t = -math.log(pfa)
    assert np.all(10 ** (det["snr_db"] / 10) >= max(t - 1, 1e-12) * (1 - 1e-9))


def test_pfa_sweep_false_alarms_rise_100x_per_step():
    """100 revisits x 14 dwells x 0.683 x (1e-2, 1, 1e2): 9.6, 956, 95 600 expected."""
    for pfa in (1e-8, 1e-6, 1e-4):
        cfg = SensorConfig(pfa=pfa)
        out = _run(cfg, grid_fleet(0), duration_s=500.0, seed=9)
        n = len(out["detections"]["det_id"])
        mean = cfg.expected_false_alarms_per_dwell * len(out["dwells"]["dwell_id"])
        assert abs(n - mean) < _count_bound(mean), (pfa, n, mean)


def test_pri_null_needs_the_integration_gain_and_too_many_false_alarms_are_refused():
    with pytest.raises(ValueError):
        SensorConfig(pri_s=None).integration_gain
    keys = [p.key for p in SensorConfig(pri_s=None).problems()]
    assert "integration_gain_db" in keys
    assert SensorConfig(pri_s=None, integration_gain_db=21.0).problems() == []
    p = SensorConfig(pfa=0.5).problems()           # 0.5 x 5 337 x 128 = 341 000 per dwell
    assert [x.key for x in p] == ["pfa"] and "max_false_alarms_per_dwell" in p[0].message
    assert SensorConfig(pfa=0.5, max_false_alarms_per_dwell=1e6).problems() == []
    assert SensorConfig(pfa=0.5, noise_false_alarms=False).problems() == []


def test_nothing_beyond_the_radar_horizon():
    """A platform at 100 m sees the ground out to kR·acos(kR/(kR + h)) ≈ sqrt(2 k R h) = 41 km
    (4/3 earth): with a window from 30 to 60 km nothing beyond that, target or false alarm."""
    low = LevelPlatform(p0=(0.0, -45_000.0, 100.0))
    cfg = SensorConfig(pfa=1e-5, range_min_m=30_000.0, range_max_m=60_000.0, pri_s=None,
                       integration_gain_db=21.0, el_min_deg=-10.0, el_max_deg=0.0, stap=False,
                       mdv_mps=0.0)
    a = 4 / 3 * RADIUS_M
    horizon = a * math.acos(a / (a + 100.0))
    assert 41_000 < horizon < 41_300
    targets = still([[0.0, -45_000.0 + 35_000.0], [0.0, -45_000.0 + 50_000.0]])
    out = _run(cfg, targets, platform=low, duration_s=30.0)
    det, looks = out["detections"], out["looks"]
    fa = det["truth_id"] < 0
    k = det["dwell_id"][fa] - out["dwells"]["dwell_id"][0]
    d = np.hypot(det["x_m"][fa] - out["dwells"]["platform_x_m"][k],
                 det["y_m"][fa] - out["dwells"]["platform_y_m"][k])
    assert fa.sum() > 50 and np.all(d <= horizon)
    # the false alarms fill the visible part of the window: (41.2 - 30) / 30 of the cells
    n_dw = len(out["dwells"]["dwell_id"])
    frac = (horizon - 30_000.0) / 30_000.0          # slant = ground to 0.2 m at 100 m altitude
    mean = cfg.expected_false_alarms_per_dwell * n_dw * frac
    assert abs(fa.sum() - mean) < _count_bound(mean) + 0.01 * mean
    far = looks["vehicle_id"] == 1
    near = looks["vehicle_id"] == 0
    seen_far = far & (looks["outcome"] != Outcome.OUTSIDE_FOV)
    assert seen_far.sum() >= 6 and np.all(looks["outcome"][seen_far] == Outcome.TERRAIN)
    assert np.any(looks["outcome"][near] == Outcome.DETECTED)


def test_terrain_shadow_masks_noise_and_clutter_false_alarms():
    wall = WallTerrain(wall_y_m=-1_000.0, wall_top_m=3_000.0)   # shadows the ground behind it
    cfg = SensorConfig(pfa=1e-4)
    ring = clutter.ClutterConfig(regions=[clutter.ClutterRegionConfig(
        name="r", shape="circle", centre_m=[0.0, 0.0], radius_m=4000.0, density_per_km2=5.0)])
    effects = [NoiseFalseAlarms(cfg, 1), FalseAlarms(cfg, ring, 1)]
    out = _run(cfg, grid_fleet(0), terrain=wall, duration_s=10.0, effects=effects)
    det = out["detections"]
    assert len(det["det_id"]) > 100
    # the ray from y = -30 km at 6 km over a 3 km wall at y = -1 km reaches the ground again
    # only beyond y = -1 km + 29 km * 3/3 ... i.e. nothing between the wall and y = 28 km
    behind = (det["y_m"] > -1_000.0 + 1.0)
    assert not np.any(behind & (det["y_m"] < 27_000.0))
    flat = _run(cfg, grid_fleet(0), duration_s=10.0, effects=effects)
    assert np.any((flat["detections"]["y_m"] > 0) & (flat["detections"]["y_m"] < 4000))


@pytest.mark.parametrize("altitude_m", [10.0, 1_000.0, 20_000.0])
def test_altitude_extremes_false_alarms_within_horizon_and_fov(altitude_m):
    """At 10 m the ground is seen to 13.0 km (4/3 earth): nothing from a 5-30 km window beyond
    it; at 20 km up the elevation limits cut the window; all columns finite."""
    plat = LevelPlatform(p0=(0.0, -20_000.0, altitude_m))
    cfg = SensorConfig(pfa=1e-5, range_min_m=5_000.0, range_max_m=30_000.0, el_min_deg=-60.0,
                       el_max_deg=0.0)
    out = _run(cfg, grid_fleet(0), platform=plat, duration_s=20.0)
    det, dw = out["detections"], out["dwells"]
    k = det["dwell_id"] - dw["dwell_id"][0]
    d = np.hypot(det["x_m"] - dw["platform_x_m"][k], det["y_m"] - dw["platform_y_m"][k])
    horizon = math.sqrt(altitude_m * (2 * 4 / 3 * 6_371_000.0 + altitude_m))
    assert np.all(d <= horizon)
    for c in ("range_m", "azimuth_rad", "range_rate_mps", "snr_db", "sigma_range_m", "x_m"):
        assert np.all(np.isfinite(det[c])), c
    el = np.degrees(np.arctan2(det["z_m"] - altitude_m, d))
    assert np.all((el >= -60.0 - 1e-6) & (el <= 1e-6))
    n_dw = len(dw["dwell_id"])
    if altitude_m == 10.0:       # visible window 5..13 km of 25 km: a third of the cells
        frac = (horizon - 5_000.0) / 25_000.0
        mean = cfg.expected_false_alarms_per_dwell * n_dw * frac
        assert abs(len(d) - mean) < _count_bound(mean) + 0.01 * mean
    if altitude_m == 20_000.0:   # slant 5..20 km cannot reach the ground: only 20..30 km does
        assert np.all(det["range_m"] >= 20_000.0)


def test_poisson_ppf_is_scipy_stats_poisson_ppf_exactly():
    """The scipy.special form of the Poisson quantile gives scipy.stats' values bit for bit
    (dwell counts, and with them every false alarm, do not change), near the CDF's steps too."""
    g = np.random.default_rng(5)
    mean = np.concatenate([g.uniform(1e-6, 0.01, 2000), g.uniform(0.01, 3.0, 4000),
                           g.uniform(3.0, 500.0, 4000)])
    q = g.uniform(0.0, 1.0, mean.size)
    q[:200] = 1e-300
    q[200:400] = 1.0 - 2.0 ** -53
    k = g.integers(0, 30, 3000)
    q[400:3400] = stats.poisson.cdf(k, mean[400:3400])     # exactly on a step
    q = np.clip(q, 1e-300, 1.0 - 2.0 ** -53)
    got = noise.poisson_ppf(q, mean)
    want = stats.poisson.ppf(q, mean)
    assert np.array_equal(got, want)
    assert got.min() >= 0 and np.all(np.isfinite(got))


def _with_cdf_steps(q, mean, steps, step_means):
    """``q`` and ``mean`` with the CDF values ``steps`` (of ``step_means``) and their
    neighbours appended (on a step, one ulp either side, a little either side), kept in (0, 1)."""
    near = np.concatenate([np.nextafter(steps, 0.0), steps, np.nextafter(steps, 1.0),
                           steps + 1e-7, steps - 1e-7, steps + 2e-6])
    q = np.concatenate([q, near])
    mean = np.concatenate([mean, np.tile(step_means, 6)])
    keep = (q > 0.0) & (q < 1.0)
    return q[keep], mean[keep]


def _count_pdtrik(monkeypatch):
    """The slow pdtrik path, and a list that records how many values each call sent it."""
    calls = []
    slow = noise._poisson_ppf_pdtrik
    monkeypatch.setattr(noise, "_poisson_ppf_pdtrik",
                        lambda a, b: calls.append(len(a)) or slow(a, b))
    return slow, calls


def test_poisson_ppf_table_path_is_scipy_stats_poisson_ppf_exactly(monkeypatch):
    """A few distinct means (the noise false alarms' case) go through the CDF table, not
    pdtrik: the same values bit for bit, on and next to the CDF's steps too."""
    g = np.random.default_rng(6)
    means = np.asarray([1e-6, 0.05, 0.7142857142857143, 2.5, 40.0, 900.0])
    mean = np.repeat(means, 40_000)
    q = (g.integers(0, 2 ** 53, mean.size) + 0.5) * 2.0 ** -53
    steps = np.concatenate([stats.poisson.cdf(np.arange(60), m) for m in means])
    q, mean = _with_cdf_steps(q, mean, steps, np.repeat(means, 60))
    slow, through_pdtrik = _count_pdtrik(monkeypatch)
    got = noise.poisson_ppf(q, mean)
    assert sum(through_pdtrik) < 0.05 * q.size            # the table really answered
    assert np.array_equal(got, stats.poisson.ppf(q, mean))
    assert np.array_equal(got, slow(q, mean))


def test_poisson_ppf_for_many_means_searches_each_cdf_as_the_table_does(monkeypatch):
    """More distinct means than the table takes (per-dwell clutter means): each value steps up
    its own CDF; the same values as pdtrik and scipy.stats bit for bit, on and next to the
    steps, with pdtrik left for the few values within the margin of a step."""
    g = np.random.default_rng(8)
    mean = np.concatenate([g.uniform(1e-6, 0.05, 3000), g.uniform(0.05, 4.0, 6000),
                           g.uniform(4.0, 300.0, 1000)])
    q = (g.integers(0, 2 ** 53, mean.size) + 0.5) * 2.0 ** -53
    k = g.integers(0, 12, 3000)
    m_step = mean[:3000]
    q, mean = _with_cdf_steps(np.concatenate([q, [0.0, 1.0, 0.5]]),
                              np.concatenate([mean, [0.3, 0.3, 2e4]]),
                              stats.poisson.cdf(k, m_step), m_step)
    slow, through_pdtrik = _count_pdtrik(monkeypatch)
    got = noise.poisson_ppf(q, mean)
    assert np.array_equal(got, stats.poisson.ppf(q, mean))
    assert np.array_equal(got, slow(q, mean))
    through_pdtrik.clear()
    noise.poisson_ppf(q[:9000], mean[:9000])              # uniform q's: the search answers
    assert 0 < sum(through_pdtrik) < 0.01 * 9000
