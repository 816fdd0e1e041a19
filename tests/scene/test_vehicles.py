"""Road-target motion: stops, overshoot, convoys, noise statistics, reproducibility, bad input.

Statistical tests use fixed seeds; their bounds are derived from the sample sizes (chi-square,
binomial/Poisson, standard errors at ~4.5 sigma), so they fail only when the model is wrong.
"""
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as hst
from omegaconf import OmegaConf
from scipy import stats

from gmtiflow.errors import ConfigError, RoadMapError
from gmtiflow.scene import motion
from gmtiflow.scene.roadmap import RoadmapConfig, RoadSpec, load_roadmap
from gmtiflow.scene.vehicles import (TRUTH_COLUMNS, ConvoySpec, RandomFleetSpec, SpeedChangeSpec,
                                     VehiclesConfig, VehicleSpec, build_fleet)

CONF = Path(__file__).resolve().parents[2] / "conf"


def fleet_of(roadmap, *specs, seed=1, duration_s=600.0, dt_s=1.0, random=None):
    cfg = VehiclesConfig(vehicles=list(specs), random=random or RandomFleetSpec())
    return build_fleet(cfg, roadmap, seed, duration_s, dt_s)


@pytest.fixture(scope="module")
def default_map():
    return load_roadmap(RoadmapConfig())


def load_vehicles(name):
    cfg = OmegaConf.merge(OmegaConf.structured(VehiclesConfig),
                          OmegaConf.load(CONF / "vehicles" / f"{name}.yaml"))
    return OmegaConf.to_object(cfg)


# -- stops ----------------------------------------------------------------------------------------
@pytest.mark.parametrize("dt_s, v0", [(1.0, None), (0.7, 17.3), (0.25, None)])
def test_vehicle_stops_exactly_at_the_stop_point(straight_map, dt_s, v0):
    spec = VehicleSpec(name="car", start="a", end="b", cruise_speed_mps=20.0,
                       start_speed_mps=v0, max_decel_mps2=3.0, stop_points=["m"],
                       mean_wait_s=5.0, max_wait_s=30.0)
    fl = fleet_of(straight_map, spec, dt_s=dt_s)
    t = np.arange(0.0, 600.0, 0.01)
    st = fl.state_at(t, 0)
    assert np.all(st["speed_mps"][st["active"]] >= 0.0)
    at_rest = st["active"] & (st["speed_mps"] == 0.0)
    assert at_rest.any()
    assert np.all(np.abs(st["x_m"][at_rest] - 5000.0) <= 1e-9)
    # At rest it is stopped (or, at the very instant of moving off, accelerating).
    assert set(st["mode"][at_rest].tolist()) == {motion.MODE_STOPPED, motion.MODE_ACCEL}
    # Braking never exceeds max_decel and the arc length never runs backwards.
    assert np.all(st["ax_mps2"][st["active"]] >= -3.0 * (1 + 1e-9))
    assert np.all(np.diff(st["route_s_m"][st["active"]]) >= 0.0)
    # The exact instant of rest from the profile: position is the stop point there too.
    p = fl.profiles
    k = int(np.flatnonzero(p.mode[:, 0] == motion.MODE_DECEL)[-1])
    t_rest = k * dt_s + p.tau_s[k, 0]
    st = fl.state_at(np.array([t_rest, t_rest + 1e-6]), 0)
    assert np.all(np.abs(st["route_s_m"] - 5000.0) <= 1e-9)
    assert np.all(st["speed_mps"] == 0.0)


def test_speed_is_never_negative_with_heavy_speed_noise(straight_map):
    spec = VehicleSpec(name="slow", start="a", end="b", cruise_speed_mps=1.0,
                       speed_noise_mps=2.0, max_accel_mps2=10.0, max_decel_mps2=10.0,
                       random_stop_rate_per_s=0.05, stop_points=["m"])
    fl = fleet_of(straight_map, spec, duration_s=2000.0, dt_s=0.5)
    st = fl.state_at(np.arange(0, 2000, 0.05), 0)
    assert np.nanmin(st["speed_mps"]) == 0.0
    assert np.all(st["speed_mps"][st["active"]] >= 0.0)


# -- overshoot (paper Fig. 1) is carried onto the next road ---------------------------------------
@pytest.mark.parametrize("dt_s", [1.0, 3.0])
def test_overshoot_at_a_crossroad_lies_on_the_next_road(corner_map, dt_s):
    spec = VehicleSpec(name="c", start="a", end="b", cruise_speed_mps=7.0)
    fl = fleet_of(corner_map, spec, dt_s=dt_s)
    t = np.array([14.0, 14.3, 15.0, 20.0])         # the corner is passed at t = 100/7 = 14.29 s
    st = fl.state_at(t, 0)
    s = 7.0 * t
    assert np.allclose(st["route_s_m"], s, atol=1e-9)
    assert np.allclose(st["x_m"], [98.0, 100.0, 100.0, 100.0], atol=1e-9)
    assert np.allclose(st["y_m"], [0.0, s[1] - 100, s[2] - 100, s[3] - 100], atol=1e-9)
    e = corner_map.edges["edge_id"]
    assert st["edge_id"].tolist() == [e[0], e[1], e[1], e[1]]
    assert np.allclose(st["heading_rad"], [np.pi / 2, 0, 0, 0])
    assert np.allclose(st["vy_mps"][1:], 7.0) and np.allclose(st["vx_mps"][0], 7.0)
    # Arrival: 400 m at 7 m/s, then the vehicle disappears.
    assert fl.end_time_s[0] == pytest.approx(400.0 / 7.0)
    st = fl.state_at([400.0 / 7.0 - 1e-6, 400.0 / 7.0 + 1e-6], 0)
    assert st["active"].tolist() == [True, False]
    assert np.isnan(st["x_m"][1]) and st["edge_id"][1] == -1


# -- position noise -------------------------------------------------------------------------------
def test_positions_lie_on_the_route_within_the_position_noise(default_map):
    cfg = load_vehicles("default")
    fl = build_fleet(cfg, default_map, 11, 900.0, 1.0)
    tt = fl.truth_table(np.arange(0.0, 900.0, 0.5))
    sig = {v.name: np.asarray(v.position_noise_m) for v in cfg.vehicles}
    for vid, name in enumerate(fl.vehicles["name"]):
        m = tt["vehicle_id"] == vid
        route = fl.routes[vid]
        on_road = route.position_at(tt["route_s_m"][m])
        d = np.column_stack([tt["x_m"][m], tt["y_m"][m], tt["z_m"][m]]) - on_road
        h = tt["heading_rad"][m]
        along = d[:, 0] * np.sin(h) + d[:, 1] * np.cos(h)
        across = -d[:, 0] * np.cos(h) + d[:, 1] * np.sin(h)
        s = sig[name.rsplit("-", 1)[0] if name.startswith("convoy") else name]
        assert np.all(np.abs(along) < 5 * s[0] + 1e-9), name
        assert np.all(np.abs(across) < 5 * s[1] + 1e-9), name
        assert np.all(np.abs(d[:, 2]) < 5 * s[2] + 1e-9), name


def test_position_noise_has_the_configured_sigma(straight_map):
    sig = np.array([2.0, 0.5, 0.05])
    spec = VehicleSpec(name="n", start="a", end="b", cruise_speed_mps=10.0,
                       position_noise_m=sig.tolist())
    fl = fleet_of(straight_map, spec, duration_s=1500.0, dt_s=1.0)
    t = np.arange(0.0, 1500.0, 1.0)                 # grid instants: independent draws
    st = fl.state_at(t, 0)
    d = np.column_stack([st["x_m"] - st["route_s_m"], st["y_m"], st["z_m"]])
    n = len(t)
    lo, hi = stats.chi2.ppf([0.0005, 0.9995], n)
    for col in range(3):
        chi = np.sum((d[:, col] / sig[col]) ** 2)
        assert lo < chi < hi, (col, chi / n)
    # Between grid points the noise is interpolated, so state_at is reproducible at any t.
    again = fl.state_at(t + 0.37, 0)
    assert np.array_equal(again["y_m"], fl.state_at(t + 0.37, 0)["y_m"])


def test_correlated_position_noise_keeps_sigma_and_correlation(straight_map):
    sig, corr, dt = np.array([1.0, 0.5, 0.05]), 3.0, 0.5
    specs = [VehicleSpec(name=f"p{i}", start="a", end="b", cruise_speed_mps=10.0,
                         position_noise_m=sig.tolist(), position_noise_corr_s=corr)
             for i in range(30)]
    fl = fleet_of(straight_map, *specs, duration_s=900.0, dt_s=dt, seed=8)
    t = np.arange(0.0, 900.0, 30.0)                   # 10 correlation times apart: independent
    st = fl.state_at(t[:, None], np.arange(30)[None, :])
    d = np.stack([st["x_m"] - st["route_s_m"], st["y_m"], st["z_m"]], axis=-1).reshape(-1, 3)
    n = len(d)
    lo, hi = stats.chi2.ppf([0.0005, 0.9995], n)
    for col in range(3):
        assert lo < np.sum((d[:, col] / sig[col]) ** 2) < hi, col
    # Correlation of the across-road noise at lags of 1, 3 and 6 s: the normalised cubic
    # B-spline's with knots corr = 3 s apart (gmtiflow.scene.wander), computed here from the
    # basis polynomials directly, averaged over the knot phases of the sampled instants.
    t = np.arange(0.0, 900.0, 1.0)
    y = fl.state_at(t[:, None], np.arange(30)[None, :])["y_m"] / sig[1]

    def weights(u):
        i = int(np.floor(u))
        x = u - i
        w = [(1 - x) ** 3 / 6, (3 * x ** 3 - 6 * x ** 2 + 4) / 6,
             (-3 * x ** 3 + 3 * x ** 2 + 3 * x + 1) / 6, x ** 3 / 6]
        return {i + k: wk for k, wk in enumerate(w)}

    for lag, rho_min in ((1, 0.8), (3, 0.45), (6, 0.0)):
        exp_r = []
        for t0 in t[:3]:                      # the phases t / corr takes
            a, b = weights(t0 / corr), weights((t0 + lag) / corr)
            cov = sum(w * b.get(k, 0.0) for k, w in a.items())
            exp_r.append(cov / np.sqrt(sum(w * w for w in a.values()) * sum(w * w for w in b.values())))
        rho = float(np.mean(exp_r))
        assert rho >= rho_min
        r = np.sum(y[:-lag] * y[lag:]) / np.sqrt(np.sum(y[:-lag] ** 2) * np.sum(y[lag:] ** 2))
        # ~y.size / (4 corr) independent pairs (knots 4 corr wide)
        assert abs(r - rho) < 4.5 * (1 - rho ** 2) / np.sqrt(y.size / (4 * corr)) + 0.005, lag


# -- speed noise, random stops, waiting times -----------------------------------------------------
def test_speed_noise_has_the_configured_sigma(straight_map):
    sigma, cruise = 0.4, 20.0
    spec = VehicleSpec(name="v", start="a", end="b", cruise_speed_mps=cruise,
                       speed_noise_mps=sigma, max_accel_mps2=4.0, max_decel_mps2=4.0)
    fl = fleet_of(straight_map, spec, duration_s=990.0, dt_s=1.0)
    v = fl.profiles.v_mps[1:, 0]                     # end-of-step speeds: the per-step draws
    n = len(v)
    chi = np.sum(((v - cruise) / sigma) ** 2)
    lo, hi = stats.chi2.ppf([0.0005, 0.9995], n)
    assert n > 900 and lo < chi < hi
    assert abs(v.mean() - cruise) < 4.5 * sigma / np.sqrt(n)


@pytest.mark.parametrize("dt_s", [0.25, 2.0])
def test_correlated_speed_noise_keeps_sigma_and_correlation_time_at_any_dt(straight_map, dt_s):
    sigma, cruise, corr = 0.5, 20.0, 4.0
    specs = [VehicleSpec(name=f"v{i}", start="a", end="b", cruise_speed_mps=cruise,
                         speed_noise_mps=sigma, speed_noise_corr_s=corr, max_accel_mps2=4.0,
                         max_decel_mps2=4.0) for i in range(40)]
    fl = fleet_of(straight_map, *specs, duration_s=800.0, dt_s=dt_s, seed=4)
    v = fl.profiles.v_mps[1:]                          # (K, 40) end-of-step speeds
    # Samples 40 s = 10 correlation times apart are independent: chi-square on their spread.
    every = int(round(40.0 / dt_s))
    x = (v[::every] - cruise) / sigma
    n = x.size
    lo, hi = stats.chi2.ppf([0.0005, 0.9995], n)
    assert n >= 760 and lo < np.sum(x**2) < hi
    # Lag-1 s correlation exp(-1/4); its standard error is about (1 - rho^2) / sqrt(n_eff).
    lag = int(round(1.0 / dt_s)) or 1
    z = (v - cruise) / sigma
    r = np.sum(z[:-lag] * z[lag:]) / np.sqrt(np.sum(z[:-lag] ** 2) * np.sum(z[lag:] ** 2))
    rho = np.exp(-lag * dt_s / corr)
    n_eff = v.size * dt_s / (2 * corr)
    assert abs(r - rho) < 4.5 * (1 - rho**2) / np.sqrt(n_eff) + 0.01


def _runs(labels, value):
    """Lengths of complete runs of ``value`` in a 1-D label array (runs touching an end dropped)."""
    x = np.concatenate([[False], labels == value, [False]]).astype(np.int8)
    d = np.diff(x)
    starts, ends = np.flatnonzero(d == 1), np.flatnonzero(d == -1)
    keep = (starts > 0) & (ends < len(labels))
    return ends[keep] - starts[keep]


@pytest.fixture(scope="module")
def stopping_fleet(long_road):
    specs = [VehicleSpec(name=f"s{i}", start="a", end="b", cruise_speed_mps=15.0,
                         max_accel_mps2=2.0, max_decel_mps2=4.0, random_stop_rate_per_s=0.02,
                         mean_wait_s=10.0, max_wait_s=1e6) for i in range(40)]
    return fleet_of(long_road, *specs, duration_s=3000.0, dt_s=1.0, seed=5)


def test_random_stop_count_matches_the_rate(stopping_fleet):
    p = stopping_fleet.profiles
    dt = p.dt_s
    prob = -np.expm1(-0.02 * dt)
    eligible = stops = 0
    for col in range(p.mode.shape[1]):
        lab = p.mode[:, col]
        v = p.v_mps[:-1, col]
        brakes = np.flatnonzero((lab == motion.MODE_DECEL)
                                & np.concatenate([[True], lab[:-1] != motion.MODE_DECEL]))
        stops += len(brakes)
        eligible += int(np.sum(((lab == motion.MODE_CRUISE) | (lab == motion.MODE_ACCEL))
                               & (v > 0))) + len(brakes)
    mean = eligible * prob
    assert stops > 1000
    assert abs(stops - mean) < 4.5 * np.sqrt(mean * (1 - prob))


def test_waiting_times_are_geometric_with_the_configured_mean(stopping_fleet):
    p = stopping_fleet.profiles
    w = np.concatenate([_runs(p.mode[:, c], motion.MODE_STOPPED) for c in range(p.mode.shape[1])])
    q = 1.0 / 10.0                                    # dt / mean_wait_s
    n = len(w)
    assert n > 1000 and w.min() >= 1
    assert abs(w.mean() - 1 / q) < 4.5 * np.sqrt((1 - q) / q**2 / n)
    ones = np.sum(w == 1)                             # P(W = 1) = q
    assert abs(ones - n * q) < 4.5 * np.sqrt(n * q * (1 - q))


def test_waiting_time_is_bounded_by_max_wait(straight_map):
    spec = VehicleSpec(name="w", start="a", end="b", cruise_speed_mps=15.0,
                       random_stop_rate_per_s=0.05, mean_wait_s=10.0, max_wait_s=12.0)
    fl = fleet_of(straight_map, spec, duration_s=1300.0, dt_s=1.0)
    w = _runs(fl.profiles.mode[:, 0], motion.MODE_STOPPED)
    assert len(w) > 5 and w.max() == 12


def test_random_stop_rate_does_not_depend_on_dt(long_road):
    counts = {}
    for dt in (0.5, 2.0):
        specs = [VehicleSpec(name=f"s{i}", start="a", end="b", cruise_speed_mps=15.0,
                             random_stop_rate_per_s=0.01, mean_wait_s=5.0)
                 for i in range(20)]
        fl = fleet_of(long_road, *specs, duration_s=3000.0, dt_s=dt, seed=9)
        lab = fl.profiles.mode
        counts[dt] = int(np.sum((lab[1:] == motion.MODE_DECEL) & (lab[:-1] != motion.MODE_DECEL)))
    a, b = counts[0.5], counts[2.0]
    # Two Poisson counts of the same mean (~ 20 * 3000 s * 0.01 * driving fraction).
    assert a > 300 and abs(a - b) < 4.5 * np.sqrt(a + b)


def test_random_stop_just_short_of_a_stop_point_does_not_strand_the_vehicle(make_map):
    """Regression: a vehicle at rest 1 m before a stop point used to brake 'to the point' from
    v = 0 for ever. Dense stop points (every 37 m) and frequent random stops provoke it."""
    nodes = {f"n{i}": [37.0 * i, 0.0, 0.0] for i in range(30)}
    rm = make_map(nodes, [RoadSpec(f"n{i}", f"n{i + 1}") for i in range(29)])
    specs = [VehicleSpec(name=f"v{i}", start="n0", end="n29", cruise_speed_mps=15.0,
                         random_stop_rate_per_s=0.3, mean_wait_s=2.0, max_wait_s=4.0,
                         stop_points=[f"n{j}" for j in range(1, 29)]) for i in range(20)]
    fl = fleet_of(rm, *specs, duration_s=1500.0, dt_s=1.0, seed=3)
    assert np.all(np.isfinite(fl.end_time_s))
    p = fl.profiles
    for c in range(20):
        # at v = 0 without being 'stopped' for at most the one step of moving off
        idle = (p.v_mps[:-1, c] == 0) & (p.mode[:, c] != motion.MODE_STOPPED) \
            & (p.s_m[:-1, c] < fl.routes[c].length_m)
        assert _runs(np.concatenate([[False], idle, [False]]), True).max(initial=0) <= 1


# -- convoys --------------------------------------------------------------------------------------
@pytest.mark.parametrize("convoy, gap", [(ConvoySpec(3, spacing_m=25.0), 25.0),
                                         (ConvoySpec(4, spacing_s=2.0), 40.0)])
def test_convoy_members_keep_their_spacing(straight_map, convoy, gap):
    spec = VehicleSpec(name="cv", type="truck", start="a", end="b", cruise_speed_mps=20.0,
                       speed_noise_mps=0.5, stop_points=["m"], random_stop_rate_per_s=0.01,
                       convoy=convoy, start_time_s=5.0)
    fl = fleet_of(straight_map, spec, duration_s=900.0, dt_s=1.0)
    n = convoy.count
    assert fl.vehicles["name"].tolist() == [f"cv-{i + 1}" for i in range(n)]
    assert np.all(fl.vehicles["convoy_id"] == 0)
    # Member i appears when the leader is i * gap down the road (start-time offsets).
    assert np.all(np.diff(fl.vehicles["start_time_s"]) > 0)
    t = np.arange(0.0, 900.0, 0.25)
    st = fl.state_at(t[:, None], np.arange(n)[None, :])
    both = st["active"].all(axis=1)
    assert both.sum() > 1000
    s = st["route_s_m"][both]
    assert np.allclose(np.diff(s, axis=1), -gap, atol=1e-9)
    # At the stop point they queue: leader on it, the others one gap behind each other.
    rest = both & (st["speed_mps"][:, 0] == 0) & (np.abs(st["route_s_m"][:, 0] - 5000) < 1e-9)
    assert rest.any()
    assert np.allclose(st["route_s_m"][rest][0], 5000.0 - gap * np.arange(n))


# -- speed limits, speed changes, tunnel, off-road ------------------------------------------------
def test_speed_limit_and_speed_change_points(default_map):
    fast = VehicleSpec(name="fast", start="g_0_2", end="g_6_2", cruise_speed_mps=30.0)
    change = VehicleSpec(name="chg", start="hw_x-4000", end="hw_x0", cruise_speed_mps=30.0,
                         speed_changes=[SpeedChangeSpec(at="hw_x-2000", cruise_speed_mps=12.0)])
    fl = fleet_of(default_map, fast, change, duration_s=600.0)
    st = fl.state_at(np.arange(0, 600, 0.5)[:, None], np.arange(2)[None, :])
    v0 = st["speed_mps"][:, 0][st["active"][:, 0]]
    assert np.all(v0 <= 13.9 + 1e-9) and v0.max() == pytest.approx(13.9)
    x1 = st["x_m"][:, 1]
    v1 = st["speed_mps"][:, 1]
    # It brakes before the change point (anticipating, on the step grid: within 5 %) and keeps
    # 12 m/s from one step after it on.
    assert np.all(v1[x1 >= -2000] <= 12.0 * 1.05)
    assert np.all(v1[x1 >= -2000 + 30] <= 12.0 + 1e-9)
    assert np.all(v1[x1 < -2000 - 130] == 30.0)            # (30² - 12²) / (2 * 0.9 * 4) = 105 m
    a1 = st["ax_mps2"][:, 1][st["active"][:, 1]]
    assert a1.min() >= -4.0 * (1 + 1e-9)


def test_tunnel_rows_are_invisible(default_map):
    spec = VehicleSpec(name="tun", start="hw_x4000", end="hw_x0", cruise_speed_mps=30.0,
                       speed_noise_mps=0.5, position_noise_m=[1.0, 0.5, 0.05])
    fl = fleet_of(default_map, spec)
    tt = fl.truth_table(np.arange(0, 600, 0.5))
    x = tt["route_s_m"]                                # westwards from x = 4000
    inside = (x > 1500 + 1e-6) & (x < 2500 - 1e-6)
    assert inside.sum() > 50
    assert np.array_equal(tt["invisible"][inside], np.ones(inside.sum(), bool))
    assert not tt["invisible"][(x < 1500 - 1e-6) | (x > 2500 + 1e-6)].any()


def test_off_road_vehicle_drives_its_waypoints(default_map):
    spec = VehicleSpec(name="off", off_road=[[0, -3000], [300, -2600], [300, -2000]],
                       cruise_speed_mps=5.0)
    fl = fleet_of(default_map, spec)
    tt = fl.truth_table(np.arange(0, 600, 1.0))
    assert np.all(tt["edge_id"] == -1) and fl.vehicles["off_road"].all()
    assert fl.vehicles["route_length_m"][0] == pytest.approx(1100.0)
    assert np.allclose(tt["x_m"][tt["time_s"] == 50.0], 150.0)
    assert fl.end_time_s[0] == pytest.approx(220.0)


# -- tables ---------------------------------------------------------------------------------------
def test_truth_table_columns_and_order(default_map):
    fl = build_fleet(load_vehicles("default"), default_map, 3, 300.0, 1.0)
    tt = fl.truth_table(np.arange(300.0, 0.0, -2.0))
    assert list(tt) == list(TRUTH_COLUMNS)
    order = np.lexsort((tt["vehicle_id"], tt["time_s"]))
    assert np.array_equal(order, np.arange(len(order)))
    assert tt["mode"].dtype == np.uint8 and tt["invisible"].dtype == bool
    assert np.all(tt["speed_mps"] >= 0)
    v = fl.vehicles
    assert list(v) == ["vehicle_id", "name", "convoy_id", "vehicle_type", "start_time_s",
                       "route_length_m", "off_road"]
    assert sorted(set(v["vehicle_type"])) == ["car", "truck"]
    st = fl.state_at(-5.0, np.arange(len(v["name"])))
    assert not st["active"].any() and np.all(np.isnan(st["x_m"]))
    st = fl.state_at(1e4, np.arange(len(v["name"])))           # beyond the simulated horizon
    assert not st["active"].any() and np.all(st["mode"] == 255)
    assert fl.state_at(150.0, [-1, 99])["active"].tolist() == [False, False]


def test_truth_table_is_state_at_of_the_active_pairs_whatever_the_chunks(default_map):
    # truth_table evaluates the active (time, vehicle) pairs only, in blocks; every row is
    # state_at's for that pair bit for bit, also among inactive rows (its other path)
    cfg = VehiclesConfig(random=RandomFleetSpec(count=12, start_time_max_s=100.0,
                                                random_stop_rate_per_s=0.02))
    fl = build_fleet(cfg, default_map, 5, 200.0, 0.5)
    times = np.arange(0.0, 200.0, 0.7)
    whole = fl.truth_table(times)
    tt, vv = np.meshgrid(times, np.arange(fl.n_vehicles), indexing="ij")
    grid = fl.state_at(tt.ravel(), vv.ravel())
    act = grid.pop("active")
    assert 0 < act.sum() < act.size
    assert list(whole) == list(TRUTH_COLUMNS) and len(whole["time_s"]) == act.sum()
    for chunk in (7, 1000, 10**6):
        blocks = list(fl.truth_blocks(times, block_rows=chunk))
        assert max(len(b["time_s"]) for b in blocks) <= chunk
        part = {k: np.concatenate([b[k] for b in blocks]) for k in TRUTH_COLUMNS}
        for k in TRUTH_COLUMNS:
            assert part[k].dtype == grid[k].dtype, k
            assert part[k].tobytes() == grid[k][act].tobytes(), k
            assert whole[k].tobytes() == part[k].tobytes(), k


def test_empty_fleet_and_empty_times(default_map):
    empty = build_fleet(VehiclesConfig(), default_map, 1, 100.0, 1.0)
    tt = empty.truth_table(np.arange(10.0))
    assert list(tt) == list(TRUTH_COLUMNS) and len(tt["time_s"]) == 0
    assert len(empty.vehicles["vehicle_id"]) == 0
    fl = build_fleet(load_vehicles("default"), default_map, 1, 100.0, 1.0)
    tt = fl.truth_table([])
    assert list(tt) == list(TRUTH_COLUMNS) and len(tt["time_s"]) == 0


# -- reproducibility ------------------------------------------------------------------------------
def _equal(a, b):
    return all(np.array_equal(a[k], b[k], equal_nan=a[k].dtype.kind == "f") for k in a)


def test_same_inputs_give_bit_identical_truth(default_map):
    cfg = load_vehicles("default")
    times = np.arange(0.0, 600.0, 0.5)
    a = build_fleet(cfg, default_map, 42, 600.0, 1.0).truth_table(times)
    b = build_fleet(load_vehicles("default"), default_map, 42, 600.0, 1.0).truth_table(times)
    assert _equal(a, b)
    c = build_fleet(cfg, default_map, 43, 600.0, 1.0).truth_table(times)
    assert not np.array_equal(a["x_m"], c["x_m"])


def test_changing_one_vehicle_leaves_the_others_bit_identical(default_map):
    cfg = load_vehicles("default")
    times = np.arange(0.0, 600.5, 0.5)        # up to the scene's last instant, included
    base = build_fleet(cfg, default_map, 42, 600.0, 1.0)
    other = load_vehicles("default")
    truck = next(v for v in other.vehicles if v.name == "truck-1")
    truck.cruise_speed_mps = 15.0
    truck.speed_noise_mps = 1.0
    truck.random_stop_rate_per_s = 0.05
    other.vehicles.append(VehicleSpec(name="extra", start="g_0_0", end="g_2_2"))
    other.vehicles.insert(0, other.vehicles.pop())      # and shift every vehicle id by one
    changed = build_fleet(other, default_map, 42, 900.0, 1.0)   # and a longer run
    for vid, name in enumerate(base.vehicles["name"]):
        j = int(np.flatnonzero(changed.vehicles["name"] == name)[0])
        a = base.state_at(times, vid)
        b = changed.state_at(times, j)
        a.pop("vehicle_id")
        b.pop("vehicle_id")
        if name == "truck-1":
            assert not np.array_equal(a["x_m"], b["x_m"], equal_nan=True)
        else:
            assert _equal(a, b), name


def test_profiles_are_stepped_and_stored_for_each_trip_only(default_map):
    """Cost and memory follow the trips: a profile's steps end at its arrival (or at the
    scene's end, plus the one step that gives the last instant), not at the scene's end for
    every vehicle."""
    dur, dt = 3600.0, 0.5
    rnd = RandomFleetSpec(count=60, start_time_max_s=dur - 300.0, min_route_m=200.0)
    fl = fleet_of(default_map, random=rnd, duration_s=dur, dt_s=dt)
    p = fl.profiles
    t0 = fl.start_time_s                       # no convoys: one profile per vehicle
    horizon = np.ceil((dur - t0) / dt - 1e-9).astype(int) + 1
    with np.errstate(invalid="ignore"):      # the step in which it arrives is its last
        arrival = np.ceil((fl.end_time_s - t0) / dt)
    assert np.array_equal(p.n_steps_p, np.minimum(arrival, horizon))
    assert p.n_steps_p.sum() < 0.2 * len(t0) * p.n_steps  # trips, not vehicles x scene steps


def test_random_fleet_on_the_largest_component(square_map):
    rnd = RandomFleetSpec(count=30, start_time_max_s=100.0, random_stop_rate_per_s=0.01)
    fl = fleet_of(square_map, random=rnd, duration_s=300.0)
    comp = set(square_map.largest_component().tolist())
    assert len(comp) == 5 and fl.n_vehicles == 30
    for r in fl.routes:
        assert set(r.node_ids.tolist()) <= comp
    more = fleet_of(square_map, random=RandomFleetSpec(count=40, start_time_max_s=100.0,
                                                       random_stop_rate_per_s=0.01),
                    duration_s=300.0)
    t = np.arange(0, 300, 1.0)
    assert _equal(fl.state_at(t[:, None], np.arange(30)), more.state_at(t[:, None],
                                                                         np.arange(30)))


def test_random_preset_runs_on_the_default_scene(default_map):
    cfg = load_vehicles("random")
    assert cfg.random.count == 100 and cfg.problems() == []
    fl = build_fleet(cfg, default_map, 1, 600.0, 1.0)
    tt = fl.truth_table(np.arange(0, 600, 5.0))
    assert fl.n_vehicles == 100 and len(tt["time_s"]) > 1000


# -- bad input ------------------------------------------------------------------------------------
def test_config_problems_name_vehicle_and_key(straight_map):
    bad = VehicleSpec(name="neg", start="a", end="b", cruise_speed_mps=-1.0,
                      position_noise_m=[1.0, 2.0], mean_wait_s=100.0, max_wait_s=10.0,
                      convoy=ConvoySpec(count=2))
    with pytest.raises(ConfigError) as err:
        fleet_of(straight_map, bad)
    msg = str(err.value)
    for key in ("vehicles[0].cruise_speed_mps", "vehicles[0].position_noise_m",
                "vehicles[0].mean_wait_s", "vehicles[0].convoy.spacing_m"):
        assert f"vehicles.{key}" in msg
    dup = VehiclesConfig(vehicles=[VehicleSpec(name="x", start="a", end="b")] * 2)
    assert [p.key for p in dup.problems()] == ["vehicles[1].name"]
    with pytest.raises(ConfigError, match="dt_s"):
        fleet_of(straight_map, VehicleSpec(name="x", start="a", end="b"), dt_s=0.0)


def test_road_errors_name_the_vehicle(square_map):
    with pytest.raises(RoadMapError, match=r"vehicle 'lost'.*unknown node 'mars'"):
        fleet_of(square_map, VehicleSpec(name="lost", start="s0", end="mars"))
    with pytest.raises(RoadMapError, match=r"vehicles=random works on any map"):
        build_fleet(load_vehicles("default"), square_map, 1, 60.0, 1.0)
    with pytest.raises(RoadMapError, match=r"vehicle 'far'.*no route from node 's0'"):
        fleet_of(square_map, VehicleSpec(name="far", start="s0", end="iso_b"))
    with pytest.raises(RoadMapError, match=r"vehicle 'sp'.*'iso_a' is not on the vehicle's route"):
        fleet_of(square_map, VehicleSpec(name="sp", start="s0", end="t1", stop_points=["iso_a"]))


# -- property test of the kernel ------------------------------------------------------------------
@settings(max_examples=30, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(dt=hst.sampled_from([0.1, 0.5, 1.0, 2.0, 3.3]), cruise=hst.floats(1.0, 40.0),
       sigma=hst.floats(0.0, 3.0), amax=hst.floats(0.3, 5.0), dmax=hst.floats(0.5, 8.0),
       limit=hst.floats(3.0, 30.0), seed=hst.integers(0, 2**31),
       rate=hst.sampled_from([0.0, 0.0, 0.05, 0.3]))
def test_kernel_invariants(make_map, dt, cruise, sigma, amax, dmax, limit, seed, rate):
    """Whatever the parameters: s never runs backwards, v >= 0, s(t) is continuous across step
    boundaries, and without random stops every stop (mode stopped) is exactly at a stop point.
    (Speed noise alone may touch v = 0 in cruise: it is clipped at zero, never negative.)"""
    rm = make_map({"a": [0, 0, 0], "b": [400, 0, 0], "c": [400, 700, 5], "d": [1500, 700, 5]},
                  [RoadSpec("a", "b"), RoadSpec("b", "c", speed_limit_mps=limit),
                   RoadSpec("c", "d")])
    spec = VehicleSpec(name="h", start="a", end="d", cruise_speed_mps=cruise,
                       speed_noise_mps=sigma, max_accel_mps2=amax, max_decel_mps2=dmax,
                       stop_points=["b", "c"], mean_wait_s=3.0, max_wait_s=6.0,
                       random_stop_rate_per_s=rate)
    fl = fleet_of(rm, spec, seed=seed, duration_s=400.0, dt_s=dt)
    t = np.linspace(0.0, 400.0, 8_001)
    s = fl.state_at(t, 0)
    act = s["active"]
    assert np.all(np.diff(s["route_s_m"][act]) >= -1e-9)
    assert np.all(s["speed_mps"][act] >= 0.0)
    rest = act & (s["mode"] == motion.MODE_STOPPED)
    assert np.all(s["speed_mps"][rest] == 0.0)
    if rate == 0.0:
        stop_s = fl.routes[0].s_m[[1, 2]]
        d = np.min(np.abs(s["route_s_m"][rest][:, None] - stop_s[None, :]), axis=1)
        assert np.all(d <= 1e-9)
    # Never stuck: no rest lasts longer than the longest wait plus the steps around it.
    still = np.concatenate([[0], (act & (s["speed_mps"] == 0.0)).astype(np.int8), [0]])
    edges = np.flatnonzero(np.diff(still))
    longest = np.max(edges[1::2] - edges[::2], initial=0) * (t[1] - t[0])
    assert longest <= 6.0 + 3 * dt + 0.2 or sigma >= cruise / 3
    k = np.arange(1, fl.profiles.n_steps)
    left = fl.state_at(k * dt - 1e-9, 0)["route_s_m"]
    right = fl.state_at(k * dt, 0)["route_s_m"]
    ok = np.isfinite(left) & np.isfinite(right)
    assert np.all(np.abs(left[ok] - right[ok]) <= 1e-9 * 50 + 1e-9)


@pytest.mark.parametrize("min_route_m, types", [(0.0, {"car": 0.8, "truck": 0.2}),
                                                (1500.0, {"bus": 1.0, "car": 2.0, "van": 0.5})])
def test_random_specs_are_the_documented_draws_of_each_vehicles_own_stream(min_route_m, types):
    """Each random vehicle: from rng.stream(seed, "truth", "vehicle", name, "spec"), node
    pairs by integers(0, n, 2) until distinct (and min_route_m apart), then the type by
    inversion of random() on the weights' CDF, the start time and the cruise speed by
    uniform(lo, hi): the vehicles' specs follow from those draws exactly."""
    from gmtiflow import rng
    from gmtiflow.scene.roadmap import RoadmapConfig, load_roadmap
    from gmtiflow.scene.vehicles import _random_specs
    rm = load_roadmap(RoadmapConfig())
    spec = RandomFleetSpec(count=300, types=types, start_time_min_s=3.0, start_time_max_s=90,
                           cruise_speed_min_mps=7.5, cruise_speed_max_mps=21.0,
                           min_route_m=min_route_m)
    got = _random_specs(spec, rm, 11)
    nodes = rm.largest_component()
    xy = rm.node_xyz(nodes)[:, :2]
    names = sorted(types)
    cdf = np.cumsum([types[t] for t in names]) / sum(types.values())
    too_close = 0
    for i, vs in enumerate(got):
        g = rng.stream(11, "truth", "vehicle", f"random-{i:04d}", "spec")
        while True:
            a, b = g.integers(0, len(nodes), size=2)
            if a != b and np.hypot(*(xy[a] - xy[b])) >= min_route_m:
                break
            too_close += a != b
        vtype = names[min(int(np.searchsorted(cdf, g.random(), side="right")), len(names) - 1)]
        assert (vs.start, vs.end) == (str(rm.nodes["name"][nodes[a]]),
                                      str(rm.nodes["name"][nodes[b]]))
        assert vs.type == vtype
        assert vs.start_time_s == float(g.uniform(3.0, 90))
        assert vs.cruise_speed_mps == float(g.uniform(7.5, 21.0))
    assert len({v.type for v in got}) == len(types)
    assert (too_close > 0) == (min_route_m > 0)     # the distance did reject pairs


@pytest.mark.parametrize("n_nodes", [2, 59, 1000, 2**31 + 1, 2**32 - 1])
def test_spec_draws_read_from_raw_words_are_the_calls_draws(n_nodes):
    """_spec_draws reads integers(0, n, 2) and random(3) of each stream from its first four
    raw words, bit for bit what the calls draw; the rows where the calls would draw again
    (Lemire's rejection, likely with 2^31 + 1 nodes) are marked for the calls, and so are all
    with 2^32 nodes or more, or when the check stream draws differently."""
    from gmtiflow import rng
    from gmtiflow.scene.streams import first_words
    from gmtiflow.scene.vehicles import _spec_draws
    names = [f"v{i}" for i in range(200)]
    raw = first_words(3, ("x",), names)
    fresh = lambda: [rng.stream(3, "x", n) for n in names]  # noqa: E731
    pair, u, plain = _spec_draws(raw, n_nodes, None)
    for g, p, uu, ok in zip(fresh(), pair, u, plain):
        want = g.integers(0, n_nodes, size=2)
        if ok:
            assert p.tolist() == want.tolist()
            assert uu.tobytes() == g.random(3).tobytes()
    assert plain.sum() >= 20 and plain.all() == (n_nodes != 2**31 + 1)
    assert not _spec_draws(raw, 2**32, None)[2].any()
    if n_nodes == 59:           # a check stream that draws otherwise: every vehicle by its calls
        assert _spec_draws(raw, n_nodes, rng.stream(3, "x", "v0"))[2].all()
        assert not _spec_draws(raw, n_nodes, rng.stream(3, "x", "other"))[2].any()


def test_speed_noise_normals_are_finite_at_both_ends_of_the_uniforms():
    """Φ⁻¹ at u + 2^-54: u = 0 is not inverted at 0 (-inf), and the largest uniform, which
    rounds to 1 with the offset, is inverted at 1 - 2^-53 (8.3σ), not at 1 (+inf: NaN speeds)."""
    from scipy.special import ndtri

    from gmtiflow.scene.vehicles import _normals_by_inversion
    u = np.array([0.0, np.nextafter(1.0, 0.0), 0.5])
    assert u[1] + 2.0 ** -54 == 1.0            # the case: the offset rounds it up to 1
    z = _normals_by_inversion(u)
    assert np.all(np.isfinite(z))
    assert z.tolist() == [ndtri(2.0 ** -54), ndtri(1.0 - 2.0 ** -53), ndtri(0.5)]
    assert 8.2 < z[1] < 8.4 and z[0] < -8.0
    assert u.tolist() == [0.0, np.nextafter(1.0, 0.0), 0.5]     # a new array
