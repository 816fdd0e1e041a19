"""Range folding, Doppler wrapping, blind speeds and the plausibility of folded reports (§5.5)."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gmtiflow.sensor import ambiguity as amb

C = 299_792_458.0


def test_unambiguous_range_is_c_pri_over_two():
    assert amb.unambiguous_range_m(3000.0) == pytest.approx(C / 3000.0 / 2.0, rel=1e-15)
    assert amb.unambiguous_range_m(3000.0) == pytest.approx(49_965.4097, abs=1e-3)


def test_target_beyond_c_pri_over_two_appears_at_the_folded_range():
    prf = 3000.0
    ru = amb.unambiguous_range_m(prf)
    folded, folds = amb.fold_range([55_000.0, 30_000.0, 2 * ru + 1234.5, ru, 0.0, np.nextafter(ru, 0)], prf)
    assert folded[5] == np.nextafter(ru, 0) and folds[5] == 0
    assert folded[0] == pytest.approx(55_000.0 - ru, abs=1e-9) and folds[0] == 1
    assert folded[1] == 30_000.0 and folds[1] == 0          # inside R_u: untouched, bit for bit
    assert folded[2] == pytest.approx(1234.5, abs=1e-8) and folds[2] == 2
    assert folded[3] == 0.0 and folds[3] == 1                # exactly R_u folds to 0
    assert folded[4] == 0.0 and folds[4] == 0


@settings(max_examples=200, deadline=None)
@given(r=st.floats(0.0, 1e6), prf=st.floats(200.0, 50_000.0))
def test_folded_range_is_in_zero_to_ru(r, prf):
    folded, folds = amb.fold_range(r, prf)
    ru = amb.unambiguous_range_m(prf)
    assert 0.0 <= folded < ru
    assert folded + folds * ru == pytest.approx(r, rel=1e-12, abs=1e-6)


def test_wrap_velocity_is_lambda_prf_over_four():
    assert amb.wrap_velocity_mps(0.03, 2000.0) == pytest.approx(15.0, rel=1e-15)
    assert amb.wrap_velocity_mps(0.03125, 2048.0) == 16.0


def test_range_rate_wrap_is_exact_at_the_interval_edges():
    lam, prf = 0.03125, 2048.0  # v_w = 16 m/s exactly
    rr = np.array([16.0, -16.0, np.nextafter(16.0, 0.0), 48.0, -48.0, 17.0, -17.0, 0.0, 32.0])
    wrapped, wraps = amb.wrap_range_rate(rr, lam, prf)
    assert wrapped.tolist() == [-16.0, -16.0, np.nextafter(16.0, 0.0), -16.0, -16.0, -15.0, 15.0, 0.0, 0.0]
    assert wraps.tolist() == [1, 0, 0, 2, -1, 1, -1, 0, 1]
    # Non-binary values: the edge computed the same way still maps +v_w to -v_w.
    vw = amb.wrap_velocity_mps(0.031, 3000.0)
    w, k = amb.wrap_range_rate(np.array([vw, -vw]), 0.031, 3000.0)
    assert w.tolist() == [-vw, -vw] and k.tolist() == [1, 0]


@settings(max_examples=300, deadline=None)
@given(rr=st.floats(-500.0, 500.0), lam=st.floats(0.005, 0.3), prf=st.floats(200.0, 30_000.0))
def test_wrapped_range_rate_is_in_the_half_open_interval(rr, lam, prf):
    vw = amb.wrap_velocity_mps(lam, prf)
    w, k = amb.wrap_range_rate(rr, lam, prf)
    assert -vw <= w < vw
    assert w + 2 * k * vw == pytest.approx(rr, rel=1e-12, abs=1e-9)


def test_blind_speeds_reproduce():
    lam, prf = 0.03, 2000.0
    v = amb.blind_speeds_mps(lam, prf, 3)
    assert v == pytest.approx([0.0, 30.0, 60.0, 90.0], rel=1e-14)
    # A target moving at a blind speed aliases onto the clutter ridge (range rate 0 mod λ·PRF/2).
    wrapped, _ = amb.wrap_range_rate(v, lam, prf)
    assert np.abs(wrapped) == pytest.approx(0.0, abs=1e-12)
    assert amb.distance_to_blind_speed(np.array([29.0, 31.5, 45.0, -59.0]), lam, prf) == pytest.approx(
        [1.0, 1.5, 15.0, 1.0], abs=1e-12)


def test_folded_report_below_the_platform_is_implausible():
    h = 8000.0
    below, beyond = amb.implausible_range([5000.0, 9000.0, 8000.0, 400_000.0], h)
    assert below.tolist() == [True, False, False, False]
    assert beyond.tolist() == [False, False, False, True]
    horizon = amb.radar_horizon_m(h)
    assert horizon == pytest.approx(np.sqrt(2 * 4 / 3 * 6_371_008.8 * h + h * h), rel=1e-12)
    assert 360e3 < horizon < 380e3   # the 4/3-earth rule of thumb: 4.12 km * sqrt(h/m)
    g = amb.ground_range_from_slant([5000.0, 8000.0, 20_000.0, horizon * 1.001], h)
    assert np.isnan(g[0]) and g[1] == pytest.approx(0.0, abs=1e-3) and np.isnan(g[3])
    assert g[2] == pytest.approx(np.sqrt(20_000.0 ** 2 - h ** 2), rel=2e-3)   # ~flat earth nearby


def test_apply_ambiguities_sets_the_flags():
    prf, lam, h = 3000.0, 0.03, 8000.0
    ru = amb.unambiguous_range_m(prf)
    out = amb.apply_ambiguities([30_000.0, ru + 5000.0, ru + 20_000.0], [10.0, -30.0, 44.0], lam, prf,
                                height_agl_m=h)
    assert out["range_folded"].tolist() == [False, True, True]
    assert out["range_m"][1] == pytest.approx(5000.0, abs=1e-8)
    assert out["doppler_wrapped"].tolist() == [False, True, True]   # v_w = 22.5 m/s
    assert out["range_rate_mps"].tolist() == pytest.approx([10.0, 15.0, -1.0])
    assert out["below_surface"].tolist() == [False, True, False]
    assert out["implausible"].tolist() == [False, True, False]
    assert np.all(out["wrap_velocity_mps"] == amb.wrap_velocity_mps(lam, prf))


def test_nothing_to_fold_or_wrap_returns_the_general_steps_values():
    """All ranges inside [0, R_u) and all range rates inside [−v_w, v_w): the shortcut gives
    what the folding and wrapping steps give (values, signed zeros, dtypes), as checked by
    running the same values with one outlier appended (the general path)."""
    g = np.random.default_rng(3)
    prf, lam = 4000.0, 0.03
    ru = amb.unambiguous_range_m(prf)
    vw = amb.wrap_velocity_mps(lam, prf)
    r = np.concatenate([g.uniform(0.0, ru, 500), [0.0, -0.0, np.nextafter(ru, 0.0)]])
    rr = np.concatenate([g.uniform(-vw, vw, 500), [-vw, -0.0, np.nextafter(vw, 0.0)]])
    for fn, x, out, args in ((amb.fold_range, r, 2.5 * ru, (prf,)),
                             (amb.wrap_range_rate, rr, 3.5 * vw, (lam, prf))):
        fast = fn(x, *args)
        general = fn(np.append(x, out), *args)
        assert fast[0].tobytes() == general[0][:-1].tobytes()
        assert fast[1].dtype == general[1].dtype and np.array_equal(fast[1], general[1][:-1])
        assert not np.shares_memory(fast[0], x)
