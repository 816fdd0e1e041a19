"""Every benchmark scenario's challenge occurs, in every seed the benchmark uses.

Each scenario runs end to end (truth, sensor; no tracker, no exports) and its check in
:mod:`gmtiflow.bench.challenges` reads the run file's tables.
"""
import pytest

from gmtiflow import pipeline
from gmtiflow.bench import challenges, scenarios
from gmtiflow.compose import compose

SEEDS = (1, 2, 3)
FAST = ["export=none", "report=none", "tracker=none", "metrics.enabled=false", "progress=false",
        "cache.enabled=false"]


def run_scenario(tmp_path, name, seed, *extra):
    cfg = compose([f"experiment={scenarios.override(name)}", f"seed={seed}", *FAST, *extra])
    return pipeline.run(cfg, tmp_path / f"{name}-{seed}")


def test_every_shipped_scenario_is_in_the_suite_and_has_a_check():
    assert sorted(scenarios.SCENARIOS) == scenarios.shipped()
    assert set(challenges.CHECKS) == set(scenarios.SCENARIOS)


@pytest.mark.parametrize("name", scenarios.SCENARIOS)
@pytest.mark.slow
def test_challenge_occurs_in_every_seed(tmp_path, name):
    for seed in SEEDS:
        result = challenges.check(name, run_scenario(tmp_path, name, seed))
        assert result.occurred, f"{name} seed {seed}: {result.summary}"


def test_scene_picture_is_drawn_from_the_run(tmp_path):
    import matplotlib.image as mpimg
    import numpy as np
    from gmtiflow.bench.figures import save_scene_png
    run = run_scenario(tmp_path, "tunnel", 1, "scene.duration_s=60")
    png = save_scene_png(run, "tunnel", tmp_path / "tunnel.png", dpi=40)
    img = mpimg.imread(png)
    assert img.shape[0] > 200 and float(np.std(img[..., :3])) > 0.05


def _tables(dwells, looks):
    t = challenges.RunTables("unused.h5")
    t._cache.update({"dwells": dwells, "looks": looks})
    return t


def test_two_sensors_check_counts_only_blind_looks_another_sensor_bridges():
    import numpy as np
    # two sensors, 5 s revisits, one dwell each per revisit, at t = 0, 5, ... and 1, 6, ...
    times = np.arange(0.0, 40.0, 5.0)
    dwells = {"dwell_id": np.arange(16), "sensor_id": np.tile([0, 1], 8),
              "dwell_index": np.zeros(16, np.int64),
              "time_s": np.ravel(np.column_stack([times, times + 1.0]))}
    blind, det, pd_miss = 4, 0, 5
    # vehicle 7: blind for sensor 0 at dwells 0, 2 (t = 0, 5), seen by sensor 1 at t = 1, 6;
    # blind for sensor 1 at dwell 9 (t = 21): sensor 0 only missed it (P_D) then
    looks = {"dwell_id": np.array([0, 1, 2, 3, 8, 9]), "vehicle_id": np.full(6, 7),
             "time_s": np.array([0.0, 1.0, 5.0, 6.0, 20.0, 21.0]),
             "outcome": np.array([blind, det, blind, det, pd_miss, blind], np.uint8)}
    result = challenges.check_two_sensors(_tables(dwells, looks))
    assert not result.occurred and "0: 2, 1: 0" in result.summary
    looks["outcome"][4] = det                         # now sensor 0 sees it 1 s before
    # and once more: sensor 0 detects at t = 25, sensor 1 is blind at t = 26
    for k, v in (("dwell_id", [10, 11]), ("vehicle_id", [7, 7]), ("time_s", [25.0, 26.0]),
                 ("outcome", [det, blind])):
        looks[k] = np.append(looks[k], np.asarray(v, looks[k].dtype))
    result = challenges.check_two_sensors(_tables(dwells, looks))
    assert result.occurred and result.numbers["min_bridged_blind_looks"] == 2
