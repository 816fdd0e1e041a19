"""Kalman building blocks: range-rate Jacobian, LOS covariance, gated assignment."""
import numpy as np
import pytest

from gmtiflow.evaluate import kalman
from gmtiflow.evaluate.assignment import gated_assignment


def test_range_rate_jacobian_matches_finite_differences():
    rng = np.random.default_rng(0)
    x = rng.normal([1000.0, 2000.0, 5.0, -3.0], [500.0, 500.0, 5.0, 5.0], (6, 4))
    z = rng.normal(0.0, 50.0, 6)
    pp, pv = np.array([-5000.0, -30000.0, 6000.0]), np.array([150.0, 10.0, 1.0])
    h, J = kalman.predicted_range_rate(x, z, pp, pv)
    for i in range(4):
        dx = np.zeros(4)
        dx[i] = 1e-3
        hp, _ = kalman.predicted_range_rate(x + dx, z, pp, pv)
        hm, _ = kalman.predicted_range_rate(x - dx, z, pp, pv)
        np.testing.assert_allclose(J[:, i], (hp - hm) / 2e-3, rtol=1e-5, atol=1e-9)
    # a target receding along the LOS at 5 m/s with a still platform: +5
    h, _ = kalman.predicted_range_rate(np.array([[0.0, 1000.0, 0.0, 5.0]]), np.zeros(1),
                                       np.zeros(3), np.zeros(3))
    assert h[0] == pytest.approx(5.0)


def test_range_rate_written_out_is_the_stacked_form_bit_for_bit():
    # the per-component arithmetic must add in numpy's order (norm: (0+1)+2, einsum: (0+2)+1);
    # magnitudes over many decades make a different order show in the last bits
    rng = np.random.default_rng(3)
    for n in (0, 1, 7, 1000):
        x = rng.normal(0, 1, (n, 4)) * 10.0 ** rng.integers(-2, 6, (n, 4))
        z = rng.normal(0, 100, n)
        pp = rng.normal(0, 1, 3) * 10.0 ** rng.integers(0, 6, 3)
        pv = rng.normal(0, 100, 3)
        h, J = kalman.predicted_range_rate(x, z, pp, pv)
        h0, J0 = kalman._predicted_range_rate_stacked(x, z, pp, pv)
        assert np.array_equal(h, h0) and np.array_equal(J, J0)


def test_position_covariance_is_along_and_across_the_los():
    # LOS to the north-east (45°): along = (1,1)/√2
    R = kalman.position_covariance(np.array([np.pi / 4]), np.array([20.0]), np.array([5.0]))[0]
    u = np.array([1.0, 1.0]) / np.sqrt(2)
    w = np.array([1.0, -1.0]) / np.sqrt(2)
    assert u @ R @ u == pytest.approx(400.0)
    assert w @ R @ w == pytest.approx(25.0)
    assert u @ R @ w == pytest.approx(0.0, abs=1e-12)


def test_cv_predict_moves_and_grows():
    x = np.array([[0.0, 0.0, 2.0, -1.0]])
    P = np.eye(4)[None]
    xp, Pp = kalman.cv_predict(x, P, np.array([3.0]), 1.0, "dwna")
    np.testing.assert_allclose(xp[0], [6.0, -3.0, 2.0, -1.0])
    # var(x) = P_xx + T² P_vv + σ² T⁴/4 = 1 + 9 + 81/4
    assert Pp[0, 0, 0] == pytest.approx(1 + 9 + 81 / 4)
    xc, Pc = kalman.cv_predict(x, P, np.array([3.0]), 1.0)          # default: cwna
    np.testing.assert_allclose(xc[0], xp[0])
    # var(x) = 1 + 9 + q T³/3, cov(x, vx) = T P_vv + q T²/2, var(vx) = 1 + q T
    assert Pc[0, 0, 0] == pytest.approx(1 + 9 + 27 / 3)
    assert Pc[0, 0, 2] == pytest.approx(3 + 9 / 2)
    assert Pc[0, 2, 2] == pytest.approx(1 + 3)


def test_process_noise_rank():
    # DWNA adds a rank-1 Q per axis (position and velocity errors tied); CWNA a full-rank one.
    zero = np.zeros((1, 4, 4))
    _, Qd = kalman.cv_predict(np.zeros((1, 4)), zero, np.array([10.0]), 1.0, "dwna")
    _, Qc = kalman.cv_predict(np.zeros((1, 4)), zero, np.array([10.0]), 1.0, "cwna")
    axis = [0, 2]
    assert np.linalg.matrix_rank(Qd[0][np.ix_(axis, axis)], tol=1e-9) == 1
    corr = Qc[0, 0, 2] / np.sqrt(Qc[0, 0, 0] * Qc[0, 2, 2])
    assert corr == pytest.approx(np.sqrt(3) / 2)
    with pytest.raises(ValueError):
        kalman.cv_predict(np.zeros((1, 4)), zero, np.array([1.0]), 1.0, "singer")


def test_gated_assignment_is_global_and_respects_the_gate():
    cost = np.array([[1.0, 2.0], [1.5, 100.0]])
    r, c = gated_assignment(cost, gate=10.0)
    assert list(zip(r, c)) == [(0, 1), (1, 0)]          # 2 + 1.5 < 1 + (miss)
    r, c = gated_assignment(np.array([[11.0, 12.0]]), gate=10.0)
    assert len(r) == 0
    r, c = gated_assignment(np.array([[9.0], [1.0]]), gate=10.0)
    assert list(zip(r, c)) == [(1, 0)]


def test_wrap_symmetric():
    np.testing.assert_allclose(kalman.wrap_symmetric([11.0, -11.0, 3.0], 10.0), [-9.0, 9.0, 3.0])
    assert kalman.wrap_symmetric(25.0, np.nan) == 25.0


def test_gated_innovations_equal_the_full_ones_inside_the_gate():
    rng = np.random.default_rng(1)
    nt, nd, gate = 30, 40, 16.0
    x = np.column_stack([rng.uniform(0, 2000, (nt, 2)), rng.normal(0, 5, (nt, 2))])
    A = rng.normal(0, 1, (nt, 4, 4))
    P = A @ np.transpose(A, (0, 2, 1)) * 400 + np.eye(4) * 10
    H = np.zeros((nt, 3, 4))
    H[:, 0, 0] = H[:, 1, 1] = 1.0
    H[:, 2, :] = rng.normal(0, 0.5, (nt, 4))
    h = np.column_stack([x[:, :2], rng.normal(0, 5, nt)])
    z = np.column_stack([rng.uniform(0, 2000, (nd, 2)), rng.normal(0, 5, nd)])
    B = rng.normal(0, 1, (nd, 3, 3))
    R = B @ np.transpose(B, (0, 2, 1)) * 100 + np.eye(3)
    nu, HPHt, full = kalman.innovations(x, P, H, h, z, R)
    _, _, gated = kalman.innovations(x, P, H, h, z, R, gate=gate)
    inside = full <= gate
    assert inside.sum() > 5
    np.testing.assert_allclose(gated[inside], full[inside], rtol=1e-12)
    assert np.all(gated[~inside] > gate)
    # and the full ones are the textbook ν' S⁻¹ ν
    i, j = np.argwhere(inside)[0]
    S = H[i] @ P[i] @ H[i].T + R[j]
    assert full[i, j] == pytest.approx(nu[i, j] @ np.linalg.solve(S, nu[i, j]))
