"""Statistics of the benchmark verdict: intervals, pairing by seed, the better/worse call."""
import csv
import io
import math

import numpy as np
import pytest
from scipy import stats as sps

from gmtiflow.bench import stats
from gmtiflow.bench.collect import JobRecord
from gmtiflow.bench.verdict import compare, to_csv, to_markdown


def test_interval_is_the_student_t_interval():
    x = np.array([3.0, 5.0, 4.0, 8.0, 6.0])
    e = stats.estimate(x)
    lo, hi = sps.t.interval(0.95, len(x) - 1, loc=x.mean(), scale=sps.sem(x))
    assert (e.mean, e.n) == (5.2, 5)
    assert e.low == pytest.approx(lo, rel=1e-12) and e.high == pytest.approx(hi, rel=1e-12)


def test_interval_ignores_nan_and_needs_two_values():
    assert stats.estimate([1.0, np.nan, 3.0]).n == 2
    one = stats.estimate([np.nan, 2.0])
    assert one.mean == 2.0 and one.n == 1 and math.isnan(one.low)
    assert stats.estimate([]).n == 0


def test_paired_difference_cancels_the_common_seed_effect():
    # seed effects of ±50 hide a constant improvement of 1 in the unpaired intervals
    seed_effect = {s: 50.0 * (-1) ** s + s for s in range(1, 7)}
    ref = {s: 10.0 + e for s, e in seed_effect.items()}
    new = {s: 9.0 + e + 0.01 * s for s, e in seed_effect.items()}
    a, b = stats.estimate(list(new.values())), stats.estimate(list(ref.values()))
    assert a.low < b.mean < a.high                        # unpaired: indistinguishable
    d = stats.paired(new, ref)
    assert d.mean == pytest.approx(-1 + 0.035) and d.high < 0
    assert stats.verdict(d, higher_is_better=False) == "better"
    assert stats.verdict(d, higher_is_better=True) == "worse"


def test_pairing_uses_only_common_seeds_and_ties_when_zero_is_inside():
    d = stats.paired({1: 1.0, 2: 2.0, 3: 7.0}, {1: 1.5, 2: 1.0, 9: 0.0})
    assert d.n == 2 and d.mean == pytest.approx(0.25)
    assert stats.verdict(d, False) == "tie"


def _rec(scenario, tracker, seed, **values):
    return JobRecord(dir=None, scenario=scenario, tracker=tracker, seed=seed, ok=True,
                     values=values)


def test_compare_pairs_trackers_per_scenario_and_writes_tables():
    recs = []
    for s in (1, 2, 3):
        recs.append(_rec("tunnel", "nn_kalman", s, invisible_road_id_kept_fraction=0.0 + 0.1 * s))
        recs.append(_rec("tunnel", "other", s, invisible_road_id_kept_fraction=0.5 + 0.1 * s))
    recs.append(JobRecord(dir="x", ok=False, error="boom"))
    comp = compare(recs)
    assert comp.reference == "nn_kalman" and comp.trackers == ["nn_kalman", "other"]
    cell = comp.cell("tunnel", "invisible_road_id_kept_fraction", "other")
    assert cell.delta.mean == pytest.approx(0.5) and cell.verdict == "better"
    assert comp.cell("tunnel", "ospa_mean_m", "other").est.n == 0   # absent values are NaN
    rows = list(csv.DictReader(io.StringIO(to_csv(comp))))
    row = next(r for r in rows if r["metric"] == "invisible_road_id_kept_fraction"
               and r["tracker"] == "other")
    assert (row["scenario"], row["n_seeds"], row["verdict"]) == ("tunnel", "3", "better")
    assert float(row["mean"]) == pytest.approx(0.7) and float(row["delta_mean"]) == pytest.approx(0.5)
    md = to_markdown(comp)
    assert "| tunnel | id kept through tunnels, higher is better |" in md
    assert "▲ better" in md and "## Failed jobs" in md and "boom" in md
    with pytest.raises(ValueError, match="reference tracker 'nope'"):
        compare(recs, reference="nope")


def test_mota_and_idf1_are_in_every_scenario_table_with_their_ranges():
    # MOTA may be negative (more errors than truths), so its interval is not cut at 0; IDF1 is a
    # fraction; both are "higher is better"
    recs = [_rec("crossing", t, s, mota=m, idf1=f)
            for t, m, f in (("nn_kalman", -0.5, 0.6), ("other", 0.5, 0.9))
            for s in (1, 2, 3)]
    recs += [_rec("crossing", "other", 4, mota=0.6, idf1=0.95),
             _rec("crossing", "nn_kalman", 4, mota=-0.4, idf1=0.99)]
    comp = compare(recs)
    ref = comp.cell("crossing", "mota", "nn_kalman")
    assert ref.est.mean == pytest.approx(-0.475) and ref.est.low < -0.475
    assert comp.cell("crossing", "mota", "other").verdict == "better"
    assert comp.cell("crossing", "idf1", "other").est.high <= 1.0
    md = to_markdown(comp)
    assert "| MOTA, higher is better |" in md and "| IDF1, higher is better |" in md
