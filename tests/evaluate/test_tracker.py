"""Baseline tracker: accuracy against the Kalman filter's own steady state, identity through a
short blind gap, determinism, clutter, and the revisit (no footprint) mode."""
import dataclasses

import numpy as np
import pytest
import scipy.linalg as sl

from gmtiflow.evaluate.align import interpolate_truth
from gmtiflow.evaluate.config import MetricsConfig, TrackerConfig
from gmtiflow.evaluate.stage import evaluate, summary_value
from gmtiflow.evaluate.synthetic import gmti_scene, straight_scene
from gmtiflow.evaluate.tracker import TRACK_COLUMNS, track

SIGMA_M = 10.0
REVISIT_S = 2.0
ACCEL = 0.5


def expected_position_rmse(sigma_m, revisit_s, accel_sigma, model="cwna"):
    """Steady-state 2-D RMS position error of the CV filter on a truly constant-velocity target.

    The filter's gain comes from the Riccati equation with its process noise Q (DARE); the actual
    error then follows e⁺ = (I−KH)F e⁺ + K v with no process noise, whose steady covariance Σ
    solves the Lyapunov equation Σ = A Σ Aᵀ + K R Kᵀ, A = (I−KH)F.  Per axis, 2 axes alike.
    """
    T = revisit_s
    F = np.array([[1.0, T], [0.0, 1.0]])
    if model == "dwna":
        Q = accel_sigma ** 2 * np.array([[T ** 4 / 4, T ** 3 / 2], [T ** 3 / 2, T ** 2]])
    else:
        Q = accel_sigma ** 2 * np.array([[T ** 3 / 3, T ** 2 / 2], [T ** 2 / 2, T]])
    H = np.array([[1.0, 0.0]])
    R = np.array([[sigma_m ** 2]])
    P = sl.solve_discrete_are(F.T, H.T, Q, R)
    K = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
    A = (np.eye(2) - K @ H) @ F
    Sigma = sl.solve_discrete_lyapunov(A, K @ R @ K.T)
    return float(np.sqrt(2.0 * Sigma[0, 0])), float(np.max(np.abs(np.linalg.eigvals(A))))


def errors_by_vehicle(scene, tracks, t_from):
    """Per-vehicle mean squared position error of the confirmed track nearest each vehicle."""
    conf = tracks["confirmed"] & (tracks["time_s"] >= t_from)
    t = tracks["time_s"][conf]
    x, y = tracks["x_m"][conf], tracks["y_m"][conf]
    out = []
    for v in np.unique(scene["truth"]["vehicle_id"]):
        tv = interpolate_truth(scene["truth"], np.full(len(t), v), t)
        d2 = (x - tv["x_m"]) ** 2 + (y - tv["y_m"]) ** 2
        out.append(d2[d2 < 100.0 ** 2].mean())
    return np.asarray(out)


@pytest.mark.parametrize("model", ["cwna", "dwna"])
def test_rmse_matches_the_steady_state_filter_and_beats_the_measurement(model):
    cfg = TrackerConfig(accel_sigma_mps2=ACCEL, use_range_rate=False, process_noise=model)
    scene = straight_scene(n_vehicles=30, n_revisits=100, revisit_s=REVISIT_S, sigma_m=SIGMA_M,
                           spacing_m=1000.0, seed=3)
    tracks = track(cfg, scene["detections"], scene["dwells"], seed=0)
    expected, pole = expected_position_rmse(SIGMA_M, REVISIT_S, ACCEL, model)
    assert expected < SIGMA_M            # the bound the tracker has to meet: better than one plot
    settle = int(np.ceil(np.log(1e-3) / np.log(pole)))          # transient down to 1e-3
    mse = errors_by_vehicle(scene, tracks, t_from=(settle + 3) * REVISIT_S)
    rmse = np.sqrt(mse.mean())
    # Vehicles are independent: the spread of their mean squared errors gives the tolerance.
    se = mse.std(ddof=1) / np.sqrt(len(mse))
    tol = 4.0 * se / (2.0 * expected ** 2) * expected       # delta-method on sqrt
    assert abs(rmse - expected) < tol + 0.02 * expected, (rmse, expected, tol)
    assert rmse < SIGMA_M


def test_range_rate_helps_or_does_no_harm():
    base = TrackerConfig(accel_sigma_mps2=ACCEL, use_range_rate=False)
    scene = straight_scene(n_vehicles=20, n_revisits=60, sigma_m=SIGMA_M, spacing_m=1000.0,
                           seed=5)
    pos_only = track(base, scene["detections"], scene["dwells"])
    with_rr = track(dataclasses.replace(base, use_range_rate=True), scene["detections"],
                    scene["dwells"])
    e0 = errors_by_vehicle(scene, pos_only, 40.0).mean()
    e1 = errors_by_vehicle(scene, with_rr, 40.0).mean()
    assert e1 < 1.05 * e0


def test_keeps_the_id_through_a_short_blind_gap_and_loses_it_through_a_long_one():
    cfg = TrackerConfig()                       # delete after 5 covered misses
    short = straight_scene(n_revisits=50, blind={0: [(40.0, 46.0)]}, seed=1)   # 4 revisits
    tr = track(cfg, short["detections"], short["dwells"])
    ids = np.unique(tr["track_id"][tr["confirmed"]])
    assert len(ids) == 1
    times = tr["time_s"][tr["track_id"] == ids[0]]
    assert times.min() <= 10.0 and times.max() == 98.0
    assert {42.0, 44.0, 46.0} <= set(times)            # coasted rows through the gap

    long = straight_scene(n_revisits=50, blind={0: [(40.0, 60.0)]}, seed=1)   # 11 revisits
    tr = track(cfg, long["detections"], long["dwells"])
    assert len(np.unique(tr["track_id"][tr["confirmed"]])) == 2


def test_deterministic_and_complete_columns():
    scene = straight_scene(n_vehicles=4, n_revisits=30, clutter_per_dwell=3.0, seed=2)
    a = track(TrackerConfig(), scene["detections"], scene["dwells"], seed=1)
    b = track(TrackerConfig(), scene["detections"], scene["dwells"], seed=2)
    assert tuple(a) == TRACK_COLUMNS
    for k in a:
        np.testing.assert_array_equal(a[k], b[k])
    assert a["track_id"].dtype == np.int64 and a["confirmed"].dtype == bool


def test_clutter_does_not_break_the_vehicles_tracks():
    scene = straight_scene(n_vehicles=5, n_revisits=60, clutter_per_dwell=5.0, seed=4)
    tr = track(TrackerConfig(), scene["detections"], scene["dwells"])
    mse = errors_by_vehicle(scene, tr, 30.0)
    assert np.all(np.sqrt(mse) < SIGMA_M * np.sqrt(2.0))
    # confirmed tracks far from every vehicle (false tracks) stay rare
    conf = tr["confirmed"]
    ids = np.unique(tr["track_id"][conf])
    assert len(ids) <= 5 + 3


def test_revisit_mode_without_footprint_columns():
    scene = straight_scene(n_revisits=50, blind={0: [(40.0, 46.0)]}, seed=1)
    dwells = {k: v for k, v in scene["dwells"].items()
              if k not in ("beam_az_rad", "angle_half_extent_rad")}
    tr = track(TrackerConfig(), scene["detections"], dwells)
    ids = np.unique(tr["track_id"][tr["confirmed"]])
    assert len(ids) == 1
    assert {42.0, 44.0, 46.0} <= set(tr["time_s"][tr["track_id"] == ids[0]])


def test_outside_the_footprint_is_not_a_miss():
    # The vehicle is hidden for 11 revisits, but the beam points away meanwhile: no misses.
    scene = straight_scene(n_revisits=50, blind={0: [(40.0, 60.0)]}, seed=1)
    dwells = dict(scene["dwells"])
    away = (dwells["time_s"] >= 40.0) & (dwells["time_s"] <= 60.0)
    dwells["beam_az_rad"] = np.where(away, dwells["beam_az_rad"] + np.pi, dwells["beam_az_rad"])
    tr = track(TrackerConfig(), scene["detections"], dwells)
    assert len(np.unique(tr["track_id"][tr["confirmed"]])) == 1


def test_disabled_gives_an_empty_table():
    scene = straight_scene(n_revisits=5)
    tr = track(TrackerConfig(enabled=False), scene["detections"], scene["dwells"])
    assert set(tr) == set(TRACK_COLUMNS) and len(tr["track_id"]) == 0


def test_config_problems():
    assert TrackerConfig().problems() == []
    keys = {p.key for p in TrackerConfig(confirm_m=6, confirm_n=5).problems()}
    assert keys == {"confirm_m"}
    keys = {p.key for p in TrackerConfig(gate_probability=1.0, accel_sigma_mps2=-1).problems()}
    assert keys == {"gate_probability", "accel_sigma_mps2"}
    assert [p.key for p in TrackerConfig(process_noise="singer").problems()] == ["process_noise"]


def test_missing_detection_column_is_a_clear_error():
    from gmtiflow.errors import InputFileError
    scene = straight_scene(n_revisits=5)
    det = {k: v for k, v in scene["detections"].items() if k != "x_m"}
    with pytest.raises(InputFileError, match="x_m"):
        track(TrackerConfig(), det, scene["dwells"])


@pytest.mark.parametrize("footprints", [True, False])
def test_several_beams_per_revisit_keep_every_track(footprints):
    # 4 dwells per revisit, each vehicle inside one beam only: the 3 other dwells of a revisit
    # must not count as misses (footprint mode) / misses are counted per revisit (revisit mode).
    scene = straight_scene(n_vehicles=8, n_revisits=60, n_beams=4, spacing_m=1500.0,
                           clutter_per_dwell=2.0, seed=3)
    assert len(np.unique(scene["looks"]["dwell_id"] % 4)) == 2      # vehicles sit in 2 beams
    dwells = scene["dwells"]
    if not footprints:
        dwells = {k: v for k, v in dwells.items()
                  if k not in ("beam_az_rad", "angle_half_extent_rad")}
    tr = track(TrackerConfig(), scene["detections"], dwells)
    conf = tr["confirmed"]
    assert len(np.unique(tr["track_id"][conf])) == 8
    # every confirmed track lives from its confirmation to the end
    for i in np.unique(tr["track_id"][conf]):
        assert tr["time_s"][tr["track_id"] == i].max() >= 118.0


def test_range_window_of_the_footprint_needs_the_origin():
    from gmtiflow import frames
    origin = frames.Origin(48.0, 11.0, 0.0)
    scene = straight_scene(n_revisits=50, blind={0: [(40.0, 60.0)]}, seed=1)
    dwells = dict(scene["dwells"])
    n = len(dwells["time_s"])
    # the range window is centred on the scene, except on t in [40, 60] where it is 20 km beyond
    away = (dwells["time_s"] >= 40.0) & (dwells["time_s"] <= 60.0)
    cx = np.where(away, 250.0, 250.0)
    cy = np.where(away, 500.0 + 20000.0, 500.0)
    lat, lon, _ = frames.enu_to_geodetic(origin, cx, cy, np.zeros(n))
    dwells.update(area_lat_deg=lat, area_lon_deg=lon, range_half_extent_m=np.full(n, 2000.0))
    with_origin = track(TrackerConfig(), scene["detections"], dwells, origin=origin)
    assert len(np.unique(with_origin["track_id"][with_origin["confirmed"]])) == 1
    without = track(TrackerConfig(), scene["detections"], dwells)       # azimuth only
    assert len(np.unique(without["track_id"][without["confirmed"]])) == 2


def test_detections_without_range_rate_or_sigmas_still_track():
    scene = straight_scene(n_vehicles=2, n_revisits=40, spacing_m=1000.0, seed=6)
    det = dict(scene["detections"])
    det["range_rate_mps"] = np.where(np.arange(len(det["x_m"])) % 3 == 0, np.nan,
                                     det["range_rate_mps"])
    det["sigma_range_m"] = np.where(np.arange(len(det["x_m"])) % 5 == 0, np.nan,
                                    det["sigma_range_m"])
    tr = track(TrackerConfig(default_sigma_range_m=10.0), det, scene["dwells"])
    assert np.all(np.isfinite(tr["x_m"])) and np.all(np.isfinite(tr["vx_mps"]))
    assert len(np.unique(tr["track_id"][tr["confirmed"]])) == 2
    mse = errors_by_vehicle(scene, tr, 30.0)
    assert np.all(np.sqrt(mse) < SIGMA_M * np.sqrt(2.0))


def test_doppler_wrapped_range_rates_are_unwrapped_in_the_innovation():
    scene = straight_scene(n_vehicles=2, n_revisits=40, spacing_m=1000.0, seed=8)
    det = dict(scene["detections"])
    w = 20.0                                         # λ·PRF/4: range rates fold into ±20 m/s
    assert np.all(np.abs(det["range_rate_mps"]) > w)     # the platform motion makes them fold
    det["range_rate_mps"] = np.mod(det["range_rate_mps"] + w, 2 * w) - w
    det["wrap_velocity_mps"] = np.full(len(det["x_m"]), w)
    tr = track(TrackerConfig(), det, scene["dwells"])
    assert len(np.unique(tr["track_id"][tr["confirmed"]])) == 2
    assert np.all(np.sqrt(errors_by_vehicle(scene, tr, 30.0)) < SIGMA_M * np.sqrt(2.0))
    # without the wrap velocity the folded range rates fall outside every gate
    det["wrap_velocity_mps"] = np.full(len(det["x_m"]), np.nan)
    broken = track(TrackerConfig(), det, scene["dwells"])
    assert len(np.unique(broken["track_id"][broken["confirmed"]])) == 0


def test_one_row_per_track_and_time_when_dwells_share_an_instant(tmp_path, compose_config):
    """instant_scan gives every dwell of a scan the same time; /tracks stays one row per
    (track, time) so it passes the same validation as an external tracker's table."""
    from gmtiflow.evaluate.tracks import validate_tracks
    from gmtiflow import pipeline, store
    cfg = compose_config(["fidelity=fast", "scene.duration_s=60", "report=none", "export=none"])
    path = pipeline.run(cfg, tmp_path)
    tracks = store.read_table(path, "tracks")
    key = tracks["track_id"] * 10_000_000 + np.round(tracks["time_s"] * 1000).astype(np.int64)
    assert len(np.unique(key)) == len(key) > 0
    validate_tracks(tracks)


# The default sensor's geometry: 0.3 m range, 74 m cross-range, 0.05 m/s range-rate σ at 30 km,
# 5 s revisits, half-overlapping beams (a vehicle is usually detected in two adjacent dwells).

def test_gmti_geometry_one_track_per_vehicle_despite_adjacent_beam_doubles():
    scene = gmti_scene(n_vehicles=6, n_revisits=40, seed=1)
    det, dw = scene["detections"], scene["dwells"]
    rev = dw["revisit_id"][det["dwell_id"]]
    _, per = np.unique(det["truth_id"] * 1000 + rev, return_counts=True)
    assert (per == 2).mean() > 0.5              # most vehicle-revisits give two plots
    tr = track(TrackerConfig(), det, dw)
    assert len(np.unique(tr["track_id"][tr["confirmed"]])) == 6
    out = evaluate(MetricsConfig(), scene["truth"], tr, scene["looks"], scene["vehicles"])
    assert summary_value(out, "identity_switches") == 0
    assert summary_value(out, "fragmentations") == 0
    assert summary_value(out, "gospa_false_mean") == 0.0        # no duplicate or false track
    assert summary_value(out, "coverage_mean") > 0.85           # all but the confirmation delay
    # Better than one plot's cross-range σ (74 m), on cross-range-dominated errors.
    assert summary_value(out, "position_rmse_m") < 60.0


def test_turn_during_a_short_gap_keeps_the_track_with_cwna_but_not_dwna():
    # Every vehicle turns 30° at t = 100 s while unseen for two revisits (98–107 s).  The range
    # and range rate are nearly exact along the LOS, so the DWNA model (position and velocity
    # noise tied, rank-1 Q) gates the first plot after the turn out and starts a new track.
    h0 = np.radians(np.linspace(20.0, 160.0, 4))
    ids = {"cwna": 0, "dwna": 0}
    for seed in range(3):
        scene = gmti_scene(n_vehicles=4, n_revisits=40, seed=seed,
                           turns={v: (100.0, h0[v] + np.radians(30.0)) for v in range(4)},
                           blind={v: [(98.0, 107.0)] for v in range(4)})
        for model in ids:
            tr = track(TrackerConfig(process_noise=model), scene["detections"], scene["dwells"])
            ids[model] += len(np.unique(tr["track_id"][tr["confirmed"]]))
    assert ids["cwna"] == 3 * 4
    assert ids["dwna"] >= 3 * 4 + 4


@pytest.mark.parametrize("per", ["dwell", "revisit"])
def test_measurements_computed_once_for_the_run_give_the_same_tracks(per):
    """track() hands the baseline every plot's measurement computed in one pass; a tracker fed
    plain batches (protocol.batches) computes them per dwell: the tracks are the same bits."""
    from gmtiflow.evaluate.protocol import SceneInfo, _Prepared, run_tracker
    from gmtiflow.evaluate.tracker import NNKalmanTracker
    scene = straight_scene(n_vehicles=4, n_revisits=40, n_beams=3, clutter_per_dwell=4.0,
                           seed=9)
    det = dict(scene["detections"])
    i = np.arange(len(det["x_m"]))
    det["range_rate_mps"] = np.where(i % 7 == 0, np.nan, det["range_rate_mps"])
    det["sigma_range_m"] = np.where(i % 5 == 0, np.nan, det["sigma_range_m"])
    det["x_m"] = np.where(i % 11 == 0, np.nan, det["x_m"])
    det["implausible"] = i % 13 == 0
    det["wrap_velocity_mps"] = np.where(i % 3 == 0, 50.0, np.nan)
    cfg = TrackerConfig(per=per)
    once = track(cfg, det, scene["dwells"])
    plain = run_tracker(NNKalmanTracker(cfg), _Prepared(det, scene["dwells"], None, per),
                        SceneInfo(per=per))
    assert len(once["track_id"]) > 100
    for k in TRACK_COLUMNS:
        assert once[k].tobytes() == plain[k].tobytes(), k
