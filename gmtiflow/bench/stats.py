"""Means with 95 % intervals over seeds, and paired (by seed) differences between trackers.

Seeds are the replications.  For a metric, a tracker and a scenario, the n seeds with a finite
value give the mean and the Student-t interval mean ± t(0.975, n−1)·s/√n (s the sample standard
deviation; no interval for n < 2).  A comparison with the reference tracker uses the
differences d_s = value(tracker, seed s) − value(reference, seed s) over the seeds where both
are finite, and the same interval on their mean: common random numbers (docs/scale.md) give
both trackers the same truth and the same plots in a seed, so the paired interval is much
narrower than the two unpaired ones.  A tracker's own interval is cut to the values its metric
can take (fractions [0, 1], counts and errors >= 0); paired intervals are not cut.  A tracker is *better* (*worse*) than the reference on a
metric when the paired interval lies entirely on the good (bad) side of 0, else the two are
*not distinguishable* with these seeds.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np
from scipy import stats as sps

LEVEL = 0.95


@dataclass(frozen=True)
class Estimate:
    mean: float
    low: float
    high: float
    n: int


def estimate(values) -> Estimate:
    """Mean and 95 % Student-t interval of the finite values."""
    x = np.asarray(values, float)
    x = x[np.isfinite(x)]
    n = int(x.size)
    if n == 0:
        return Estimate(np.nan, np.nan, np.nan, 0)
    mean = float(np.mean(x))
    if n < 2:
        return Estimate(mean, np.nan, np.nan, 1)
    half = float(sps.t.ppf(0.5 + LEVEL / 2, n - 1) * np.std(x, ddof=1) / np.sqrt(n))
    return Estimate(mean, mean - half, mean + half, n)


def clip(e: Estimate, low: float, high: float) -> Estimate:
    """The interval cut to the values the metric can take (a t-interval over few seeds of a
    fraction can reach past 0 or 1); the mean is unchanged."""
    if not np.isfinite(e.low):
        return e
    return Estimate(e.mean, max(e.low, low), min(e.high, high), e.n)


def paired(values: Mapping[int, float], reference: Mapping[int, float]) -> Estimate:
    """Estimate of the mean of value − reference over the seeds both have (finite)."""
    seeds = sorted(set(values) & set(reference))
    d = np.array([values[s] - reference[s] for s in seeds], float)
    return estimate(d)


def verdict(delta: Estimate, higher_is_better: bool) -> str:
    """``better``, ``worse`` or ``tie`` (interval contains 0, or too few seeds)."""
    if delta.n < 2 or not np.isfinite(delta.low):
        return "tie"
    if delta.low > 0 or delta.high < 0:
        good = (delta.low > 0) == higher_is_better
        return "better" if good else "worse"
    return "tie"
