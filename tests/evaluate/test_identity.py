"""Identity metrics on crafted association histories: switches, fragmentation, purity, coverage,
convoy confusions.  Tracks carry no velocity (held between rows) and are scored only at their own
second (max_extrapolation_s = 0.5 s), so every step's association is known by construction."""
import numpy as np
import pytest

from gmtiflow.evaluate.config import MetricsConfig
from gmtiflow.evaluate.stage import evaluate, summary_value

from .helpers import line, track_table, truth_table

CFG = MetricsConfig(cutoff_m=100.0, assoc_gate_m=30.0, max_extrapolation_s=0.5)
T = np.arange(10.0)


def follow(track_id, vehicle_path, times, offset=(2.0, 0.0)):
    t, x, y = vehicle_path
    return [(track_id, tt, x[int(tt)] + offset[0], y[int(tt)] + offset[1]) for tt in times]


def test_replacement_is_one_switch_counted_once():
    v0 = line(T, 0, 0, 10, 0)
    truth = truth_table({0: v0})
    tracks = track_table(follow(1, v0, T[:5]) + follow(2, v0, T[5:]))
    out = evaluate(CFG, truth, tracks)
    assert summary_value(out, "identity_switches") == 1
    assert summary_value(out, "fragmentations") == 0
    sw = out["metrics/identity_switches"]
    assert list(sw["time_s"]) == [5.0]
    assert (sw["from_track_id"][0], sw["to_track_id"][0]) == (1, 2)


def test_switch_back_counts_twice():
    v0 = line(T, 0, 0, 10, 0)
    tracks = track_table(follow(1, v0, T[:4]) + follow(2, v0, T[4:7]) + follow(1, v0, T[7:]))
    out = evaluate(CFG, truth_table({0: v0}), tracks)
    assert summary_value(out, "identity_switches") == 2


def test_two_tracks_swapping_two_truths_is_one_switch_per_truth():
    v0, v1 = line(T, 0, 0, 10, 0), line(T, 0, 200, 10, 0)
    tracks = track_table(follow(1, v0, T[:5]) + follow(1, v1, T[5:])
                         + follow(2, v1, T[:5]) + follow(2, v0, T[5:]))
    out = evaluate(CFG, truth_table({0: v0, 1: v1}), tracks)
    assert summary_value(out, "identity_switches") == 2
    assert list(out["metrics/truth_identity"]["identity_switches"]) == [1, 1]
    assert summary_value(out, "track_purity_mean") == pytest.approx(0.5)


def test_fragmentation_without_switch():
    v0 = line(T, 0, 0, 10, 0)
    tracks = track_table(follow(1, v0, T[:4]) + follow(1, v0, T[7:]))
    out = evaluate(CFG, truth_table({0: v0}), tracks)
    assert summary_value(out, "fragmentations") == 1
    assert summary_value(out, "identity_switches") == 0
    assert summary_value(out, "coverage_mean") == pytest.approx(7 / 10)


def test_far_track_is_not_associated():
    v0 = line(T, 0, 0, 10, 0)
    tracks = track_table(follow(1, v0, T, offset=(40.0, 0.0)))   # beyond the 30 m gate
    out = evaluate(CFG, truth_table({0: v0}), tracks)
    assert summary_value(out, "coverage_mean") == 0.0
    assert summary_value(out, "gospa_missed_mean") == pytest.approx(0.0)   # inside cut-off 100
    assert np.isnan(summary_value(out, "position_rmse_m"))


def test_purity_and_convoy_confusion():
    v0, v1, v2 = line(T, 0, 0, 10, 0), line(T, -100, 0, 10, 0), line(T, 0, 500, 10, 0)
    truth = truth_table({0: v0, 1: v1, 2: v2})
    vehicles = {"vehicle_id": np.array([0, 1, 2]), "convoy_id": np.array([7, 7, -1])}
    # Track 1 holds convoy member 0 for 6 s then hops to member 1; track 2 holds vehicle 2.
    tracks = track_table(follow(1, v0, T[:6]) + follow(1, v1, T[6:]) + follow(2, v2, T))
    out = evaluate(CFG, truth, tracks, vehicles=vehicles)
    pur = out["metrics/track_purity"]
    assert list(pur["track_id"]) == [1, 2]
    assert pur["purity"] == pytest.approx([0.6, 1.0])
    assert list(pur["dominant_vehicle_id"]) == [0, 2]
    conv = out["metrics/convoys"]
    assert list(conv["convoy_id"]) == [7] and list(conv["n_confused_tracks"]) == [1]
    assert summary_value(out, "convoy_confused_tracks") == 1


def test_perfect_tracks_score_zero():
    v0, v1 = line(T, 0, 0, 10, 0), line(T, 0, 200, 0, -5)
    truth = truth_table({0: v0, 1: v1})
    tracks = {"track_id": np.where(truth["vehicle_id"] == 0, 10, 11), "time_s": truth["time_s"],
              "x_m": truth["x_m"], "y_m": truth["y_m"], "vx_mps": truth["vx_mps"],
              "vy_mps": truth["vy_mps"]}
    platform = {"time_s": np.array([0.0, 9.0]), "x_m": np.array([0.0, 1350.0]),
                "y_m": np.full(2, -30000.0), "z_m": np.full(2, 6000.0),
                "vx_mps": np.full(2, 150.0), "vy_mps": np.zeros(2), "vz_mps": np.zeros(2)}
    out = evaluate(CFG, truth, tracks, platform=platform)
    for name in ("ospa_mean_m", "gospa_mean_m", "position_rmse_m", "speed_rmse_mps",
                 "heading_rmse_rad", "range_rate_rmse_mps", "identity_switches",
                 "fragmentations"):
        assert summary_value(out, name) == pytest.approx(0.0, abs=1e-9), name
    assert summary_value(out, "coverage_mean") == 1.0


# CLEAR-MOT keeps a still-valid correspondence: a nearer track does not take a held vehicle over.

def test_two_tracks_on_one_vehicle_alternating_nearer_is_no_switch():
    # Track 1 is always within the gate (offset 10 m); track 2 (offset -16 m, then 4 m, ...)
    # is nearer on every odd step.  A per-step nearest pairing would flip 1-2-1-2...: 9
    # "switches" for a vehicle that track 1 never stopped following.
    v0 = line(T, 0, 0, 10, 0)
    rows = follow(1, v0, T, offset=(0.0, 10.0))
    rows += [(2, t, x, y + (-16.0 if int(t) % 2 == 0 else 4.0)) for t, x, y in zip(*v0)]
    out = evaluate(CFG, truth_table({0: v0}), track_table(rows))
    assert summary_value(out, "identity_switches") == 0
    assert summary_value(out, "fragmentations") == 0
    assert set(out["metrics/association"]["track_id"]) == {1}
    # Track 2 is a duplicate: unassociated, so it costs GOSPA a false track at every step.
    assert summary_value(out, "gospa_false_mean") == pytest.approx(100.0 ** 2 / 2)


def test_convoy_tracks_crossing_within_the_gate_keep_their_vehicles():
    # Two vehicles 20 m apart (a convoy); each track wobbles 14 m towards the other vehicle on odd
    # steps, where the swapped pairing is the cheaper one (2·6² < 2·14²).  Each track still
    # follows its vehicle: no switch, and neither track hops between convoy members.
    v0, v1 = line(T, 0, 0, 10, 0), line(T, 0, 20, 10, 0)
    wob = [0.0 if int(t) % 2 == 0 else 14.0 for t in T]
    rows = [(1, t, x, y + w) for t, x, y, w in zip(*v0, wob)]
    rows += [(2, t, x, y - w) for t, x, y, w in zip(*v1, wob)]
    vehicles = {"vehicle_id": np.array([0, 1]), "convoy_id": np.array([3, 3])}
    out = evaluate(CFG, truth_table({0: v0, 1: v1}), track_table(rows), vehicles=vehicles)
    assert summary_value(out, "identity_switches") == 0
    assert summary_value(out, "convoy_confused_tracks") == 0
    assert summary_value(out, "track_purity_mean") == 1.0


def test_kept_track_leaving_the_gate_hands_over_once():
    # Track 1 holds the vehicle for t < 4, then drifts 40 m off (beyond the 30 m gate) and comes
    # back at t >= 7; track 2 (5 m off) is there all along.  CLEAR-MOT: switch 1 -> 2 at t = 4,
    # and track 2, still valid, keeps the vehicle when track 1 returns: 1 switch, not 2.
    v0 = line(T, 0, 0, 10, 0)
    off = [0.0 if (t < 4 or t >= 7) else 40.0 for t in T]
    rows = [(1, t, x, y + o) for t, x, y, o in zip(*v0, off)]
    rows += follow(2, v0, T, offset=(0.0, -5.0))
    out = evaluate(CFG, truth_table({0: v0}), track_table(rows))
    assert summary_value(out, "identity_switches") == 1
    sw = out["metrics/identity_switches"]
    assert list(sw["time_s"]) == [4.0]
    assert (sw["from_track_id"][0], sw["to_track_id"][0]) == (1, 2)
    assert summary_value(out, "fragmentations") == 0


def test_closest_claims_keep_the_nearest_truth_of_each_track():
    # pass 1's conflicts: the closest claim of each track wins (ties: the lower truth row), with
    # or without conflicts (the conflict-free step skips the sort)
    from gmtiflow.evaluate.identity import _closest_claims
    rng = np.random.default_rng(3)
    for n_tracks in (1, 3, 40, 100):
        r = rng.permutation(60)[:30]
        k = rng.integers(0, n_tracks, 30) if n_tracks < 100 else rng.permutation(100)[:30]
        d2 = rng.integers(0, 4, 30).astype(float)            # ties on purpose
        want = {}
        for dd, rr, kk in sorted(zip(d2.tolist(), r.tolist(), k.tolist())):
            want.setdefault(kk, rr)
        got_r, got_k = _closest_claims(r, k, d2, n_tracks)
        assert sorted(zip(got_k.tolist(), got_r.tolist())) == sorted(want.items())


def test_identity_metrics_rows_in_any_order():
    # align gives rows by step (a stable sort by vehicle then suffices); any other order is
    # sorted by (vehicle, step) first: the same tables
    from gmtiflow.evaluate.identity import identity_metrics
    rng = np.random.default_rng(12)
    step = np.repeat(np.arange(40), 6)
    vid = np.tile(np.array([9, 2, 5, 1000, 7, 3]), 40)
    assigned = np.where(rng.uniform(size=240) < 0.2, -1, rng.integers(0, 4, 240))
    want = identity_metrics({"step": step, "vehicle_id": vid}, assigned, np.arange(40.0))
    o = rng.permutation(240)
    got = identity_metrics({"step": step[o], "vehicle_id": vid[o]}, assigned[o], np.arange(40.0))
    assert want["switches"] > 5 and want["fragmentations"] > 5
    for part in ("truth", "tracks", "switch_times"):
        for col in want[part]:
            assert np.array_equal(got[part][col], want[part][col], equal_nan=True), (part, col)


def test_unique_pairs_is_np_unique_of_the_rows():
    from gmtiflow.evaluate.identity import unique_pairs
    rng = np.random.default_rng(21)
    for lo, hi in ((0, 5), (-7, 40), (-10 ** 6, 10 ** 6)):
        a, b = rng.integers(lo, hi, 500), rng.integers(lo, hi, 500)
        want, counts = np.unique(np.c_[a, b], axis=0, return_counts=True)
        got, got_counts = unique_pairs(a, b, return_counts=True)
        assert np.array_equal(got, want) and np.array_equal(got_counts, counts)
        assert got.dtype == np.int64 and got_counts.dtype == counts.dtype
        assert np.array_equal(unique_pairs(a, b), want)
