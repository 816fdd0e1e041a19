"""Batched constant-velocity Kalman filter in the ground plane, with an optional range-rate EKF row.

State ``[x, y, vx, vy]`` (ENU metres, m/s).  Every function works on a batch of tracks at once
(leading axis ``n``), so one dwell's predictions, gates and updates are a handful of numpy calls.

Motion model: constant velocity, per axis ``F = [[1, T], [0, 1]]``, with one of two process
noises (Bar-Shalom, Li & Kirubarajan 2001, §6.2.2 and §6.3.3), σ_a = ``accel_sigma_mps2``:

* ``"cwna"`` (default) *continuous* white-noise acceleration with power spectral density
  q = σ_a²·(1 s) (so σ_a is the acceleration σ averaged over one second):

  .. math::  Q = q \\begin{pmatrix}T^3/3 & T^2/2\\\\ T^2/2 & T\\end{pmatrix}.

* ``"dwna"`` *discrete* white-noise acceleration, constant over the step:

  .. math::  Q = σ_a^2 \\begin{pmatrix}T^4/4 & T^3/2\\\\ T^3/2 & T^2\\end{pmatrix}.

The DWNA ``Q`` has rank 1 per axis: it says the position and velocity errors a step adds are
exactly tied (δp = δv·T/2).  A GMTI plot measures range to ~0.3 m and range rate to ~0.05 m/s,
so along the line of sight both are nearly exact and a road vehicle that turned or changed speed
during a 5–10 s gap breaks that tie: its innovation lands in a direction the DWNA filter holds
almost certain, and the χ² gate rejects the right plot (on the default scene this lost tracks
and started duplicates).  The CWNA ``Q`` is full rank (correlation √3/2) and makes no such claim.

The tracker always predicts from a track's *last update* (a missed dwell does not store a
prediction), so ``T`` is the time since the last measurement and the model is not re-applied in
small pieces.

Measurements: the ground position ``(x_m, y_m)`` of a detection, whose covariance is diagonal in
(along the line of sight, cross range) and rotated by the LOS azimuth ``a`` (clockwise from north):

.. math::  R = σ_\\parallel^2\\,u u^T + σ_\\perp^2\\,w w^T,\\quad u = (\\sin a, \\cos a),\\;
           w = (\\cos a, -\\sin a),

with ``σ_⊥ = R_slant σ_az`` and ``σ_∥ = σ_r R_slant / ρ`` (a slant-range error projected onto flat
ground at ground range ``ρ``).  Optionally the range rate

.. math::  \\dot r = \\frac{(p - p_p)\\cdot(v - v_p)}{|p - p_p|}

(target ``p = (x, y, z)``, ``v = (vx, vy, 0)``; platform ``p_p, v_p``; + = receding) is a third,
nonlinear measurement row, linearised at the prediction (extended Kalman filter).
"""
from __future__ import annotations

import numpy as np

_EYE4 = np.eye(4)[None]


def cv_predict(x: np.ndarray, P: np.ndarray, dt_s: np.ndarray, accel_sigma_mps2: float,
               model: str = "cwna"):
    """Predict states ``x`` (n, 4) and covariances ``P`` (n, 4, 4) over ``dt_s`` (n,).

    ``model`` is the process noise, ``"cwna"`` or ``"dwna"`` (module docstring)."""
    dt = np.asarray(dt_s, float)
    n = len(x)
    F = np.broadcast_to(_EYE4, (n, 4, 4)).copy()
    F[:, 0, 2] = dt
    F[:, 1, 3] = dt
    q = accel_sigma_mps2 ** 2
    Q = np.zeros((n, 4, 4))
    if model == "cwna":
        pp, pv, vv = q * dt ** 3 / 3.0, q * dt ** 2 / 2.0, q * dt
    elif model == "dwna":
        pp, pv, vv = q * dt ** 4 / 4.0, q * dt ** 3 / 2.0, q * dt ** 2
    else:
        raise ValueError(f"process noise model must be 'cwna' or 'dwna', got {model!r}")
    for a, b in ((0, 2), (1, 3)):
        Q[:, a, a] = pp
        Q[:, a, b] = Q[:, b, a] = pv
        Q[:, b, b] = vv
    x_new = np.einsum("nij,nj->ni", F, x)
    P_new = F @ P @ np.transpose(F, (0, 2, 1)) + Q
    return x_new, P_new


def extrapolate_position(x: np.ndarray, dt_s) -> np.ndarray:
    """Constant-velocity position after ``dt_s`` (no covariance): (n, 2)."""
    return x[:, :2] + x[:, 2:4] * np.asarray(dt_s, float)[:, None]


def position_covariance(los_az_rad, sigma_along_m, sigma_cross_m) -> np.ndarray:
    """(n, 2, 2) ENU covariances of ground positions, from σ along / across the LOS azimuth."""
    a = np.asarray(los_az_rad, float)
    u = np.stack([np.sin(a), np.cos(a)], axis=-1)
    w = np.stack([np.cos(a), -np.sin(a)], axis=-1)
    sa = np.asarray(sigma_along_m, float)[:, None, None]
    sc = np.asarray(sigma_cross_m, float)[:, None, None]
    return sa ** 2 * u[:, :, None] * u[:, None, :] + sc ** 2 * w[:, :, None] * w[:, None, :]


def predicted_range_rate(x: np.ndarray, z_m: np.ndarray, platform_pos: np.ndarray,
                         platform_vel: np.ndarray):
    """Range rate ``h(x)`` (n,) and its Jacobian row (n, 4) w.r.t. ``[x, y, vx, vy]``.

    Written out per component (no (n, 3) stacks): ``|d|`` sums the squares in the order
    ``np.linalg.norm`` does and ``d·w`` in the order ``np.einsum("ni,ni->n")`` does, so the
    values are those of the stacked form bit for bit (``tests/evaluate/test_kalman.py``)."""
    d0 = x[:, 0] - platform_pos[0]
    d1 = x[:, 1] - platform_pos[1]
    d2 = np.asarray(z_m, float) - platform_pos[2]
    w0 = x[:, 2] - platform_vel[0]
    w1 = x[:, 3] - platform_vel[1]
    w2 = -platform_vel[2]
    r = np.sqrt((d0 * d0 + d1 * d1) + d2 * d2)
    r = np.where(r > 0.0, r, 1.0)
    dw = (d0 * w0 + d2 * w2) + d1 * w1
    h = dw / r
    r3 = r ** 3
    J = np.empty((len(x), 4))
    J[:, 0] = w0 / r - dw * d0 / r3
    J[:, 1] = w1 / r - dw * d1 / r3
    J[:, 2] = d0 / r
    J[:, 3] = d1 / r
    return h, J


def _predicted_range_rate_stacked(x, z_m, platform_pos, platform_vel):
    """The stacked form :func:`predicted_range_rate` reproduces (kept for its test)."""
    d = np.stack([x[:, 0] - platform_pos[0], x[:, 1] - platform_pos[1],
                  np.asarray(z_m, float) - platform_pos[2]], axis=-1)
    w = np.stack([x[:, 2] - platform_vel[0], x[:, 3] - platform_vel[1],
                  np.broadcast_to(-platform_vel[2], len(x))], axis=-1)
    r = np.linalg.norm(d, axis=-1)
    r = np.where(r > 0.0, r, 1.0)
    dw = np.einsum("ni,ni->n", d, w)
    h = dw / r
    J = np.empty((len(x), 4))
    J[:, 0] = w[:, 0] / r - dw * d[:, 0] / r ** 3
    J[:, 1] = w[:, 1] / r - dw * d[:, 1] / r ** 3
    J[:, 2] = d[:, 0] / r
    J[:, 3] = d[:, 1] / r
    return h, J


def wrap_symmetric(value, half_period):
    """Wrap ``value`` into [-half_period, half_period); NaN/inf half-periods leave it unchanged."""
    value = np.asarray(value, float)
    hp = np.asarray(half_period, float)
    finite = np.isfinite(hp) & (hp > 0)
    safe = np.where(finite, hp, 1.0)
    wrapped = np.mod(value + safe, 2.0 * safe) - safe
    return np.where(finite, wrapped, value)


def innovations(x: np.ndarray, P: np.ndarray, H: np.ndarray, h: np.ndarray, z: np.ndarray,
                R: np.ndarray, rr_half_period=None, gate=None):
    """Innovations and squared Mahalanobis distances of every (track, detection) pair.

    ``x`` (nt, 4), ``P`` (nt, 4, 4); ``H`` (nt, m, 4) and ``h`` (nt, m) the linearised measurement
    model per track; ``z`` (nd, m) and ``R`` (nd, m, m) per detection.  Returns ``nu``
    (nt, nd, m), ``HPHt`` (nt, m, m) (so ``S = HPHt[i] + R[j]``) and ``d2`` (nt, nd).  When
    ``rr_half_period`` (nd,) is given, the third (range-rate) innovation is wrapped into
    ± that value (Doppler ambiguity, λ·PRF/4).

    With ``gate``, ``d2`` is computed only for pairs that can be inside it and is ``inf``
    elsewhere.  The pre-test is exact: the Mahalanobis distance of the full innovation is at
    least that of its position part, which is at least ``‖ν_pos‖² / λ_max(S_pos)``, and
    ``λ_max(S_pos) ≤ tr(S_pos) = tr(HPHᵀ_pos) + tr(R_pos)``.
    """
    nu = z[None, :, :] - h[:, None, :]
    if rr_half_period is not None and z.shape[1] == 3:
        nu[:, :, 2] = wrap_symmetric(nu[:, :, 2], np.asarray(rr_half_period)[None, :])
    HPHt = H @ P @ np.transpose(H, (0, 2, 1))
    if gate is None:
        ti, di = np.nonzero(np.ones(nu.shape[:2], bool))
    else:
        bound = (np.trace(HPHt[:, :2, :2], axis1=1, axis2=2)[:, None]
                 + np.trace(R[:, :2, :2], axis1=1, axis2=2)[None, :])
        ti, di = np.nonzero((nu[:, :, :2] ** 2).sum(axis=-1) <= gate * bound)
    d2 = np.full(nu.shape[:2], np.inf)
    if len(ti):
        S = HPHt[ti] + R[di]
        v = nu[ti, di]
        d2[ti, di] = np.einsum("ni,ni->n", v, np.linalg.solve(S, v[..., None])[..., 0])
    return nu, HPHt, d2


def kalman_update(x: np.ndarray, P: np.ndarray, H: np.ndarray, nu: np.ndarray, S: np.ndarray,
                  R: np.ndarray):
    """Joseph-form update of n (track, measurement) pairs; all arrays batched on axis 0."""
    K = np.transpose(np.linalg.solve(S, H @ P), (0, 2, 1))          # P Hᵀ S⁻¹ (S symmetric)
    x_new = x + np.einsum("nij,nj->ni", K, nu)
    IKH = _EYE4 - K @ H
    P_new = IKH @ P @ np.transpose(IKH, (0, 2, 1)) + K @ R @ np.transpose(K, (0, 2, 1))
    P_new = 0.5 * (P_new + np.transpose(P_new, (0, 2, 1)))
    return x_new, P_new


def gated_pairs(x_pos: np.ndarray, HPHt: np.ndarray, z: np.ndarray, R: np.ndarray, h: np.ndarray,
                rr_half_period, gate: float):
    """The (track, detection) pairs inside ``gate`` and their innovations, without the dense
    (nt, nd) matrices of :func:`innovations` (linear in tracks + detections at a fixed density).

    Candidates come from a k-d tree of the detections' positions, searched around each track's
    predicted position ``x_pos`` (nt, 2) within ``sqrt(gate · (tr HPHᵀ_pos + max tr R_pos))`` (a
    superset of the exact pre-test of :func:`innovations`); then the same pre-test and the same
    per-pair arithmetic as :func:`innovations`, so ``d2`` is bit-identical for every pair.
    Returns ``ti, di`` (sorted by track, then detection), ``nu`` (n, m) and ``d2`` (n,) of the
    pairs with ``d2 < gate``.
    """
    from scipy.spatial import cKDTree
    nt, m = len(x_pos), z.shape[1]
    tr_p = HPHt[:, 0, 0] + HPHt[:, 1, 1]       # the traces of the position blocks
    tr_r = R[:, 0, 0] + R[:, 1, 1]
    radius = np.sqrt(gate * (tr_p + tr_r.max(initial=0.0))) * (1.0 + 1e-9) + 1e-9
    hits = cKDTree(z[:, :2]).query_ball_point(x_pos, radius)
    counts = np.fromiter((len(k) for k in hits), np.int64, nt)
    ti = np.repeat(np.arange(nt, dtype=np.int64), counts)
    di = (np.concatenate([np.sort(np.asarray(k, np.int64)) for k in hits]) if counts.sum()
          else np.zeros(0, np.int64))
    nu = z[di] - h[ti]
    if rr_half_period is not None and m == 3:
        nu[:, 2] = wrap_symmetric(nu[:, 2], np.asarray(rr_half_period)[di])
    keep = (nu[:, :2] ** 2).sum(axis=-1) <= gate * (tr_p[ti] + tr_r[di])
    ti, di, nu = ti[keep], di[keep], nu[keep]
    return _inside_gate(HPHt, R, ti, di, nu, gate)


def dense_gated_pairs(HPHt: np.ndarray, z: np.ndarray, R: np.ndarray, h: np.ndarray,
                      rr_half_period, gate: float):
    """:func:`gated_pairs` for a small dwell: the exact pre-test of :func:`innovations` on every
    (track, detection) pair at once, then the innovations and distances of the pairs that pass
    it only (not the dense (nt, nd, m) innovations).  The pairs, ``nu`` and ``d2`` are those of
    :func:`innovations` bit for bit (``tests/evaluate/test_kalman.py``); the same outputs as
    :func:`gated_pairs` (``ti, di`` sorted by track, then detection)."""
    m = z.shape[1]
    dx = z[None, :, 0] - h[:, None, 0]
    dy = z[None, :, 1] - h[:, None, 1]
    # traces of the position blocks (two terms: the sum np.trace makes)
    bound = ((HPHt[:, 0, 0] + HPHt[:, 1, 1])[:, None] + (R[:, 0, 0] + R[:, 1, 1])[None, :])
    ti, di = np.nonzero(dx * dx + dy * dy <= gate * bound)
    nu = z[di] - h[ti]
    if rr_half_period is not None and m == 3:
        nu[:, 2] = wrap_symmetric(nu[:, 2], np.asarray(rr_half_period)[di])
    return _inside_gate(HPHt, R, ti, di, nu, gate)


def _inside_gate(HPHt, R, ti, di, nu, gate: float):
    """The pairs ``(ti, di)`` with innovations ``nu`` whose squared Mahalanobis distance under
    S = HPHᵀ + R is below ``gate``: ``ti, di, nu, d2`` of those (the last step of
    :func:`gated_pairs` and :func:`dense_gated_pairs`)."""
    d2 = np.full(len(ti), np.inf)
    if len(ti):
        S = HPHt[ti] + R[di]
        d2 = np.einsum("ni,ni->n", nu, np.linalg.solve(S, nu[..., None])[..., 0])
    inside = d2 < gate
    return ti[inside], di[inside], nu[inside], d2[inside]
