"""OSPA and GOSPA: hand-worked small cases and agreement with Stone Soup on random sets."""
import math

import numpy as np
import pytest

from gmtiflow.evaluate.ospa import ospa_gospa, series


def test_both_empty_is_zero():
    r = ospa_gospa(np.zeros((0, 2)), np.zeros((0, 2)), c=10.0, p=2.0)
    assert r["ospa"] == 0.0 and r["gospa"] == 0.0


def test_one_truth_no_track_costs_the_cutoff():
    # OSPA: (c^p (1-0) / 1)^(1/p) = c.  GOSPA: (c^p/2)^(1/p) with one missed target.
    r = ospa_gospa([[0.0, 0.0]], np.zeros((0, 2)), c=10.0, p=2.0)
    assert r["ospa"] == pytest.approx(10.0)
    assert r["gospa"] == pytest.approx(math.sqrt(50.0))
    assert r["missed"] == pytest.approx(50.0) and r["false"] == 0.0


def test_one_to_one_is_the_distance():
    r = ospa_gospa([[0.0, 0.0]], [[3.0, 4.0]], c=10.0, p=1.0)
    assert r["ospa"] == pytest.approx(5.0)
    assert r["gospa"] == pytest.approx(5.0)
    assert r["localisation"] == pytest.approx(5.0) and r["n_assigned"] == 1


def test_cutoff_hit_counts_as_missed_plus_false():
    # d = 50 > c = 10: OSPA = c; GOSPA leaves both unassigned: sqrt(50 + 50) = 10.
    r = ospa_gospa([[0.0, 0.0]], [[30.0, 40.0]], c=10.0, p=2.0)
    assert r["ospa"] == pytest.approx(10.0)
    assert r["gospa"] == pytest.approx(10.0)
    assert r["n_assigned"] == 0
    assert r["missed"] == pytest.approx(50.0) and r["false"] == pytest.approx(50.0)


def test_cardinality_mismatch():
    # One truth, two tracks (one at 5 m, one far): OSPA sqrt((25 + 100)/2), GOSPA sqrt(25 + 50).
    r = ospa_gospa([[0.0, 0.0]], [[3.0, 4.0], [100.0, 0.0]], c=10.0, p=2.0)
    assert r["ospa"] == pytest.approx(math.sqrt(62.5))
    assert r["gospa"] == pytest.approx(math.sqrt(75.0))
    assert (r["localisation"], r["missed"], r["false"]) == pytest.approx((25.0, 0.0, 50.0))


def test_assignment_is_optimal_not_greedy():
    # Greedy pairs (10,0)-(6,0) at 4 m first and leaves 16 m; optimal is 6 m + 6 m.
    r = ospa_gospa([[0.0, 0.0], [10.0, 0.0]], [[6.0, 0.0], [16.0, 0.0]], c=20.0, p=2.0)
    assert r["ospa"] == pytest.approx(6.0)
    assert r["gospa"] == pytest.approx(math.sqrt(72.0))


def test_series_steps_are_independent():
    truth_at = {"step": np.array([0, 1, 1]), "x_m": np.array([0.0, 0.0, 50.0]),
                "y_m": np.zeros(3)}
    tracks_at = {"step": np.array([1]), "x_m": np.array([3.0]), "y_m": np.array([4.0]),
                 "track_id": np.array([7])}
    s = series(truth_at, tracks_at, np.array([0.0, 1.0, 2.0]), c=10.0, p=1.0)
    assert s["ospa_m"] == pytest.approx([10.0, (5.0 + 10.0) / 2.0, 0.0])
    assert s["gospa_m"] == pytest.approx([5.0, 5.0 + 5.0, 0.0])
    assert list(s["n_truth"]) == [1, 2, 0] and list(s["n_assigned"]) == [0, 1, 0]


def _stonesoup():
    try:
        from stonesoup.metricgenerator.ospametric import GOSPAMetric, OSPAMetric
        from stonesoup.types.array import StateVector
        from stonesoup.types.state import State
    except Exception as exc:  # pragma: no cover - depends on the environment
        pytest.skip(f"Stone Soup is not importable ({exc}); cross-check skipped")
    return GOSPAMetric, OSPAMetric, State, StateVector


def _brute_ospa(X, Y, c, p):
    """OSPA by trying every pairing (the exact minimum of the definition)."""
    import itertools
    m, n = len(X), len(Y)
    if m + n == 0:
        return 0.0
    A, B = (X, Y) if m <= n else (Y, X)
    best = np.inf
    for perm in itertools.permutations(range(len(B)), len(A)):
        d = np.array([min(np.linalg.norm(A[i] - B[j]), c) for i, j in enumerate(perm)])
        best = min(best, float((d ** p).sum()))
    return ((best + c ** p * abs(m - n)) / max(m, n)) ** (1.0 / p)


@pytest.mark.parametrize("p", [1.0, 2.0, 3.0])
def test_exact_minimum_and_how_stone_soup_differs_on_random_sets(p):
    """Ours is the exact minimum over pairings of Σ min(d, c)^p.  Stone Soup 1.9's GOSPAMetric
    minimises the same sum: its GOSPA and its three components equal ours for every p.  Its
    OSPAMetric picks the pairing minimising Σ min(d, c) and then takes the p-th powers, so its
    OSPA is >= ours and equal whenever both pairings agree (always for p = 1)."""
    import datetime
    GOSPAMetric, OSPAMetric, State, StateVector = _stonesoup()
    rng = np.random.default_rng(int(p))
    now = datetime.datetime(2026, 1, 1)
    c = 30.0
    equal = 0
    for _ in range(40):
        m, n = rng.integers(0, 6, size=2)
        if m + n == 0:
            continue
        X = rng.uniform(0, 100, (m, 2))
        Y = rng.uniform(0, 100, (n, 2))
        truths = [State(StateVector(x), timestamp=now) for x in X]
        tracks = [State(StateVector(y), timestamp=now) for y in Y]
        ours = ospa_gospa(X, Y, c=c, p=p)
        assert ours["ospa"] == pytest.approx(_brute_ospa(X, Y, c, p), rel=1e-9, abs=1e-9)
        ss_ospa = OSPAMetric(c=c, p=p).compute_OSPA_distance(tracks, truths).value
        ss_gospa = GOSPAMetric(c=c, p=p).compute_gospa_metric(tracks, truths)[0].value
        assert ours["ospa"] <= ss_ospa + 1e-9
        assert ours["gospa"] == pytest.approx(ss_gospa["distance"], rel=1e-12, abs=1e-9)
        for part in ("localisation", "missed", "false"):
            assert ours[part] == pytest.approx(ss_gospa[part], rel=1e-12, abs=1e-9), part
        equal += abs(ours["ospa"] - ss_ospa) < 1e-9
        if p == 1.0:
            assert ours["ospa"] == pytest.approx(ss_ospa, rel=1e-9, abs=1e-9)
    assert equal >= 20


def test_stone_soup_pairs_on_d_not_d_to_the_p():
    """The docs' example: Σd prefers A↔C, B↔D (4 + 8.94) but Σd² prefers A↔D, B↔C (52 + 36)."""
    import datetime
    GOSPAMetric, OSPAMetric, State, StateVector = _stonesoup()
    now = datetime.datetime(2026, 1, 1)
    X = np.array([[4.0, 2.0], [2.0, 2.0]])
    Y = np.array([[8.0, 2.0], [10.0, 6.0]])
    ours = ospa_gospa(X, Y, c=100.0, p=2.0)["ospa"]
    ss = OSPAMetric(c=100.0, p=2.0).compute_OSPA_distance(
        [State(StateVector(y), timestamp=now) for y in Y],
        [State(StateVector(x), timestamp=now) for x in X]).value
    assert ours == pytest.approx(np.sqrt(88.0 / 2.0), rel=1e-12)       # 6.633
    assert ss == pytest.approx(np.sqrt(96.0 / 2.0), rel=1e-12)         # 6.928
    # Stone Soup's GOSPAMetric takes the Σd² pairs, as ours does
    ss_gospa = GOSPAMetric(c=100.0, p=2.0).compute_gospa_metric(
        [State(StateVector(y), timestamp=now) for y in Y],
        [State(StateVector(x), timestamp=now) for x in X])[0].value
    assert ss_gospa["localisation"] == pytest.approx(88.0, rel=1e-12)
    assert ospa_gospa(X, Y, c=100.0, p=2.0)["gospa"] == pytest.approx(np.sqrt(88.0), rel=1e-12)


from hypothesis import given, settings, strategies as st  # noqa: E402
from hypothesis.extra.numpy import arrays  # noqa: E402

points = st.integers(0, 6).flatmap(
    lambda n: arrays(np.float64, (n, 2), elements=st.floats(-500, 500, allow_nan=False)))


@settings(max_examples=200, deadline=None)
@given(points, points, st.floats(1.0, 200.0), st.sampled_from([1.0, 2.0, 3.5]))
def test_metric_properties(X, Y, c, p):
    a, b = ospa_gospa(X, Y, c, p), ospa_gospa(Y, X, c, p)
    assert a["ospa"] == pytest.approx(b["ospa"], rel=1e-9, abs=1e-9)          # symmetric
    assert a["gospa"] == pytest.approx(b["gospa"], rel=1e-9, abs=1e-9)
    assert 0.0 <= a["ospa"] <= c * (1 + 1e-12)                                  # bounded by c
    assert a["gospa"] ** p == pytest.approx(a["localisation"] + a["missed"] + a["false"],
                                            rel=1e-9, abs=1e-9)
    assert a["missed"] == pytest.approx(c ** p / 2 * (len(X) - a["n_assigned"]))
    assert ospa_gospa(X, X, c, p)["gospa"] == pytest.approx(0.0, abs=1e-9)      # identity
