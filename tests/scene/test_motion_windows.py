"""The speed-profile kernel takes whole windows of steps at once (motion.simulate_profiles);
those windows must reproduce the step-by-step state machine bit for bit, in every regime:
free cruise with correlated and independent speed noise, speed limits and speed changes
(braking curves), random stops and waits, stop points, convoys, motion steps that are and are
not powers of two, trips that end inside a window and horizons shorter than a window."""
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as hst

from gmtiflow.scene import motion
from gmtiflow.scene.roadmap import RoadmapConfig, RoadSpec, load_roadmap
from gmtiflow.scene.vehicles import (ConvoySpec, RandomFleetSpec, SpeedChangeSpec,
                                     VehiclesConfig, VehicleSpec, build_fleet)

FIELDS = ("n_steps_p", "step_offset", "s_flat", "v_flat", "a_flat", "tau_flat", "mode_flat",
          "noise_flat", "bridge_flat", "kappa")


@pytest.fixture(scope="module")
def default_map():
    return load_roadmap(RoadmapConfig())


REAL = motion.simulate_profiles


def both(monkeypatch, cfg, roadmap, duration_s, dt_s, seed=3, windows=(True, False),
         window_steps=None):
    """The fleet's profiles with windows and step by step (the same draws); ``window_steps``
    the window length (None: the kernel's choice for the fleet's size)."""
    out = []
    for w in windows:
        monkeypatch.setattr(motion, "simulate_profiles",
                            lambda inp, dt, progress=False, w=w: REAL(
                                inp, dt, progress, windows=w, window_steps=window_steps))
        out.append(build_fleet(cfg, roadmap, seed, duration_s, dt_s).profiles)
    monkeypatch.setattr(motion, "simulate_profiles", REAL)
    return out


def assert_identical(a, b):
    for name in FIELDS:
        x, y = getattr(a, name), getattr(b, name)
        assert x.shape == y.shape, name
        assert x.tobytes() == y.tobytes(), name


RANDOM = dict(count=20, start_time_max_s=200.0, speed_noise_mps=1.0, speed_noise_corr_s=4.0,
              random_stop_rate_per_s=0.01, mean_wait_s=3.0, max_wait_s=20.0)


@pytest.mark.parametrize("dt_s, corr_s", [(1.0, 4.0), (0.1, 4.0), (0.3, 0.0), (1.0, 0.0)])
def test_windows_reproduce_the_step_loop_random_fleet(monkeypatch, default_map, dt_s, corr_s):
    cfg = VehiclesConfig(random=RandomFleetSpec(**{**RANDOM, "speed_noise_corr_s": corr_s}))
    a, b = both(monkeypatch, cfg, default_map, 300.0, dt_s)
    assert_identical(a, b)
    # the fleet did stop, wait and brake for lower limits, so every regime was exercised
    assert np.any(a.mode_flat == motion.MODE_STOPPED)
    assert np.any(a.mode_flat == motion.MODE_ACCEL)
    assert np.any(a.bridge_flat)


@pytest.mark.parametrize("noisy", [0, 3])
def test_windows_reproduce_the_step_loop_without_speed_noise(monkeypatch, default_map, noisy):
    """Profiles without speed noise (σ = 0) skip their normals, the braking cap where no
    noisy target reaches the slowest one and the free-cruise test: 80 of them (the windows'
    many-rows running sum), alone or with a few noisy ones in the same windows."""
    quiet = RandomFleetSpec(**{**RANDOM, "count": 80, "speed_noise_mps": 0.0,
                               "random_stop_rate_per_s": 0.005})
    specs = [VehicleSpec(name=f"n{i}", start="hw_x-4000", end="g_5_0", speed_noise_mps=0.5,
                         speed_noise_corr_s=3.0) for i in range(noisy)]
    a, b = both(monkeypatch, VehiclesConfig(vehicles=specs, random=quiet), default_map,
                300.0, 1.0)
    assert_identical(a, b)
    assert np.any(a.mode_flat == motion.MODE_STOPPED)
    assert np.any(a.bridge_flat) == (noisy > 0)


@pytest.mark.parametrize("dt_s", [1.0, 0.1, 0.7])
def test_windows_reproduce_the_step_loop_stop_points_convoys(monkeypatch, default_map, dt_s):
    specs = [
        VehicleSpec(name="s1", start="hw_x-4000", end="g_5_0", stop_points=["g_2_0", "g_4_0"],
                    speed_noise_mps=0.5, speed_noise_corr_s=3.0, random_stop_rate_per_s=0.02,
                    mean_wait_s=2.0),
        VehicleSpec(name="c1", start="g_0_0", end="g_6_2",
                    convoy=ConvoySpec(count=3, spacing_m=20.0),
                    speed_changes=[SpeedChangeSpec(at="g_3_0", cruise_speed_mps=6.0)],
                    speed_noise_mps=0.3),
        VehicleSpec(name="z", start="hw_x-1000", end="n_x4000", start_speed_mps=0.0,
                    cruise_speed_mps=25.0, obey_speed_limits=False),
    ]
    cfg = VehiclesConfig(vehicles=specs)
    a, b = both(monkeypatch, cfg, default_map, 300.0, dt_s)
    assert_identical(a, b)
    assert np.any(a.mode_flat == motion.MODE_STOPPED)


def test_window_length_follows_the_fleet_size():
    # few profiles: longer windows (the per-window cost spread over more steps), bounded
    assert motion.window_length(1) == motion.MAX_WINDOW_STEPS
    assert motion.window_length(10) == 1024
    assert motion.window_length(100) == 128
    assert motion.window_length(10_000) == motion.NOISE_BLOCK_STEPS
    # no longer than the longest trip's steps (a window past them is wasted work)
    assert motion.window_length(10, 9001) == 1024
    assert motion.window_length(10, 601) == 512
    assert motion.window_length(10, 300) == 256
    assert motion.window_length(10, 50) == motion.NOISE_BLOCK_STEPS
    for n in (1, 3, 10, 50, 129, 10_000):
        w = motion.window_length(n)
        assert w >= motion.NOISE_BLOCK_STEPS and w & (w - 1) == 0
        assert w == motion.NOISE_BLOCK_STEPS or n * w <= motion.WINDOW_CELLS


@pytest.mark.parametrize("window_steps, dt_s", [(2, 1.0), (37, 1.0), (128, 1.0), (1024, 1.0),
                                                 (3, 0.1), (16, 0.1)])
def test_window_length_does_not_change_the_profiles(monkeypatch, default_map, window_steps,
                                                     dt_s):
    # the windows' length (and the noise blocks') is the kernel's choice: the profiles are
    # those of the step loop whatever it is (a trip longer than a window, stops, waits, and
    # brakings and waits longer than the noise buffer's two blocks at dt = 0.1 s)
    cfg = VehiclesConfig(random=RandomFleetSpec(**{**RANDOM, "count": 6,
                                                   "random_stop_rate_per_s": 0.03}))
    a, = both(monkeypatch, cfg, default_map, 300.0, dt_s, windows=(False,))
    b, = both(monkeypatch, cfg, default_map, 300.0, dt_s, windows=(True,),
              window_steps=window_steps)
    c, = both(monkeypatch, cfg, default_map, 300.0, dt_s, windows=(False,),
              window_steps=window_steps)
    assert_identical(a, b)
    assert_identical(a, c)
    assert np.any(a.mode_flat == motion.MODE_STOPPED)
    assert a.n_steps_p.max() > 128


def test_windows_reproduce_the_step_loop_short_horizon(monkeypatch, default_map):
    cfg = VehiclesConfig(random=RandomFleetSpec(**{**RANDOM, "count": 10}))
    a, b = both(monkeypatch, cfg, default_map, 37.0, 0.5)       # 75 steps: within a window
    assert_identical(a, b)


@settings(max_examples=25, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(dt=hst.sampled_from([0.1, 0.5, 1.0, 2.0, 3.3]), cruise=hst.floats(1.0, 40.0),
       sigma=hst.floats(0.0, 3.0), corr=hst.sampled_from([0.0, 2.0, 8.0]),
       amax=hst.floats(0.3, 5.0), dmax=hst.floats(0.5, 8.0), limit=hst.floats(3.0, 30.0),
       v0=hst.sampled_from([None, 0.0, 35.0]), seed=hst.integers(0, 2**31),
       rate=hst.sampled_from([0.0, 0.05, 0.3]))
def test_windows_reproduce_the_step_loop_any_parameters(monkeypatch, make_map, dt, cruise,
                                                         sigma, corr, amax, dmax, limit, v0,
                                                         seed, rate):
    rm = make_map({"a": [0, 0, 0], "b": [400, 0, 0], "c": [400, 700, 5], "d": [1500, 700, 5]},
                  [RoadSpec("a", "b"), RoadSpec("b", "c", speed_limit_mps=limit),
                   RoadSpec("c", "d")])
    spec = VehicleSpec(name="h", start="a", end="d", cruise_speed_mps=cruise,
                       start_speed_mps=v0, speed_noise_mps=sigma, speed_noise_corr_s=corr,
                       max_accel_mps2=amax, max_decel_mps2=dmax, stop_points=["c"],
                       mean_wait_s=3.0, max_wait_s=6.0, random_stop_rate_per_s=rate)
    a, b = both(monkeypatch, VehiclesConfig(vehicles=[spec]), rm, 300.0, dt, seed=seed)
    assert_identical(a, b)


@pytest.mark.parametrize("guess_above", [-1.0, 1.0 / 3.0, 2.0])
@pytest.mark.parametrize("dt_s", [1.0, 0.2])
def test_the_windows_first_guess_does_not_change_the_profiles(monkeypatch, default_map,
                                                              guess_above, dt_s):
    """Windows start from a guess of the positions: constant speed, or (NOISE_GUESS_ABOVE:
    from the start, once second passes are frequent, never) the speed noise's; the profiles
    are the step loop's whichever guess is taken."""
    monkeypatch.setattr(motion, "NOISE_GUESS_ABOVE", guess_above)
    cfg = VehiclesConfig(random=RandomFleetSpec(**{**RANDOM, "count": 60,
                                                   "speed_noise_mps": 0.4}))
    a, b = both(monkeypatch, cfg, default_map, 400.0, dt_s)
    assert_identical(a, b)
    assert np.any(a.bridge_flat) and np.any(a.mode_flat == motion.MODE_STOPPED)
