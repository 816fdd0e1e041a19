"""Fair scores: perfect tracks score perfectly (no end-of-scene penalty), MDV-gated truth."""
import dataclasses

import numpy as np
import pytest

from gmtiflow.evaluate.align import interpolate_truth
from gmtiflow.evaluate.config import MetricsConfig
from gmtiflow.evaluate.stage import evaluate, summary_value
from gmtiflow.evaluate.synthetic import gmti_scene, straight_scene


def perfect_tracks(scene, times, id_offset=100):
    """Every vehicle's exact state at each of ``times`` inside its truth span."""
    vids = np.unique(scene["truth"]["vehicle_id"])
    qv = np.repeat(vids, len(times))
    qt = np.tile(times, len(vids))
    it = interpolate_truth(scene["truth"], qv, qt)
    ok = it["valid"]
    return {"track_id": qv[ok] + id_offset, "time_s": qt[ok], "x_m": it["x_m"][ok],
            "y_m": it["y_m"][ok], "vx_mps": it["vx_mps"][ok], "vy_mps": it["vy_mps"][ok]}


@pytest.fixture(scope="module")
def scene():
    # vehicle 0 is Doppler blind for 20 s (a blind-gap event a perfect tracker holds through)
    return gmti_scene(n_vehicles=5, n_revisits=40, seed=3, blind={0: [(60.0, 80.0)]})


def test_perfect_tracks_score_perfectly_up_to_the_last_dwell(scene):
    # the radar stops a revisit before the truth ends: the last 5 s cannot be tracked
    dwells = scene["dwells"]
    dwells = {k: v[dwells["revisit_id"] < dwells["revisit_id"].max()] for k, v in dwells.items()}
    last_dwell = float(dwells["time_s"].max())
    assert scene["truth"]["time_s"].max() > last_dwell + 4.0
    tracks = perfect_tracks(scene, np.unique(dwells["time_s"]))
    out = evaluate(MetricsConfig(), scene["truth"], tracks, scene["looks"], until_s=last_dwell)
    assert summary_value(out, "ospa_mean_m") == pytest.approx(0.0, abs=1e-6)
    assert summary_value(out, "gospa_mean_m") == pytest.approx(0.0, abs=1e-6)
    assert summary_value(out, "coverage_mean") == 1.0
    assert summary_value(out, "identity_switches") == 0
    assert summary_value(out, "fragmentations") == 0
    assert summary_value(out, "doppler_blind_events_held") >= 1
    assert summary_value(out, "doppler_blind_id_kept_fraction") == 1.0
    assert summary_value(out, "mota") == 1.0 and summary_value(out, "idf1") == 1.0
    assert out["metrics/ospa"]["time_s"].max() <= last_dwell


def test_tracks_reported_only_at_revisit_ends_are_not_cut_at_the_end(scene):
    dwells = scene["dwells"]
    ends = np.unique(dwells["time_s"][dwells["last_dwell"]])
    out = evaluate(MetricsConfig(), scene["truth"], perfect_tracks(scene, ends),
                   until_s=float(dwells["time_s"].max()))
    # the only cost left: the instants before the first revisit ended (no report yet)
    first = out["metrics/ospa"]["time_s"] >= ends[0]
    assert np.all(out["metrics/ospa"]["ospa_m"][first] < 1e-6)
    assert summary_value(out, "identity_switches") == 0


def test_tracks_that_really_end_early_are_still_missed(scene):
    dwells = scene["dwells"]
    last_dwell = float(dwells["time_s"].max())
    times = np.unique(dwells["time_s"])
    tracks = perfect_tracks(scene, times[times < last_dwell - 30.0])
    out = evaluate(MetricsConfig(), scene["truth"], tracks, until_s=last_dwell)
    ospa = out["metrics/ospa"]
    late = ospa["time_s"] > last_dwell - 30.0 + MetricsConfig().max_extrapolation_s
    assert late.sum() > 10 and np.all(ospa["ospa_m"][late] == MetricsConfig().cutoff_m)


def test_mdv_gated_truth_is_neither_missed_nor_false_while_stopped():
    # vehicle 1 stops for 30 s: undetectable; a tracker coasting past it would be false, one
    # holding it still is not missed when gated
    scene = straight_scene(n_vehicles=2, n_revisits=60, spacing_m=2000.0, seed=1,
                           stops={1: (40.0, 70.0)})
    times = np.arange(0.0, 119.0, 1.0)
    tracks = perfect_tracks(scene, times)
    moving = np.hypot(tracks["vx_mps"], tracks["vy_mps"]) > 0.5
    gone = {k: v[moving] for k, v in tracks.items()}          # no track while stopped
    cfg = MetricsConfig()
    plain = evaluate(cfg, scene["truth"], gone, until_s=118.0)
    gated_cfg = dataclasses.replace(cfg, min_truth_speed_mps=2.0)
    gated = evaluate(gated_cfg, scene["truth"], gone, until_s=118.0)
    held = evaluate(gated_cfg, scene["truth"], tracks, until_s=118.0)
    assert summary_value(plain, "gospa_missed_mean") > 0
    assert summary_value(gated, "gospa_missed_mean") == 0.0
    assert summary_value(held, "gospa_false_mean") == 0.0         # a held stopped vehicle
    assert summary_value(gated, "ospa_mean_m") < 1e-6
    with pytest.raises(AssertionError):
        assert summary_value(plain, "ospa_mean_m") < 1e-6


@pytest.mark.parametrize("report_every_s", [1.0, 0.5])
def test_perfect_tracks_of_a_vehicle_that_leaves_the_road_score_perfectly(report_every_s):
    """/truth drops a vehicle when it arrives; its perfect track, reported up to its last truth
    instant, used to be held track_end_hold_s (1 s) *including* the next 1 s truth instant, where
    it was a false track (one OSPA step at c, a CLEAR-MOT false positive) though no tracker
    could have done better.  The hold now ends before that instant."""
    from tests.evaluate.helpers import line, truth_table
    truth = truth_table({0: line(np.arange(0.0, 61.0), 0.0, 0.0, 10.0, 0.0),
                         1: line(np.arange(0.0, 31.0), 5000.0, 0.0, -10.0, 0.0)})
    times = np.arange(0.0, 60.0 + 1e-9, report_every_s)
    it0 = interpolate_truth(truth, np.zeros(len(times), np.int64), times)
    it1 = interpolate_truth(truth, np.ones(len(times), np.int64), times)
    ok = it1["valid"]
    tracks = {"track_id": np.r_[np.full(len(times), 5), np.full(ok.sum(), 6)],
              "time_s": np.r_[times, times[ok]], "x_m": np.r_[it0["x_m"], it1["x_m"][ok]],
              "y_m": np.r_[it0["y_m"], it1["y_m"][ok]],
              "vx_mps": np.r_[it0["vx_mps"], it1["vx_mps"][ok]],
              "vy_mps": np.r_[it0["vy_mps"], it1["vy_mps"][ok]]}
    out = evaluate(MetricsConfig(), truth, tracks, since_s=0.0, until_s=60.0)
    assert summary_value(out, "ospa_mean_m") == 0.0
    assert summary_value(out, "mota") == 1.0 and summary_value(out, "idf1") == 1.0
