"""Truth interpolation, tracks on the evaluation grid, and the config files."""
from pathlib import Path

import numpy as np
import pytest
from omegaconf import OmegaConf

from gmtiflow.evaluate.align import interpolate_truth, tracks_at_grid, truth_at_grid
from gmtiflow.evaluate.config import MetricsConfig, TrackerConfig

from .helpers import line, truth_table

CONF = Path(__file__).resolve().parents[2] / "conf" / "tracker"


def test_truth_is_interpolated_linearly_per_vehicle():
    truth = truth_table({3: line([0.0, 1.0, 2.0], 0, 0, 10, 0), 5: line([1.0, 2.0], 0, 50, 0, 2)})
    it = interpolate_truth(truth, np.array([3, 3, 5, 5, 9]), np.array([0.25, 2.0, 0.5, 1.5, 1.0]))
    assert list(it["valid"]) == [True, True, False, True, False]
    assert it["x_m"][0] == pytest.approx(2.5) and it["x_m"][1] == pytest.approx(20.0)
    assert it["y_m"][3] == pytest.approx(53.0)
    assert it["heading_rad"][0] == pytest.approx(np.pi / 2)


def test_tracks_are_extrapolated_to_the_grid_within_the_limit():
    tracks = {"track_id": np.array([1, 1]), "time_s": np.array([0.5, 1.5]),
              "x_m": np.array([0.0, 10.0]), "y_m": np.zeros(2), "vx_mps": np.full(2, 10.0),
              "vy_mps": np.zeros(2)}
    at = tracks_at_grid(tracks, np.arange(6.0), max_extrapolation_s=2.0)
    assert list(at["step"]) == [1, 2, 3]                 # absent before 0.5 and after 3.5
    assert at["x_m"] == pytest.approx([5.0, 15.0, 25.0])


def test_truth_on_a_coarser_grid():
    truth = truth_table({0: line(np.arange(5.0), 0, 0, 1, 0)})
    at = truth_at_grid(truth, np.array([0.0, 1.5, 3.0]))
    assert at["x_m"] == pytest.approx([0.0, 1.5, 3.0])


@pytest.mark.parametrize("name, enabled", [("nn_kalman", True), ("none", False)])
def test_tracker_yaml_composes_with_the_schema(name, enabled):
    merged = OmegaConf.merge(OmegaConf.structured(TrackerConfig),
                             OmegaConf.load(CONF / f"{name}.yaml"))
    cfg = OmegaConf.to_object(merged)
    assert cfg.enabled is enabled and cfg.problems() == []


def test_nn_kalman_yaml_holds_the_schema_defaults():
    assert OmegaConf.to_object(OmegaConf.merge(OmegaConf.structured(TrackerConfig),
                                               OmegaConf.load(CONF / "nn_kalman.yaml"))) \
        == TrackerConfig()


def test_metrics_config_problems():
    assert MetricsConfig().problems() == []
    keys = {p.key for p in MetricsConfig(gospa_alpha=1.0, order_p=0.5, cutoff_m=0).problems()}
    assert keys == {"gospa_alpha", "order_p", "cutoff_m"}


def test_a_track_ends_with_its_last_row():
    tracks = {"track_id": np.array([1, 1]), "time_s": np.array([0.5, 1.5]),
              "x_m": np.array([0.0, 10.0]), "y_m": np.zeros(2)}
    at = tracks_at_grid(tracks, np.arange(6.0), max_extrapolation_s=2.0, end_hold_s=1.0)
    assert list(at["step"]) == [1, 2]


def test_tracks_at_grid_rows_sorted_by_step_then_track():
    from gmtiflow.evaluate.align import tracks_at_grid
    rng = np.random.default_rng(6)
    ids = rng.integers(-50, 10 ** 9, 30)
    tid = np.repeat(ids, 12)
    tt = np.tile(np.arange(12.0), 30) + rng.uniform(0, 0.5, 360)
    o = rng.permutation(360)
    out = tracks_at_grid({"track_id": tid[o], "time_s": tt[o], "x_m": tt[o], "y_m": tt[o]},
                         np.arange(14.0), 2.0)
    assert len(out["step"]) > 300
    assert np.array_equal(np.lexsort((out["track_id"], out["step"])), np.arange(len(out["step"])))
