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
