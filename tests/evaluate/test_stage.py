"""The whole evaluation chain on a synthetic scene: baseline tracker -> evaluate."""
import numpy as np
import pytest

from gmtiflow.evaluate.config import MetricsConfig, TrackerConfig
from gmtiflow.evaluate.stage import SUMMARY_NAMES, evaluate, summary_value
from gmtiflow.evaluate.synthetic import PLATFORM_START, PLATFORM_VEL, straight_scene
from gmtiflow.evaluate.tracker import track


def platform_table(t_end):
    t = np.array([0.0, t_end])
    pos = PLATFORM_START[None, :] + t[:, None] * PLATFORM_VEL[None, :]
    return {"time_s": t, "x_m": pos[:, 0], "y_m": pos[:, 1], "z_m": pos[:, 2],
            "vx_mps": np.full(2, PLATFORM_VEL[0]), "vy_mps": np.full(2, PLATFORM_VEL[1]),
            "vz_mps": np.full(2, PLATFORM_VEL[2])}


@pytest.fixture(scope="module")
def scored():
    # vehicle 1 stops for 30 s (lost by a baseline deleting after 5 misses of 2 s revisits);
    # vehicle 2 is Doppler blind for 4 revisits (kept)
    scene = straight_scene(n_vehicles=3, n_revisits=80, spacing_m=1000.0, seed=7,
                           stops={1: (60.0, 90.0)}, blind={2: [(40.0, 46.0)]})
    tracks = track(TrackerConfig(), scene["detections"], scene["dwells"])
    out = evaluate(MetricsConfig(), scene["truth"], tracks, scene["looks"], scene["vehicles"],
                   platform_table(160.0))
    return scene, tracks, out


def test_summary_has_every_name_once(scored):
    _, _, out = scored
    assert tuple(out["metrics"]["name"]) == SUMMARY_NAMES
    assert out["metrics"]["value"].dtype == np.float64


def test_baseline_scores_as_expected(scored):
    _, _, out = scored
    assert summary_value(out, "position_rmse_m") < 10.0 * np.sqrt(2.0)
    # Range rate: typically better than one plot (σ 0.5 m/s); the RMS is dominated by the
    # rows a track coasts at speed over the stopped vehicle before it is deleted.
    rr = out["metrics/track_errors"]["range_rate_error_mps"]
    assert np.median(np.abs(rr)) < 0.5
    assert summary_value(out, "range_rate_rmse_mps") < 3.0
    assert summary_value(out, "coverage_mean") > 0.8
    ev = out["metrics/events"]
    stop = (ev["kind"] == "stop") & (ev["vehicle_id"] == 1)
    assert stop.sum() == 1 and not ev["id_kept"][stop][0] and ev["reacquired"][stop][0]
    # a new track must be confirmed (3 of 5 at 2 s): at least 2 revisits after it moves again
    assert ev["reacq_delay_s"][stop][0] >= 4.0
    gap = (ev["kind"] == "doppler_blind") & (ev["vehicle_id"] == 2)
    assert gap.sum() == 1 and ev["id_kept"][gap][0]
    assert summary_value(out, "identity_switches") == 1          # the stop's replacement


def test_tables_have_equal_length_columns(scored):
    from gmtiflow.tables import n_rows
    _, _, out = scored
    for name, table in out.items():
        n_rows(table)


def test_disabled_metrics_give_nothing():
    scene = straight_scene(n_revisits=5)
    assert evaluate(MetricsConfig(enabled=False), scene["truth"], {}) == {}


def test_tables_round_trip_through_the_run_file(scored, tmp_path):
    from gmtiflow.store import RunWriter, read_table
    _, tracks, out = scored
    path = tmp_path / "run.h5"
    with RunWriter(path, seed=1) as writer:
        writer.write_table("tracks", tracks)
        for name, table in out.items():
            writer.write_table(name, table)
        writer.commit()
    back = read_table(path, "metrics")
    assert list(back["name"]) == list(out["metrics"]["name"])
    np.testing.assert_array_equal(back["value"], out["metrics"]["value"])
    ev = read_table(path, "metrics/events")
    assert list(ev["kind"]) == list(out["metrics/events"]["kind"])
    tr = read_table(path, "tracks")
    np.testing.assert_array_equal(tr["x_m"], tracks["x_m"])
