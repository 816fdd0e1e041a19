"""GMTI events: identity through a stop or a blind gap, and the re-acquisition delay."""
import numpy as np
import pytest

from gmtiflow.evaluate.config import MetricsConfig
from gmtiflow.evaluate.events import blind_gap_events
from gmtiflow.evaluate.stage import evaluate, summary_value

from .helpers import track_table, truth_table

CFG = MetricsConfig(cutoff_m=100.0, assoc_gate_m=30.0, max_extrapolation_s=0.5)
T = np.arange(40.0)


def stopping_vehicle():
    """Drives east at 10 m/s, stands still on t = 10..19 (mode 2), drives on from t = 20."""
    s = 10.0 * (np.minimum(T, 10.0) + np.maximum(T - 19.0, 0.0))
    mode = np.where((T >= 10) & (T <= 19), 2, 0)
    return truth_table({0: (T, s, np.zeros_like(s))}, modes={0: mode})


def rows(track_id, truth, times):
    return [(track_id, t, truth["x_m"][int(t)] + 1.0, truth["y_m"][int(t)]) for t in times]


def test_track_surviving_a_stop_is_credited():
    truth = stopping_vehicle()
    out = evaluate(CFG, truth, track_table(rows(1, truth, T)))
    ev = out["metrics/events"]
    assert list(ev["kind"]) == ["stop"]
    assert (ev["start_s"][0], ev["end_s"][0]) == (10.0, 20.0)
    assert ev["track_before"][0] == 1 and ev["track_after"][0] == 1
    assert bool(ev["id_kept"][0]) and ev["reacq_delay_s"][0] == 0.0
    assert summary_value(out, "stop_id_kept_fraction") == 1.0


def test_track_replaced_after_a_stop_is_not_credited_and_delay_is_measured():
    truth = stopping_vehicle()
    # Track 1 is lost at t = 12 during the stop; track 2 picks the vehicle up at t = 23.
    tracks = track_table(rows(1, truth, T[:13]) + rows(2, truth, T[23:]))
    out = evaluate(CFG, truth, tracks)
    ev = out["metrics/events"]
    assert ev["track_before"][0] == 1 and ev["track_after"][0] == 2
    assert not bool(ev["id_kept"][0])
    assert ev["reacq_delay_s"][0] == pytest.approx(3.0)
    assert summary_value(out, "stop_id_kept_fraction") == 0.0
    assert summary_value(out, "stop_reacq_delay_mean_s") == pytest.approx(3.0)


def test_never_reacquired():
    truth = stopping_vehicle()
    out = evaluate(CFG, truth, track_table(rows(1, truth, T[:13])))
    ev = out["metrics/events"]
    assert not bool(ev["reacquired"][0]) and np.isnan(ev["reacq_delay_s"][0])
    assert summary_value(out, "stop_reacquired_fraction") == 0.0


def test_event_without_a_track_before_is_not_scored():
    truth = stopping_vehicle()
    out = evaluate(CFG, truth, track_table(rows(2, truth, T[25:])))
    assert summary_value(out, "stop_events") == 1
    assert summary_value(out, "stop_events_held") == 0
    assert np.isnan(summary_value(out, "stop_id_kept_fraction"))


def looks_of(outcomes, times=None, vehicle=0):
    n = len(outcomes)
    times = np.arange(n) * 2.0 if times is None else np.asarray(times, float)
    return {"dwell_id": np.arange(n), "vehicle_id": np.full(n, vehicle), "time_s": times,
            "outcome": np.asarray(outcomes, np.uint8), "det_id": np.full(n, -1)}


def test_blind_gaps_from_looks():
    # detected, detected, blind, blind, terrain, detected, pd_miss, detected
    looks = looks_of([0, 0, 4, 4, 3, 0, 5, 0])
    ev = blind_gap_events(looks)
    assert list(ev["kind"]) == ["doppler_blind"]          # 2 blind looks beat 1 terrain look
    assert (ev["start_s"][0], ev["end_s"][0]) == (4.0, 10.0)
    assert len(blind_gap_events(looks, min_gap_looks=3)["kind"]) == 1
    assert len(blind_gap_events(looks, min_gap_looks=4)["kind"]) == 0


def test_blind_gap_scored_against_tracks():
    truth = truth_table({0: (T, 10.0 * T, np.zeros_like(T))})
    looks = looks_of([0] * 5 + [4] * 4 + [0] * 11)          # blind at t = 10..16, seen at 18
    kept = evaluate(CFG, truth, track_table(rows(1, truth, T)), looks=looks)
    assert summary_value(kept, "doppler_blind_id_kept_fraction") == 1.0
    assert summary_value(kept, "doppler_blind_reacq_delay_mean_s") == 0.0
    lost = evaluate(CFG, truth, track_table(rows(1, truth, T[:12]) + rows(4, truth, T[21:])),
                    looks=looks)
    assert summary_value(lost, "doppler_blind_id_kept_fraction") == 0.0
    assert summary_value(lost, "doppler_blind_reacq_delay_mean_s") == pytest.approx(3.0)


def test_two_sensors_give_per_sensor_and_fused_gaps():
    truth = truth_table({0: (T, 10.0 * T, np.zeros_like(T))})
    # sensor 0 looks at even seconds and is blind for t = 10..18; sensor 1 looks at odd seconds
    # and sees the vehicle throughout except a P_D miss at t = 13 (no blind look of its own)
    t0, t1 = np.arange(0.0, 40.0, 2.0), np.arange(1.0, 40.0, 2.0)
    out0 = np.where((t0 >= 10) & (t0 <= 18), 4, 0)
    out1 = np.where(t1 == 13, 5, 0)
    looks = {"vehicle_id": np.zeros(40, np.int64), "time_s": np.r_[t0, t1],
             "outcome": np.r_[out0, out1].astype(np.uint8), "det_id": np.full(40, -1),
             "sensor_id": np.r_[np.zeros(20, np.int64), np.ones(20, np.int64)]}
    out = evaluate(CFG, truth, track_table(rows(1, truth, T)), looks=looks)
    ev = out["metrics/events"]
    own = ev["sensor_id"] == 0
    # sensor 0 alone: one gap, t = 10 to its next detection at 20
    assert list(zip(ev["start_s"][own], ev["end_s"][own])) == [(10.0, 20.0)]
    assert not np.any(ev["sensor_id"] == 1)
    # fused: each blind look of sensor 0 is ended by sensor 1's next detection, except the one at
    # t = 12, which sensor 1 missed at 13: 10-11, 12-15 (looks 12, 13 (P_D), 14), 16-17, 18-19
    fused = ev["sensor_id"] == -1
    assert list(zip(ev["start_s"][fused], ev["end_s"][fused])) == [
        (10.0, 11.0), (12.0, 15.0), (16.0, 17.0), (18.0, 19.0)]
    # the summary counts the fused gaps
    assert summary_value(out, "doppler_blind_events") == 4
    # with one sensor every row is fused and the summary is what it was
    one = {k: v[:20] for k, v in looks.items()}
    ev1 = evaluate(CFG, truth, track_table(rows(1, truth, T)), looks=one)["metrics/events"]
    assert list(ev1["sensor_id"]) == [-1] and (ev1["start_s"][0], ev1["end_s"][0]) == (10.0, 20.0)


def test_event_tables_written_before_the_sensor_id_column_still_read(tmp_path):
    from gmtiflow import store
    from gmtiflow.evaluate.events import EVENT_COLUMNS
    old = {c: np.zeros(2) for c in EVENT_COLUMNS}          # an events table without sensor_id
    old["kind"] = np.array(["stop", "doppler_blind"])
    with store.RunWriter(tmp_path / "old.h5", seed=1) as w:
        w.write_table("metrics/events", old)
        path = w.commit()
    with store.open_run(path, require_columns=True) as f:
        assert "sensor_id" not in f["metrics/events"]
    del old["track_after"]                                  # a column it always had is required
    with store.RunWriter(tmp_path / "bad.h5", seed=1) as w:
        w.write_table("metrics/events", old)
        bad = w.commit()
    with pytest.raises(store.StoreError, match="lacks the column"):
        store.open_run(bad, require_columns=True).close()


def _score_events_one_by_one(events, av, at, ak, lookback_s):
    """The per-event loop score_events replaced: the reference its vectorised searches must
    reproduce bit for bit."""
    from gmtiflow.evaluate.order import lexorder
    o = lexorder(av, at)
    av, at, ak = av[o], at[o], ak[o]
    has = ak >= 0
    av, at, ak = av[has], at[has], ak[has]
    n = len(events["vehicle_id"])
    before, after = np.full(n, -1, np.int64), np.full(n, -1, np.int64)
    delay = np.full(n, np.nan)
    eps = 1e-9
    for i in range(n):
        vid = events["vehicle_id"][i]
        lo, hi = np.searchsorted(av, [vid, vid + 1])
        times, ids = at[lo:hi], ak[lo:hi]
        t0, t1 = events["start_s"][i], events["end_s"][i]
        j = np.searchsorted(times, t0 + eps, side="right") - 1
        if j >= 0 and times[j] >= t0 - lookback_s - eps:
            before[i] = ids[j]
        if np.isfinite(t1):
            j = np.searchsorted(times, t1 - eps, side="left")
            if j < len(times):
                after[i] = ids[j]
                delay[i] = max(times[j] - t1, 0.0)
    return before, after, delay


@pytest.mark.parametrize("seed", range(6))
def test_score_events_matches_a_search_per_event(seed):
    from gmtiflow.evaluate.events import score_events
    g = np.random.default_rng(seed)
    n_veh, n_steps = [(1, 5), (3, 40), (20, 200), (50, 30), (7, 1), (30, 100)][seed]
    grid = np.arange(n_steps) * 0.5
    av = np.repeat(np.arange(n_veh) * 3, n_steps)          # sparse ids: some never associated
    at = np.tile(grid, n_veh)
    ak = np.where(g.random(len(av)) < 0.3, -1, g.integers(0, 10, len(av)))
    keep = g.random(len(av)) < 0.8                          # holes in each vehicle's series
    av, at, ak = av[keep], at[keep], ak[keep]
    shuffle = g.permutation(len(av))
    av, at, ak = av[shuffle], at[shuffle], ak[shuffle]
    n_ev = 3 * n_veh + 5
    start = g.choice(grid, n_ev) + g.choice([0.0, 1e-9, -1e-9, 2e-9, 0.25], n_ev)
    end = start + g.choice([0.0, 0.5, 1.0, 3.7, np.nan, np.inf], n_ev)
    ids = np.r_[np.arange(n_veh) * 3, -1, 1, 3 * n_veh]         # and three never associated
    events = {"vehicle_id": g.choice(ids, n_ev), "kind": np.zeros(n_ev, np.int64),
              "start_s": start, "end_s": end}
    out = score_events(events, av, at, ak, lookback_s=1.0)
    before, after, delay = _score_events_one_by_one(events, av, at, ak, 1.0)
    assert np.array_equal(out["track_before"], before)
    assert np.array_equal(out["track_after"], after)
    assert out["reacq_delay_s"].tobytes() == delay.tobytes()
    if n_veh * n_steps >= 100:                  # the bigger cases find tracks both sides
        assert (before >= 0).any() and (after >= 0).any() and np.isfinite(delay).any()


def test_score_events_with_no_association_or_no_event():
    from gmtiflow.evaluate.events import score_events
    events = {"vehicle_id": np.array([0, 1]), "kind": np.zeros(2, np.int64),
              "start_s": np.array([1.0, 2.0]), "end_s": np.array([3.0, np.nan])}
    none = np.array([], np.int64)
    out = score_events(events, none, np.array([]), none, 5.0)
    assert (out["track_before"] == -1).all() and (out["track_after"] == -1).all()
    assert np.isnan(out["reacq_delay_s"]).all()
    empty = {k: v[:0] for k, v in events.items()}
    assert len(score_events(empty, np.array([0]), np.array([1.0]), np.array([4]), 5.0)
               ["track_before"]) == 0
