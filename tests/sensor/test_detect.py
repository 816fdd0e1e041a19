"""Swerling-I detection (eq. 11) and the reported SNR, checked statistically."""
import math

import numpy as np
import pytest
from scipy import stats

from gmtiflow import rng
from gmtiflow.sensor import detect

N = 40_000


def uniforms(purpose="pd", n=N):
    key = rng.counter_key(123, "sensor", purpose)
    return rng.pair_uniform(key, np.arange(n) // 100, np.arange(n) % 100)


def binomial_ok(k, n, p, z=4.5):
    return abs(k - n * p) <= z * math.sqrt(n * p * (1 - p)) + 1


@pytest.mark.parametrize("snr_db", [-5.0, 5.0, 10.0, 13.0, 16.0, 20.0])
def test_empirical_detection_rate_matches_pd(snr_db):
    pfa = 1e-6
    s = 10 ** (snr_db / 10)
    p = float(detect.pd(s, pfa))
    hits = int(detect.detected(uniforms(), np.full(N, s), pfa).sum())
    assert binomial_ok(hits, N, p), (hits, N * p)


def test_pd_limits_without_nan_or_overflow():
    with np.errstate(all="raise"):
        for pfa in (1e-15, 1e-12, 1e-6, 0.1):
            p = detect.pd(np.array([0.0, 1e-12, 1e-3, 1e12]), pfa)
            assert np.all(np.isfinite(p))
            assert p[0] == pytest.approx(pfa, rel=1e-12)
            assert p[1] == pytest.approx(pfa, rel=1e-9)
            assert p[3] == pytest.approx(1.0, abs=1e-10)
            lp = detect.log_pd(np.array([1e-12, 1e12]), pfa)
            assert lp[0] == pytest.approx(math.log(pfa), rel=1e-11)
            assert -lp[1] == pytest.approx(-math.log(pfa) / (1 + 1e12), rel=1e-9)


def test_pd_is_monotone_in_snr():
    s = np.logspace(-12, 12, 500)
    p = detect.pd(s, 1e-6)
    assert np.all(np.diff(p) >= 0)


@pytest.mark.parametrize("snr_db", [8.0, 15.0, 25.0])
def test_reported_snr_given_detection_is_threshold_plus_exponential(snr_db):
    """z = −(1+S) ln U; given z > T = −ln P_FA, (z − T)/(1 + S) ~ Exp(1) (memoryless)."""
    pfa = 1e-6
    s = 10 ** (snr_db / 10)
    u = uniforms("fluct")
    hit = detect.detected(u, np.full(N, s), pfa)
    z = detect.reported_snr(u[hit], s) + 1.0
    t = -math.log(pfa)
    assert np.all(z > t)
    excess = (z - t) / (1 + s)
    assert stats.kstest(excess, "expon").pvalue > 1e-4


def test_reported_snr_is_unbiased_over_all_looks():
    s = 100.0
    u = uniforms("bias")
    est = detect.reported_snr(u, s)
    # E[z − 1] = S, Var = (1 + S)²
    assert abs(est.mean() - s) < 4.5 * (1 + s) / math.sqrt(N)
