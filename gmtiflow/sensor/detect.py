"""Swerling-I detection and the reported (fluctuated) SNR (paper eq. 11, DESIGN §5 step 4).

Model.  After coherent integration the detector compares the normalised power
z = |s + n|² / N₀ with a threshold T.  For a Swerling-I target (Rayleigh amplitude, constant over
the CPI) plus complex Gaussian noise, z is exponential with mean 1 + SNR, SNR the mean
signal-to-noise ratio of the look.  Noise alone (SNR = 0) exceeds T with P_FA = e^{−T}, so
T = −ln P_FA, and

.. math::

    P_D = \\Pr(z > T) = e^{-T/(1+\\mathrm{SNR})} = P_{FA}^{1/(1+\\mathrm{SNR})},
    \\qquad \\ln P_D = \\frac{\\ln P_{FA}}{1 + \\mathrm{SNR}}

(eq. 11), evaluated in log space: finite and exact for P_FA = 1e-15 and SNR from 1e-12 to 1e12.

One uniform ``U`` per (dwell, target) pair drives both the decision and the reported SNR: by
inversion, ``z = −(1 + SNR) ln U`` is exactly the exponential detector output, and
``z > T  ⇔  ln U < ln P_D  ⇔  U < P_D``.  Given detection, z = T + (1 + SNR)·E with E ~ Exp(1)
(memorylessness), i.e. the Swerling-I power conditioned on exceeding the threshold.  The reported
SNR is the processor's noise-subtracted estimate ``z − 1`` (unbiased over all looks:
E[z − 1] = SNR), floored at :data:`gmtiflow.sensor.snr.SNR_MIN`.  It is always ≥ T − 1, so weak
targets that are detected report at least the threshold SNR, as real plots do.

A noise false alarm follows the same convention (:func:`false_alarm_snr`): noise alone gives
z ~ Exp(1); given that it crossed T, z = T + E (memoryless) and the reported SNR is z − 1 ≥ T − 1,
the same floor as a target's.  (For P_FA > 1/e, T − 1 < 0 and the floor SNR_MIN applies.)
"""
from __future__ import annotations

import numpy as np

from gmtiflow.sensor.snr import SNR_MIN


def log_pd(snr, pfa: float):
    """ln P_D = ln P_FA / (1 + SNR) (finite for any SNR ≥ 0 and 0 < P_FA < 1)."""
    return np.log(pfa) / (1.0 + np.asarray(snr, float))


def pd(snr, pfa: float):
    """P_D = P_FA^{1/(1+SNR)} (eq. 11)."""
    return np.exp(log_pd(snr, pfa))


def detected(uniform, snr, pfa: float):
    """The Swerling-I decision U < P_D, made in log space."""
    return np.log(uniform) < log_pd(snr, pfa)


def reported_snr(uniform, snr, log_uniform=None):
    """Noise-subtracted detector output z − 1 with z = −(1 + SNR) ln U (linear); ``log_uniform``:
    ln U when the caller has it (the detection decision took it), ``uniform`` is then not read."""
    if log_uniform is None:
        log_uniform = np.log(uniform)
    z = -(1.0 + np.asarray(snr, float)) * log_uniform
    return np.maximum(z - 1.0, SNR_MIN)


def threshold(pfa: float) -> float:
    """Detection threshold T = −ln P_FA on z = |s + n|²/N₀ (linear)."""
    return -np.log(pfa)


def false_alarm_snr(uniform, pfa: float):
    """Reported SNR z − 1 of a noise false alarm, z = T − ln U (noise above the threshold)."""
    z = threshold(pfa) - np.log(np.asarray(uniform, float))
    return np.maximum(z - 1.0, SNR_MIN)
