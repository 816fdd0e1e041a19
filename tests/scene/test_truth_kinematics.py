"""The truth is kinematically consistent at ANY instant (issue 12 §2): velocity is the time
derivative of position and acceleration that of velocity (central differences at random
instants, not on the motion grid), no position or velocity jump at corners, and the wander's
configured σ at random instants."""
import math

import numpy as np
import pytest
from scipy import stats

from gmtiflow.scene.vehicles import RandomFleetSpec, VehicleSpec, VehiclesConfig, build_fleet

H = 1e-4          # s, central-difference step


def _fleet(roadmap, *specs, seed=1, duration_s=600.0, dt_s=1.0):
    return build_fleet(VehiclesConfig(vehicles=list(specs), random=RandomFleetSpec()), roadmap,
                       seed, duration_s, dt_s)


def _xyz(st, key="x_m"):
    names = {"x_m": ("x_m", "y_m", "z_m"), "v": ("vx_mps", "vy_mps", "vz_mps"),
             "a": ("ax_mps2", "ay_mps2", "az_mps2")}[key]
    return np.column_stack([st[c] for c in names])


@pytest.mark.parametrize("dt_s, corr_s", [(1.0, 5.0), (0.1, 5.0), (1.0, 0.0)])
def test_velocity_and_acceleration_are_derivatives_at_random_instants(corner_map, dt_s, corr_s):
    spec = VehicleSpec(name="w", start="a", end="b", cruise_speed_mps=8.0, speed_noise_mps=0.5,
                       speed_noise_corr_s=5.0, position_noise_m=[1.0, 0.5, 0.05],
                       position_noise_corr_s=corr_s)
    fl = _fleet(corner_map, spec, duration_s=60.0, dt_s=dt_s)
    t = np.random.default_rng(3).uniform(0.5, 40.0, 4000)
    st = fl.state_at(t, 0)
    ok = st["active"]
    lo, hi = fl.state_at(t - H, 0), fl.state_at(t + H, 0)
    ok &= lo["active"] & hi["active"]
    # the route's own speed profile has kinks where the piecewise-constant acceleration
    # switches (grid instants) and the polyline corner itself; skip ±2H around them
    grid = np.abs(t / dt_s - np.round(t / dt_s)) * dt_s < 2 * H
    corner = np.abs(st["route_s_m"] - 100.0) < 2 * H * 20.0
    ok &= ~grid & ~corner
    assert ok.sum() > 3000
    fd_v = (_xyz(hi) - _xyz(lo)) / (2 * H)
    err_v = np.abs(fd_v - _xyz(st, "v"))[ok]
    # central difference error ~ H^2/6 |x'''|: below 1e-5 m/s for these processes
    assert err_v.max() < 1e-4, err_v.max()
    fd_a = (_xyz(hi, "v") - _xyz(lo, "v")) / (2 * H)
    err_a = np.abs(fd_a - _xyz(st, "a"))[ok]
    # the wander frame's smoothstep has a jump in d2psi/ds2 at the blend edges (velocity is
    # continuous there, acceleration jumps): allow a few such rows, the rest to 1e-3 m/s^2
    assert np.quantile(err_a.max(axis=1), 0.99) < 1e-3


def test_no_jump_at_the_corner(corner_map):
    """Around the 90° corner the position moves continuously (old model: up to 2.3 m within
    20 ms) and the velocity stays the derivative across it."""
    spec = VehicleSpec(name="w", start="a", end="b", cruise_speed_mps=10.0,
                       position_noise_m=[1.0, 1.0, 0.0], position_noise_corr_s=5.0)
    fl = _fleet(corner_map, spec, duration_s=60.0, dt_s=0.5)
    t = np.arange(5.0, 15.0, 1e-3)
    st = fl.state_at(t, 0)
    p = _xyz(st)
    step = np.linalg.norm(np.diff(p, axis=0), axis=1)
    v = np.linalg.norm(_xyz(st, "v"), axis=1)
    assert np.any(np.abs(st["route_s_m"] - 100.0) < 1.0)      # the corner is in the window
    # every 1 ms step is at most the speed times 1 ms (plus rounding): no jump
    assert np.all(step <= 1e-3 * np.maximum(v[:-1], v[1:]) * 1.01 + 1e-9)
    dv = np.linalg.norm(np.diff(_xyz(st, "v"), axis=0), axis=1)
    # the route's own velocity turns 90° at the vertex (the paper's sharp corner: one jump of
    # ~sqrt(2) x speed); the wander adds no other jump
    assert np.sum(dv > 0.5) == 1


@pytest.mark.parametrize("corr_s", [0.0, 5.0])
def test_wander_sigma_holds_at_random_instants(long_road, corr_s):
    """The configured σ at random instants between motion steps (the old linear interpolation
    gave 0.71-0.82 σ between grid points with corr 0)."""
    sig = np.array([2.0, 0.5, 0.1])
    specs = [VehicleSpec(name=f"v{i}", start="a", end="b", cruise_speed_mps=10.0,
                         position_noise_m=sig.tolist(), position_noise_corr_s=corr_s)
             for i in range(40)]
    fl = _fleet(long_road, *specs, duration_s=3000.0, dt_s=1.0, seed=5)
    g = np.random.default_rng(1)
    # instants 60 s apart (>= 10 correlation times) plus a random fraction of a step
    t = np.arange(10.0, 2900.0, 60.0)[:, None] + g.uniform(0, 1, (1, 40))
    st = fl.state_at(t, np.arange(40)[None, :])
    d = np.stack([st["x_m"] - st["route_s_m"], st["y_m"], st["z_m"]], axis=-1).reshape(-1, 3)
    n = len(d)
    lo, hi = stats.chi2.ppf([0.0005, 0.9995], n)
    for col in range(3):
        q = np.sum((d[:, col] / sig[col]) ** 2)
        assert lo < q < hi, (col, q / n)


@pytest.mark.parametrize("corr_s", [0.0, 5.0])
def test_speed_noise_sigma_holds_at_random_instants(long_road, corr_s):
    """The speed noise's σ at random instants between motion steps (a straight line between
    the grid values gave σ√((1+ρ)/2) mid-step: 0.71 σ with correlation time 0), and its
    mean is the cruise speed."""
    sigma, cruise = 0.3, 10.0
    specs = [VehicleSpec(name=f"v{i}", start="a", end="b", cruise_speed_mps=cruise,
                         speed_noise_mps=sigma, speed_noise_corr_s=corr_s)
             for i in range(40)]
    fl = _fleet(long_road, *specs, duration_s=3000.0, dt_s=1.0, seed=7)
    g = np.random.default_rng(2)
    # instants 60 s apart (>= 12 correlation times), at a random fraction of a step
    t = np.arange(30.0, 2900.0, 60.0)[:, None] + g.uniform(0, 1, (1, 40))
    st = fl.state_at(t, np.arange(40)[None, :])
    z = ((st["speed_mps"] - cruise) / sigma).ravel()
    n = z.size
    lo, hi = stats.chi2.ppf([0.0005, 0.9995], n)
    assert lo < np.sum(z * z) < hi, np.mean(z * z)
    assert abs(z.mean()) < 3.5 / np.sqrt(n)
    # mid-step instants alone (where the straight line was lowest)
    tm = np.arange(30.0, 2900.0, 60.0)[:, None] + 0.5 + np.zeros((1, 40))
    zm = ((fl.state_at(tm, np.arange(40)[None, :])["speed_mps"] - cruise) / sigma).ravel()
    assert lo < np.sum(zm * zm) < hi, np.mean(zm * zm)


@pytest.mark.parametrize("corr_s", [0.0, 5.0])
def test_speed_noise_keeps_velocity_the_derivative(long_road, corr_s):
    """With the bridge, s(t) is still the integral of the speed and the speed that of the
    acceleration at random instants (central differences, off the grid instants)."""
    spec = VehicleSpec(name="w", start="a", end="b", cruise_speed_mps=10.0,
                       speed_noise_mps=0.5, speed_noise_corr_s=corr_s)
    fl = _fleet(long_road, spec, duration_s=200.0, dt_s=1.0, seed=3)
    assert fl.profiles.bridge.mean() > 0.5          # most steps are free cruise
    t = np.random.default_rng(4).uniform(2.0, 190.0, 3000)
    t = t[np.abs(t - np.round(t)) > 2 * H]
    st, lo, hi = fl.state_at(t, 0), fl.state_at(t - H, 0), fl.state_at(t + H, 0)
    ds = (hi["route_s_m"] - lo["route_s_m"]) / (2 * H)
    assert np.max(np.abs(ds - st["speed_mps"])) < 1e-5
    dv = (hi["speed_mps"] - lo["speed_mps"]) / (2 * H)
    acc = np.hypot(st["ax_mps2"], st["ay_mps2"]) * np.sign(dv)
    assert np.max(np.abs(dv - acc)) < 1e-3
    # the grid values are the kernel's: s at whole seconds is continuous from both sides
    tg = np.arange(5.0, 150.0)
    left, right = fl.state_at(tg - 1e-9, 0), fl.state_at(tg + 1e-9, 0)
    assert np.max(np.abs(right["route_s_m"] - left["route_s_m"])) < 1e-6


def test_time_at_inverts_a_bridged_profile(long_road):
    """Profiles.time_at (the instant a convoy member or a stop is reached) inverts s(t) inside
    free-cruise steps carrying the speed bridge."""
    spec = VehicleSpec(name="w", start="a", end="b", cruise_speed_mps=10.0,
                       speed_noise_mps=0.8, speed_noise_corr_s=0.0)
    fl = _fleet(long_road, spec, duration_s=200.0, dt_s=1.0, seed=3)
    prof = fl.profiles
    t = np.random.default_rng(5).uniform(2.0, 190.0, 200)
    s, *_ = prof.evaluate(t, 0)
    back = np.array([prof.time_at(0, x) for x in s])
    assert np.max(np.abs(back - t)) < 1e-9


def test_road_frames_of_all_routes_at_once_are_each_routes_own():
    # Fleet keeps the road frame (segment heading, corner blend and turn) of all routes in
    # flat arrays computed at once; they are wander's per-route ones bit for bit, also for
    # a single-segment route and routes with a vertical segment (no heading of its own)
    from gmtiflow.scene import wander
    from gmtiflow.scene.fleet import _road_frames
    from gmtiflow.scene.routes import off_road_route
    routes = [off_road_route(w) for w in (
        [[0, 0], [100, 0], [100, 300], [-50.5, 320.25, 3.0], [0, 2]],
        [[5, 5], [9, 9]],
        [[0, 0, 0], [0, 0, 10], [30, 40, 10], [30, 40, 12], [30, 90, 12], [30, 90, 15]],
        [[0, 0, 0], [0, 0, 10], [0, 0, 15]],
        [[1e5, -2e4], [1e5 + 3.0, -2e4 + 4.0], [1e5 + 3.0, -2e4 + 14.0]])]
    for order in (routes, routes[::-1], routes[:2], routes[2:3]):
        off = np.concatenate([[0], np.cumsum([len(r.s_m) for r in order])])
        psi, blend, turn = _road_frames(order, np.concatenate([r.xyz_m for r in order]),
                                        np.concatenate([r.s_m for r in order]), off)
        for r, a, b in zip(order, off[:-1], off[1:]):
            h = wander.segment_headings(r.xyz_m)
            bl, tu = wander.corner_blends(r.s_m, h)
            assert psi[a:b].tobytes() == np.append(h, h[-1]).tobytes()
            assert blend[a:b].tobytes() == bl.tobytes()
            assert turn[a:b].tobytes() == tu.tobytes()
    assert np.any(turn != 0) and np.any(blend != 0)


def _bridge_scalar(x0, x1, kappa, f):
    """The speed bridge (``speed_bridge.bridge``) for one float, with the math module: the form the
    one-pair inversion used, which ``speed_bridge.bridge_exact`` must match bit for bit."""
    g = f - 0.5
    m = 1.0 - 0.25 * kappa
    q = kappa * g * g + m
    rq = 1.0 / math.sqrt(q)
    a, b = 0.5 * (x0 + x1), x1 - x0
    lin = a + b * g
    rk = math.sqrt(kappa / m)

    def prim(gg):
        z = gg * rk
        ratio = 1.0 - z * z / 6.0 if abs(z) < 1e-4 else math.asinh(z) / z
        return a * gg / math.sqrt(m) * ratio

    integral = (prim(g) - prim(-0.5) + b * (g * g - 0.25) / (math.sqrt(q) + 1.0)
                - (x0 * f + 0.5 * b * f * f))
    return lin * (rq - 1.0), integral


def _time_at_scalar(prof, p, s_target):
    """The one-pair inversion as it was written before ``times_at`` (Python floats, math
    module): the oracle ``times_at`` must match bit for bit."""
    i0, n, dt = int(prof.step_offset[p]), int(prof.n_steps_p[p]), prof.dt_s
    col = prof.s_flat[i0 + p:i0 + p + n + 1]
    i = int(np.searchsorted(col, s_target, side="left"))
    if i == 0:
        return 0.0
    if i >= len(col):
        return math.inf
    k = i - 1
    g = i0 + p + k
    s0, v0 = float(col[k]), float(prof.v_flat[g])
    a, tk = float(prof.a_flat[i0 + k]), float(prof.tau_flat[i0 + k])
    if prof.bridge_flat[i0 + k]:
        x0, x1, kap = float(prof.noise_flat[g]), float(prof.noise_flat[g + 1]), \
            float(prof.kappa[p])
        lo, hi, u = 0.0, dt, 0.5 * dt
        for _ in range(60):
            d, integral = _bridge_scalar(x0, x1, kap, u / dt)
            err = s0 + v0 * u + 0.5 * a * u * u + integral * dt - s_target
            vu = v0 + a * u + d
            if abs(err) <= 1e-12 * max(1.0, abs(s_target)):
                break
            lo, hi = (u, hi) if err < 0 else (lo, u)
            nxt = u - err / vu if vu > 0 else 0.5 * (lo + hi)
            u = nxt if lo < nxt < hi else 0.5 * (lo + hi)
            if hi - lo < 1e-12 * dt:
                break
        return k * dt + u
    s_tau = s0 + v0 * tk + 0.5 * a * tk * tk
    x = s_target - s0
    if s_target <= s_tau:
        den = v0 + math.sqrt(max(v0 * v0 + 2.0 * a * x, 0.0))
        u = 0.0 if den <= 0 else 2.0 * x / den
    else:
        v1 = float(prof.v_flat[g + 1])
        u = tk + (s_target - s_tau) / v1 if v1 > 0 else dt
    return k * dt + min(max(u, 0.0), dt)


@pytest.mark.parametrize("dt_s", [1.0, 0.1])
def test_times_at_is_the_one_pair_inversion_for_every_pair(straight_map, dt_s):
    """Profiles.times_at (all vehicles' entry and arrival at once) gives each pair's scalar
    inversion bit for bit: in bridged free-cruise steps (Newton), in braking and waiting steps
    (closed form), before the start (0) and past the stored steps (inf)."""
    specs = [VehicleSpec(name=f"v{i}", start="a", end="b", cruise_speed_mps=8.0 + i,
                         speed_noise_mps=0.6, speed_noise_corr_s=float(i % 3),
                         random_stop_rate_per_s=0.02, mean_wait_s=5.0, stop_points=["m"],
                         start_time_s=3.0 * i) for i in range(6)]
    fl = _fleet(straight_map, *specs, duration_s=900.0, dt_s=dt_s, seed=7)
    prof = fl.profiles
    assert 0.2 < prof.bridge_flat.mean() < 0.99 and (prof.mode_flat == 2).any()
    g = np.random.default_rng(8)
    p = g.integers(0, len(specs), 3000)
    end = prof.s_flat[prof.step_offset[1:] + np.arange(len(specs))]
    s = g.uniform(-0.05, 1.05, p.size) * end[p]
    s[:40] = prof.s_flat[prof.step_offset[p[:40]] + p[:40] + g.integers(0, 50, 40)]  # grid
    s[40:60] = 5000.0                                                                # stop
    got = prof.times_at(p, s)
    want = np.array([_time_at_scalar(prof, int(a), float(b)) for a, b in zip(p, s)])
    assert got.tobytes() == want.tobytes()
    assert np.isinf(got).any() and (got == 0).any()
    assert prof.time_at(int(p[7]), float(s[7])) == want[7]


def test_state_at_in_blocks_is_state_at_at_once(monkeypatch):
    """Fleet.state_at evaluates long requests in cache-sized blocks; every column is the
    one-block result bit for bit (rows of active and inactive vehicles, any order)."""
    from gmtiflow.scene import fleet as fleet_mod
    from gmtiflow.scene.roadmap import RoadmapConfig, load_roadmap
    fl = build_fleet(VehiclesConfig(random=RandomFleetSpec(count=40, start_time_max_s=60.0)),
                     load_roadmap(RoadmapConfig()), 2, 300.0, 1.0)
    g = np.random.default_rng(9)
    t = g.uniform(-10.0, 320.0, 5000)
    v = g.integers(-1, 42, 5000)
    whole, table = fl.state_at(t, v), fl.truth_table(np.arange(0.0, 300.0, 0.5))
    monkeypatch.setattr(fleet_mod, "_BLOCK_ROWS", 333)
    blocks, table_b = fl.state_at(t, v), fl.truth_table(np.arange(0.0, 300.0, 0.5))
    assert whole.keys() == blocks.keys() and 0.2 < whole["active"].mean() < 0.9
    for k in whole:
        assert whole[k].dtype == blocks[k].dtype and whole[k].tobytes() == blocks[k].tobytes()
    assert table["x_m"].size > 3 * 333
    for k in table:
        assert table[k].dtype == table_b[k].dtype and table[k].tobytes() == table_b[k].tobytes()



@pytest.mark.parametrize("columns", [
    ("x_m", "y_m", "z_m", "vx_mps", "vy_mps", "vz_mps", "heading_rad", "invisible"),
    ("active", "x_m", "y_m", "z_m", "vx_mps", "vy_mps", "vz_mps"),
    ("ax_mps2", "mode", "route_s_m"), ("vy_mps", "edge_id", "time_s"), ("convoy_id",), ()])
@pytest.mark.parametrize("mixed", [True, False])
def test_state_at_of_some_columns_is_those_of_all(monkeypatch, columns, mixed):
    """Fleet.state_at(..., columns=...) gives the columns asked and ``active``, each bit for bit
    the one of the call for all columns: rows of active and inactive vehicles (``mixed``) or
    of active ones only (the path without gathers), in one block and in several."""
    from gmtiflow.scene import fleet as fleet_mod
    from gmtiflow.scene.roadmap import RoadmapConfig, load_roadmap
    fl = build_fleet(VehiclesConfig(random=RandomFleetSpec(
        count=40, start_time_max_s=60.0, position_noise_m=[1.0, 0.5, 0.05])),
        load_roadmap(RoadmapConfig()), 2, 300.0, 1.0)
    g = np.random.default_rng(9)
    t = g.uniform(-10.0, 320.0, 5000)
    v = g.integers(-1, 42, 5000)
    if not mixed:
        keep = fl.state_at(t, v)["active"]
        t, v = t[keep], v[keep]
    for block_rows in (fleet_mod._BLOCK_ROWS, 333):
        monkeypatch.setattr(fleet_mod, "_BLOCK_ROWS", block_rows)
        every, some = fl.state_at(t, v), fl.state_at(t, v, columns=columns)
        assert (0.2 < every["active"].mean() < 0.9) if mixed else every["active"].all()
        assert list(some) == [c for c in every if c in columns or c == "active"]
        for k in some:
            assert some[k].dtype == every[k].dtype and some[k].tobytes() == every[k].tobytes()
    with pytest.raises(ValueError, match="speed_mp"):
        fl.state_at(t, v, columns=("x_m", "speed_mp"))


def test_bridge_with_per_profile_constants_is_the_bridge():
    """Profiles.evaluate passes the κ-only parts of the speed bridge computed once per
    profile; the bridge (δ, dδ/df, its integral) is the one computed row by row, bit for bit,
    including κ = 0 (independent noise) and κ near 2."""
    from gmtiflow.scene.speed_bridge import bridge, bridge_constants
    g = np.random.default_rng(12)
    kappa_p = np.concatenate([[0.0, 2.0, 1e-9], g.uniform(0.0, 2.0, 20)])
    p = g.integers(0, kappa_p.size, 5000)
    x0, x1, f = g.normal(0, 0.5, 5000), g.normal(0, 0.5, 5000), g.uniform(0, 1, 5000)
    want = bridge(x0, x1, kappa_p[p], f)
    got = bridge(x0, x1, kappa_p[p], f, tuple(c[p] for c in bridge_constants(kappa_p)))
    for w, o in zip(want, got):
        assert np.isfinite(w).all() and w.tobytes() == o.tobytes()


@pytest.mark.parametrize("chunk", [None, 300])
def test_wander_without_accelerations_is_the_same_offset_and_rate(monkeypatch, chunk):
    """wander.evaluate(second=False) (the sensor reads no accelerations) and world_offset
    without n̈ give the offset and rate of the full calls bit for bit, no acceleration (in one
    block and in several)."""
    from gmtiflow.scene import wander
    if chunk is not None:
        monkeypatch.setattr(wander, "_CHUNK", chunk)
    g = np.random.default_rng(3)
    offset = np.array([0, 30, 75, 80])
    knots = g.standard_normal((80, 3))
    t0, h = np.array([0.0, 12.5, 40.0]), np.array([5.0, 1.0, 2.5])
    veh = g.integers(0, 3, 2000)
    t = t0[veh] + g.uniform(0.0, 30.0, 2000)
    full = wander.evaluate(t, veh, knots, offset, t0, h)
    part = wander.evaluate(t, veh, knots, offset, t0, h, second=False)
    assert part[2] is None
    for a, b in zip(full[:2], part[:2]):
        assert a.tobytes() == b.tobytes()
    psi, d1, d2 = (g.uniform(-1, 1, 2000) for _ in range(3))
    speed, accel = g.uniform(0, 20, 2000), g.uniform(-2, 2, 2000)
    w_full = wander.world_offset(*full, psi, d1, d2, speed, accel)
    w_part = wander.world_offset(*part, psi, d1, d2, speed, accel)
    assert w_part[2] is None
    for a, b in zip(w_full[:2], w_part[:2]):
        assert a.tobytes() == b.tobytes()


@pytest.mark.parametrize("dt_s, corr_s", [(0.5, 5.0), (1.0, 5.0), (0.1, 2.0)])
def test_speed_noise_never_takes_the_acceleration_beyond_the_limits(long_road, dt_s, corr_s):
    """Between motion steps the free-cruise speed bridge adds its own rate to the step's
    acceleration; steps that the limits leave free must stay within them at every instant,
    not only on average over the step (the bridge took a convoy truck of the default scene
    to 1.018 m/s² against max_accel_mps2 1.0).  Tight limits so that steps come close."""
    amax, dmax = 0.4, 0.5
    specs = [VehicleSpec(name=f"v{i}", start="a", end="b", cruise_speed_mps=12.0,
                         speed_noise_mps=0.6, speed_noise_corr_s=corr_s, max_accel_mps2=amax,
                         max_decel_mps2=dmax) for i in range(20)]
    fl = _fleet(long_road, *specs, duration_s=600.0, dt_s=dt_s, seed=11)
    assert fl.profiles.bridge.any()
    g = np.random.default_rng(5)
    n = 50_000
    t, vid = g.uniform(1.0, 590.0, n), g.integers(0, 20, n)
    off_grid = np.abs(t / dt_s - np.round(t / dt_s)) * dt_s > 2 * H
    t, vid = t[off_grid], vid[off_grid]
    lo, hi = fl.state_at(t - H, vid), fl.state_at(t + H, vid)
    acc = (hi["speed_mps"] - lo["speed_mps"]) / (2 * H)
    assert acc.max() <= amax * (1 + 1e-6) + 1e-6, acc.max()
    assert acc.min() >= -dmax * (1 + 1e-6) - 1e-6, acc.min()


@pytest.mark.parametrize("corr_s", [1e-300, 1e-6, 0.3])
def test_a_correlation_shorter_than_the_motion_step_is_the_steps(long_road, corr_s):
    """position_noise_corr_s below the motion step (down to 1e-300, which config validation
    accepts as > 0) gives the wander of corr 0: knots one step apart, the finest time the truth
    resolves. It used to space the knots corr_s apart: 1e-300 overflowed the knot count (numpy's
    'invalid value encountered in cast', then garbage), 1e-6 asked for 1e8 knots a vehicle."""
    import warnings

    def noise(c):
        spec = VehicleSpec(name="v", start="a", end="b", cruise_speed_mps=10.0,
                           position_noise_m=[2.0, 0.5, 0.1], position_noise_corr_s=c)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            fl = _fleet(long_road, spec, duration_s=100.0, dt_s=1.0, seed=5)
        st = fl.state_at(np.random.default_rng(2).uniform(0.0, 90.0, 500), 0)
        return st["y_m"][st["active"]]

    reference = noise(0.0)
    assert len(reference) > 100
    assert np.array_equal(noise(corr_s), reference)
