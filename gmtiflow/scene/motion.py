r"""Speed-profile kernel: arc length s(t) of every vehicle, vectorised over the fleet (DESIGN §3).

The paper's Alg. 1–2 move a position step by step and patch the overshoot at a crossroad
(Fig. 1). Here a vehicle is only a speed profile along its route polyline: on a time grid
:math:`\tau_k = k\,\Delta t` (local time since the profile's start) each step stores the arc length
:math:`s_k`, the speed :math:`v_k` at the step start, a constant acceleration :math:`a_k` that acts
for :math:`\tau'_k \le \Delta t` (the exact in-step instant at which a braking vehicle reaches
:math:`v = 0`; afterwards the speed stays :math:`v_{k+1}`), and a mode label. Hence for
:math:`u = \tau - \tau_k`

.. math::
    s(\tau) = s_k + v_k u + \tfrac12 a_k u^2 \quad (u < \tau'_k), \qquad
    s(\tau) = s_{k+1} - v_{k+1} (\Delta t - u) \quad (u \ge \tau'_k),

exact at any instant, so the position on the route polyline needs no overshoot correction and
no interpolation error.

One time loop runs over the steps; every operation inside is numpy over all profiles (there is no
per-vehicle Python loop). Per profile a small state machine (the corrected Alg. 2, DESIGN §3):

* ``TRACK`` (modes 0 cruise / 1 decelerate / 3 accelerate): the speed heads for the target
  :math:`v^* = \max(0, \min(c(s) + \sigma \xi_k, v_{cap}))` at the end of the step, where
  :math:`c(s)` is the cruise speed of the road segment at the current position (vehicle cruise,
  changed permanently at speed-change points, capped by the road's speed limit), :math:`\xi_k` a
  stationary standard Gauss–Markov (AR(1)) sequence,
  :math:`\xi_k = \rho \xi_{k-1} + \sqrt{1-\rho^2}\, n_k`, :math:`\rho = e^{-\Delta t/T_c}`
  (:math:`T_c` = speed_noise_corr_s; :math:`T_c = 0` gives the paper's independent per-step
  noise, with :math:`\sigma` the standard deviation either way), and :math:`v_{cap}` the
  braking curve (at 0.9 max_decel) towards any lower cruise speed further along the route, so a
  vehicle slows down *before* a lower limit or a speed-change point. The acceleration
  :math:`(v^*-v_k)/\Delta t` is clipped to
  :math:`[-d_{max}, a_{max}]`; the label is cruise when unclipped, accelerate/decelerate when
  clipped. Restarting from rest is therefore "accelerate at max_accel back to cruise".
* Random stop: a moving ``TRACK`` vehicle starts braking at :math:`d_{max}` when
  :math:`u_k < p = 1 - e^{-\lambda \Delta t}` (``rnd() < prob_stop``, DESIGN's correction of
  Alg. 2), i.e. a Poisson rate :math:`\lambda` per second of driving, independent of
  :math:`\Delta t`.
* Stop point ahead at :math:`s_{stop}`: when the look-ahead
  :math:`s + v\Delta t + \tfrac12 a_{max}\Delta t^2 + (v + a_{max}\Delta t)^2/(2 d_{max})`
  reaches it, brake with :math:`a = v^2 / (2 d)`, :math:`d = s_{stop}-s`, recomputed each step (so
  rounding does not accumulate). The stop happens at :math:`\tau' = 2d/v` inside the step and is
  stored as :math:`s_{k+1} = s_{stop}` exactly.
  A vehicle at rest within that look-ahead (it stopped at random just short of the point, at
  most :math:`\tfrac12 a_{max}\Delta t^2 + (a_{max}\Delta t)^2/(2 d_{max})`, 1.5 m at the
  defaults and dt = 1 s) counts the stop as made and drives on.
* ``STOPPED``: after the step in which it came to rest, the vehicle waits :math:`W` whole steps,
  :math:`W` geometric on {1, 2, …} with success probability :math:`q = \min(1, \Delta t/\bar w)`
  (mean :math:`\bar w` = mean_wait_s), drawn by inversion, capped at
  :math:`\lfloor w_{max}/\Delta t \rfloor` steps; then ``TRACK`` again.

Speed noise between grid points.  In a *free cruise* step (tracking, unclipped, not at the
speed floor or the braking cap, and the step's start speed the free target c + σξ_k of the
same cruise c) the speed is not the straight line between c + σξ_k and c + σξ_{k+1}: that
line's variance, σ²q(f) with :math:`q(f) = 1 - \kappa f(1-f)`, :math:`\kappa = 2(1-\rho)`,
f = u/Δt, dips to σ²(1+ρ)/2 mid-step (0.71 σ with T_c = 0).  Instead

.. math::
    v(u) = c + \sigma\,\frac{(1-f)\xi_k + f\xi_{k+1}}{\sqrt{q(f)}} ,

the linear interpolation normalised by its own standard deviation: exactly N(c, σ²) at every
instant, equal to the grid values at f = 0 and 1, and smooth inside the step.  The difference
from the straight line, δ(f) = L(f)(q^{-1/2} − 1) with L = σ((1-f)ξ_k + fξ_{k+1}), is a bridge
(zero at both ends) carried per step as ``bridge``/``noise_mps``; its integral (closed form, see
:func:`_bridge`) is added to s, and its derivative to the acceleration, so v = ds/dt and
a = dv/dt still hold exactly.  The bridge is applied only where it keeps v ≥ 0
(min(v_k, v_{k+1}) ≥ (√2 − 1) max |σξ|); elsewhere (accelerating, braking, capped) the step keeps
its constant acceleration.

Randomness enters only through pre-drawn per-profile arrays (speed normals, stop uniforms, wait
uniforms), drawn from each vehicle's own stream by the caller, so the kernel is deterministic.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import numpy as np

TRACK, BRAKE_RANDOM, STOPPED, BRAKE_POINT = 0, 1, 2, 4
_BRIDGE_GUARD = np.sqrt(2.0) - 1.0     # max of q^{-1/2} - 1 (kappa <= 2)


def _asinh_ratio(z):
    """asinh(z)/z, 1 at z = 0 (series below 1e-4)."""
    z = np.asarray(z, float)
    small = np.abs(z) < 1e-4
    safe = np.where(small, 1.0, z)
    return np.where(small, 1.0 - z * z / 6.0, np.arcsinh(safe) / safe)


def _bridge(x0, x1, kappa, f):
    """The free-cruise speed bridge of a step (module doc): δ(f), dδ/df and ∫_0^f δ df'.

    ``x0``, ``x1`` = σξ_k, σξ_{k+1} (m/s), ``kappa`` = 2(1 − ρ) in [0, 2], ``f`` in [0, 1].
    With g = f − ½, q = κg² + m (m = 1 − κ/4), L = A + Bg (A = (x0 + x1)/2, B = x1 − x0):
    ∫ L q^{-1/2} dg = A asinh(g√(κ/m))/√κ + (B/κ)√q, written stably for κ → 0 as
    A g m^{-1/2} asinh(z)/z and B(g² − ¼)/(√q + 1) from g = −½.
    """
    g = f - 0.5
    m = 1.0 - 0.25 * kappa
    q = kappa * g * g + m
    rq = 1.0 / np.sqrt(q)
    a = 0.5 * (x0 + x1)
    b = x1 - x0
    lin = a + b * g
    delta = lin * (rq - 1.0)
    d_delta = b * (rq - 1.0) - lin * kappa * g * rq ** 3
    rk = np.sqrt(kappa / m)

    def prim(gg):
        return a * gg / np.sqrt(m) * _asinh_ratio(gg * rk)

    integral_n = prim(g) - prim(-0.5) + b * (g * g - 0.25) / (np.sqrt(q) + 1.0)
    integral_l = x0 * f + 0.5 * b * f * f
    return delta, d_delta, integral_n - integral_l
MODE_CRUISE, MODE_DECEL, MODE_STOPPED, MODE_ACCEL = 0, 1, 2, 3


@dataclass
class ProfileInputs:
    """Per-profile inputs of :func:`simulate_profiles` (P profiles, flat per-segment arrays).

    seg_start_m: flat segment start arc lengths; profile p's segments are
        ``seg_offset[p]:seg_offset[p+1]``, sorted ascending within the profile.
    seg_target_mps: cruise target of each flat segment.
    stop_m: flat stop-point arc lengths (sorted within a profile), ``stop_offset`` as above.
    """

    length_m: np.ndarray          # (P,) arc length at which the profile is done
    v0_mps: np.ndarray            # (P,) initial speed
    seg_start_m: np.ndarray
    seg_target_mps: np.ndarray
    seg_offset: np.ndarray        # (P+1,)
    stop_m: np.ndarray
    stop_offset: np.ndarray       # (P+1,)
    max_accel_mps2: np.ndarray
    max_decel_mps2: np.ndarray
    speed_noise_mps: np.ndarray
    noise_rho: np.ndarray         # per-step correlation exp(-dt / corr) of the speed noise
    p_stop: np.ndarray            # per-step random stop probability
    q_wait: np.ndarray            # per-step release probability of the geometric wait
    max_wait_steps: np.ndarray    # int
    normal: np.ndarray            # (K, P) standard normals (speed noise)
    u_stop: np.ndarray            # (K, P) uniforms in (0, 1)
    u_wait: np.ndarray            # (K, P) uniforms in (0, 1)


@dataclass
class Profiles:
    """Speed profiles on the grid tau_k = k dt (K steps, P profiles)."""

    dt_s: float
    s_m: np.ndarray        # (K+1, P)
    v_mps: np.ndarray      # (K+1, P)
    a_mps2: np.ndarray     # (K, P)
    tau_s: np.ndarray      # (K, P) duration of a_k within the step
    mode: np.ndarray       # (K, P) uint8 label of the step
    noise_mps: Optional[np.ndarray] = None   # (K+1, P) σξ_k at the grid points
    bridge: Optional[np.ndarray] = None      # (K, P) bool: free-cruise step with the bridge
    kappa: Optional[np.ndarray] = None       # (P,) 2(1 − ρ) of the speed noise

    @property
    def n_steps(self) -> int:
        return self.a_mps2.shape[0]

    def evaluate(self, tau_s, p):
        """(s, v, a, mode) of profiles ``p`` at local times ``tau_s`` (broadcast arrays).

        Times are clipped to [0, K dt]; beyond the grid the last step's end state holds.
        """
        dt = self.dt_s
        K = self.n_steps
        tau = np.clip(np.asarray(tau_s, float), 0.0, K * dt)
        p = np.asarray(p, dtype=np.int64)
        k = np.clip(np.floor(tau / dt).astype(np.int64), 0, K - 1)
        u = tau - k * dt
        s0 = self.s_m[k, p]
        v0 = self.v_mps[k, p]
        s1 = self.s_m[k + 1, p]
        v1 = self.v_mps[k + 1, p]
        a = self.a_mps2[k, p]
        tk = self.tau_s[k, p]
        early = u < tk
        s = np.where(early, s0 + v0 * u + 0.5 * a * u * u, s1 - v1 * (dt - u))
        v = np.where(early, np.maximum(v0 + a * u, 0.0), v1)
        acc = np.where(early, a, 0.0)
        if self.bridge is not None:
            br = self.bridge[k, p] & early      # at u = Δt the grid value s_{k+1} holds
            if np.any(br):
                i = np.flatnonzero(br)
                ki, pi = np.broadcast_to(k, br.shape)[br], np.broadcast_to(p, br.shape)[br]
                d, dd, integral = _bridge(self.noise_mps[ki, pi], self.noise_mps[ki + 1, pi],
                                          self.kappa[pi], np.broadcast_to(u, br.shape)[br] / dt)
                s, v, acc = (np.array(x, float, copy=True) for x in
                             np.broadcast_arrays(s, v, acc))
                s.flat[i] += integral * dt
                v.flat[i] += d
                acc.flat[i] += dd / dt
        mode = self.mode[k, p]
        mode = np.where((v == 0.0) & (mode == MODE_DECEL) & ~early, MODE_STOPPED, mode)
        return s, v, acc, mode.astype(np.uint8)

    def _bridged_time(self, k: int, p: int, s_target: float) -> float:
        """Time into bridged step ``k`` at which profile ``p`` reaches ``s_target``: Newton on
        s(u) from u = Δt/2 (s is increasing and smooth there, v > 0), bisection as a fallback."""
        dt = self.dt_s
        s0, v0, a = float(self.s_m[k, p]), float(self.v_mps[k, p]), float(self.a_mps2[k, p])
        x0, x1 = float(self.noise_mps[k, p]), float(self.noise_mps[k + 1, p])
        kap = float(self.kappa[p])

        def s_v(u):
            d, integral = _bridge_scalar(x0, x1, kap, u / dt)
            return s0 + v0 * u + 0.5 * a * u * u + integral * dt, v0 + a * u + d

        lo, hi, u = 0.0, dt, 0.5 * dt
        for _ in range(60):
            su, vu = s_v(u)
            err = su - s_target
            if abs(err) <= 1e-12 * max(1.0, abs(s_target)):
                return u
            if err < 0:
                lo = u
            else:
                hi = u
            nxt = u - err / vu if vu > 0 else 0.5 * (lo + hi)
            u = nxt if lo < nxt < hi else 0.5 * (lo + hi)
            if hi - lo < 1e-12 * dt:
                break
        return u

    def time_at(self, p: int, s_target: float) -> float:
        """First local time at which profile ``p`` reaches arc length ``s_target`` (inf: never)."""
        col = self.s_m[:, p]
        i = int(np.searchsorted(col, s_target, side="left"))
        if i == 0:
            return 0.0
        if i >= len(col):
            return float("inf")
        k = i - 1
        dt = self.dt_s
        s0, v0, a, tk = col[k], self.v_mps[k, p], self.a_mps2[k, p], self.tau_s[k, p]
        if self.bridge is not None and self.bridge[k, p]:
            return k * dt + self._bridged_time(k, p, s_target)
        s_tau = s0 + v0 * tk + 0.5 * a * tk * tk
        x = s_target - s0
        if s_target <= s_tau:
            root = np.sqrt(max(v0 * v0 + 2.0 * a * x, 0.0))
            den = v0 + root
            u = 0.0 if den <= 0 else 2.0 * x / den
        else:
            v1 = self.v_mps[k + 1, p]
            u = tk + (s_target - s_tau) / v1 if v1 > 0 else dt
        return k * dt + min(max(u, 0.0), dt)


def _bridge_scalar(x0, x1, kappa, f):
    """:func:`_bridge` for one float (math module: no numpy overhead in a per-vehicle loop)."""
    g = f - 0.5
    m = 1.0 - 0.25 * kappa
    q = kappa * g * g + m
    rq = 1.0 / math.sqrt(q)
    a, b = 0.5 * (x0 + x1), x1 - x0
    lin = a + b * g
    rk = math.sqrt(kappa / m)

    def prim(gg):
        z = gg * rk
        ratio = 1.0 - z * z / 6.0 if abs(z) < 1e-4 else math.asinh(z) / z
        return a * gg / math.sqrt(m) * ratio

    integral = (prim(g) - prim(-0.5) + b * (g * g - 0.25) / (math.sqrt(q) + 1.0)
                - (x0 * f + 0.5 * b * f * f))
    return lin * (rq - 1.0), integral


def simulate_profiles(inp: ProfileInputs, dt_s: float, n_steps: int,
                      progress: bool = False) -> Profiles:
    """Run the fleet's speed profiles for ``n_steps`` steps of ``dt_s`` (see module docstring).

    ``progress`` shows a tqdm bar over the steps (on a terminal only)."""
    P = len(inp.length_m)
    K = int(n_steps)
    dt = float(dt_s)
    S = np.empty((K + 1, P))
    V = np.empty((K + 1, P))
    A = np.zeros((K, P))
    TAU = np.full((K, P), dt)
    M = np.zeros((K, P), dtype=np.uint8)
    W = np.zeros((K + 1, P))                  # σξ_k at the grid points
    BR = np.zeros((K, P), dtype=bool)         # free-cruise steps carrying the speed bridge

    amax, dmax = inp.max_accel_mps2, inp.max_decel_mps2
    sigma = inp.speed_noise_mps
    rho = inp.noise_rho
    rho_c = np.sqrt(1.0 - rho * rho)
    kappa = 2.0 * (1.0 - rho)
    # ∫_0^1 δ df = (σξ_k + σξ_{k+1})/2 · c1 (_bridge at f = 1, where q = 1 and the B term is 0)
    c1 = _bridge(np.ones(P), np.ones(P), kappa, 1.0)[2]
    xi = np.zeros(P)
    # Segment lookup over all profiles at once: key = s + p * span keeps the flat array sorted.
    span = float(2.0 ** np.ceil(np.log2(max(float(np.max(inp.length_m)), 1.0) * 2.0 + 2.0)))
    seg_prof = np.repeat(np.arange(P), np.diff(inp.seg_offset))
    seg_key = inp.seg_start_m + seg_prof * span
    first_seg = inp.seg_offset[:-1]
    last_seg = inp.seg_offset[1:] - 1
    prof_base = np.arange(P) * span
    stop_flat = np.concatenate([inp.stop_m, [np.inf]])
    stop_ptr = inp.stop_offset[:-1].copy()
    stop_end = inp.stop_offset[1:]

    # Anticipation of lower cruise speeds ahead (speed limits, speed-change points): entering
    # segment b at s_b with target T_b allows at most sqrt(T_b^2 + 2 d (s_b - s)) before it.
    # The binding segment ahead of segment j is B(j) = argmin_{b > j} (T_b^2 + 2 d s_b), which
    # does not depend on s, so it is precomputed (the nearest one on ties; d = 0.9 max_decel).
    # The bound is evaluated at the step's look-ahead point and clamped at T_B once past s_B.
    d_cap = 0.9 * dmax
    cap_t = np.full(len(inp.seg_start_m), np.inf)
    cap_s = np.full(len(inp.seg_start_m), np.inf)
    for p in range(P):
        a0, a1 = int(inp.seg_offset[p]), int(inp.seg_offset[p + 1])
        if a1 - a0 > 1:
            tb = inp.seg_target_mps[a0 + 1:a1]
            sb = inp.seg_start_m[a0 + 1:a1]
            r = (tb ** 2 + 2.0 * d_cap[p] * sb)[::-1]
            acc = np.minimum.accumulate(r)
            pos = np.maximum.accumulate(np.where(r == acc, np.arange(len(r)), -1))
            best = (len(r) - 1 - pos)[::-1]           # index into tb/sb for segments a0..a1-2
            cap_t[a0:a1 - 1] = tb[best]
            cap_s[a0:a1 - 1] = sb[best]

    s = np.zeros(P)
    v = np.asarray(inp.v0_mps, float).copy()
    state = np.full(P, TRACK, dtype=np.int64)
    wait_left = np.zeros(P, dtype=np.int64)
    done = np.zeros(P, dtype=bool)
    S[0] = s
    V[0] = v
    look_a = 0.5 * amax * dt * dt
    from tqdm import tqdm
    for k in tqdm(range(K), desc="truth", unit="step", leave=False,
                  disable=None if progress else True, mininterval=0.5):
        if done.all():
            S[k + 1:] = s
            V[k + 1:] = 0.0
            M[k:] = MODE_CRUISE
            break
        # -- target cruise speed of the segment under each vehicle
        j = np.searchsorted(seg_key, s + prof_base, side="right") - 1
        j = np.clip(j, first_seg, last_seg)
        target = inp.seg_target_mps[j]
        # -- state transitions at the step start
        stopped = state == STOPPED
        release = stopped & (wait_left <= 0)
        state[release] = TRACK
        wait_left[stopped & ~release] -= 1
        next_stop = np.where(stop_ptr < stop_end,
                             stop_flat[np.minimum(stop_ptr, len(stop_flat) - 1)], np.inf)
        dist = next_stop - s
        moving = state != STOPPED
        rand_stop = moving & (state == TRACK) & (v > 0) & (inp.u_stop[k] < inp.p_stop)
        state[rand_stop] = BRAKE_RANDOM
        v_up = v + amax * dt
        reach = s + v * dt + look_a + v_up * v_up / (2.0 * dmax) >= next_stop
        b_rand = v * v / (2.0 * dmax)
        to_point = (moving & (state != BRAKE_POINT) & reach & (dist > 0)
                    & ~((state == BRAKE_RANDOM) & (b_rand < dist)))
        # At rest within the start-up look-ahead of a stop point (it came to rest just short
        # of it, e.g. by a random stop): that stop counts as made, it drives on.
        served = to_point & (v <= 0.0)
        if served.any():
            stop_ptr[served] += 1
            to_point &= ~served
            next_stop = np.where(stop_ptr < stop_end,
                                 stop_flat[np.minimum(stop_ptr, len(stop_flat) - 1)], np.inf)
            dist = next_stop - s
        state[to_point] = BRAKE_POINT
        # -- kinematics of the step
        a = np.zeros(P)
        tau = np.full(P, dt)
        label = np.full(P, MODE_STOPPED, dtype=np.uint8)
        tr = state == TRACK
        with np.errstate(invalid="ignore"):
            ahead = np.maximum(cap_s[j] - (s + v * dt), 0.0)
        cap = np.sqrt(cap_t[j] ** 2 + 2.0 * d_cap * ahead)
        xi_prev = xi
        if k == 0:
            xi = inp.normal[0].copy()
        else:
            xi = rho * xi + rho_c * inp.normal[k]
        noisy = target + sigma * xi
        v_des = np.maximum(np.minimum(noisy, cap), 0.0)
        raw = (v_des - v) / dt
        a_tr = np.clip(raw, -dmax, amax)
        a = np.where(tr, a_tr, a)
        label = np.where(tr, np.where(raw > amax, MODE_ACCEL,
                                      np.where(raw < -dmax, MODE_DECEL, MODE_CRUISE)), label)
        bp = state == BRAKE_POINT
        br = state == BRAKE_RANDOM
        with np.errstate(divide="ignore", invalid="ignore"):
            a_bp = np.where(dist > 0, -v * v / (2.0 * dist), 0.0)
            t_bp = np.where(v > 0, 2.0 * dist / v, np.inf)
        t_br = v / dmax
        a = np.where(bp, a_bp, np.where(br, -dmax, a))
        t_stop = np.where(bp, t_bp, np.where(br, t_br, np.inf))
        # A stop point reached up to rounding (the last braking step may leave ~1e-13 m/s and
        # ~1e-12 m) counts as reached in this step.
        stops = (bp | br) & (t_stop <= dt * (1.0 + 1e-9))
        stops |= bp & (dist <= 1e-9)
        tau = np.where(stops, np.minimum(t_stop, dt), tau)
        label = np.where(bp | br, MODE_DECEL, label)
        v_end = np.where(stops, 0.0, np.maximum(v + a * tau, 0.0))
        s_end = s + v * tau + 0.5 * a * tau * tau + v_end * (dt - tau)
        s_end = np.where(stops & bp, next_stop, s_end)
        if k > 0:
            # free cruise from the free target c + σξ_k to c + σξ_{k+1}: the speed bridge
            x0, x1 = sigma * xi_prev, sigma * xi
            free = (tr & (label == MODE_CRUISE) & (v_des == noisy) & (sigma > 0) & ~done
                    & ~stops & (np.abs(v - (target + x0)) <= 1e-9 * np.maximum(v, 1.0))
                    & (np.minimum(v, v_des) >= _BRIDGE_GUARD * np.maximum(np.abs(x0),
                                                                          np.abs(x1))))
            if free.any():
                s_end = np.where(free, s_end + 0.5 * (x0 + x1) * c1 * dt, s_end)
                BR[k] = free
        W[k + 1] = sigma * xi
        still = state == STOPPED
        a = np.where(still, 0.0, a)
        v_end = np.where(still, 0.0, v_end)
        s_end = np.where(still, s, s_end)
        # -- vehicles come to rest: draw the geometric wait, advance past a reached stop point
        if stops.any():
            q = inp.q_wait[stops]
            q_safe = np.where(q >= 1.0, 0.5, q)
            w = np.where(q >= 1.0, 1.0, np.ceil(np.log(inp.u_wait[k][stops]) / np.log1p(-q_safe)))
            w = np.maximum(w, 1.0)
            w = np.minimum(w, inp.max_wait_steps[stops]).astype(np.int64)
            wait_left[stops] = w
            state[stops] = STOPPED
            stop_ptr[stops & bp] += 1
        # -- finished profiles freeze
        a = np.where(done, 0.0, a)
        tau = np.where(done, dt, tau)
        v_end = np.where(done, 0.0, v_end)
        s_end = np.where(done, s, s_end)
        A[k] = a
        TAU[k] = tau
        M[k] = label
        s, v = s_end, v_end
        S[k + 1] = s
        V[k + 1] = v
        done |= s >= inp.length_m
    return Profiles(dt_s=dt, s_m=S, v_mps=V, a_mps2=A, tau_s=TAU, mode=M, noise_mps=W,
                    bridge=BR, kappa=kappa)
