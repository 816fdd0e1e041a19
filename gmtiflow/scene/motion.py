r"""Speed-profile kernel: arc length s(t) of every vehicle, vectorised over the fleet (DESIGN §3).

The paper's Alg. 1–2 move a position step by step and patch the overshoot at a crossroad
(Fig. 1). Here a vehicle is only a speed profile along its route polyline
(:class:`~gmtiflow.scene.profiles.Profiles`: per step of a time grid the arc length, the speed
and a constant acceleration, exact at any instant), so the position on the route polyline needs
no overshoot correction and no interpolation error.

Every operation is numpy over profiles (and, in windows, over steps): there is no per-vehicle
Python loop and, for driving profiles, no per-step one either (below).  Per profile a small
state machine (the corrected Alg. 2, DESIGN §3):

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
same cruise c) the speed between the grid values c + σξ_k and c + σξ_{k+1} follows the bridge of
:mod:`gmtiflow.scene.speed_bridge` (exactly N(c, σ²) at every instant, not the straight line),
carried per step as ``bridge``/``noise_mps``.  It is applied only where it keeps v ≥ 0 and the
acceleration within the vehicle's limits at every instant of the step
(:func:`~gmtiflow.scene.speed_bridge.drop_past_limits`); a step near a limit whose bridge would
cross it keeps its constant acceleration, as do the steps that accelerate, brake or are capped.

Randomness enters only through per-profile noise blocks (speed normals, stop uniforms, wait
uniforms) that the caller draws from each vehicle's own stream on demand (:class:`NoiseSource`),
so the kernel is deterministic.  ξ depends on the draws alone, so it is computed when a block is
drawn (the same sequential recurrence as a step loop).

Windows.  Each profile runs in its own local time, at its own pace, in rounds.  In a round a
profile in ``TRACK`` takes a *window* of up to W steps at once (W = :func:`window_length`:
:data:`NOISE_BLOCK_STEPS`, longer for a fleet of few profiles, whose cost is per window; the
result does not depend on W): from a
guess of every step's start position and speed (constant speed, or, once windows often need a
second pass as with long steps, the speed the window's noise gives: :data:`NOISE_GUESS_ABOVE`;
the result does not depend on the guess), the desired speeds v* of all steps are
computed; the start speeds follow from them by the step recurrence in v alone (a step within
its limits ends at v* whatever its start speed — the speeds are within a factor 2, so
v + ((v* − v)/Δt)Δt rounds to v* — and a clipped run adds aΔt step by step, a sequential
``np.add.accumulate``); every step's kinematics follow, and the positions are the running sum,
again with ``np.add.accumulate``, of the very terms each step adds, in its order (less one that
is ±0 in a tracking step, whose addition changes nothing).  A step is
*right* when its start speed is the previous step's end speed and the desired speed at its
start state is the one used, bit for bit; the right steps are taken, up to the first random
stop or stop point ahead or the profile's end, and for the rest the pass is repeated with the
desired speeds it found (at most :data:`MAX_SWEEPS` passes; steady cruise needs one, a window
that crosses a segment or brakes for a lower limit a few).  So the result is the step loop's,
bit for bit (``windows=False`` runs that loop; tests/scene/test_motion_windows.py compares
them), while the Python cost is per window, not per step.  A profile at rest takes its whole
wait at once, and one braking for a random stop (no stop point ahead) the rest of its braking,
to rest, at once (the speeds by repeated additions of aΔt, as the steps make them); the step
that starts a random stop, stop points and the step after a wait take single steps (the step
loop's body, vectorised over the profiles that need it).  In one round a profile can take a
window, a single step, its braking and its wait, so a random stop costs one or two rounds.

Cost follows the trips: a profile is stepped from its start until it is done (past its length)
or reaches its own horizon (the scene's end), and then leaves the active set, so work and
memory are the sum of the trips' steps, not vehicles x scene steps (docs/scale.md).  The
profiles are stored flat, one run of steps per profile (:class:`Profiles`).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Optional, Tuple

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from gmtiflow import bars
from gmtiflow.scene import speed_bridge
from gmtiflow.scene.profiles import MODE_ACCEL, MODE_CRUISE, MODE_DECEL, MODE_STOPPED, Profiles

TRACK, BRAKE_RANDOM, STOPPED, BRAKE_POINT = 0, 1, 2, 4


#: Steps of noise drawn per block for the active profiles (bounded temporaries), and of a
#: window; up to 64 profiles (with trips of 256 steps or more) get longer blocks and windows
#: (:func:`window_length`).
NOISE_BLOCK_STEPS = 128

#: ``noise(profiles, k0, n) -> (normal, u_stop, u_wait)``, each (n, len(profiles)) (fewer rows
#: allowed past the last step there is): the noise of local steps k0 .. k0 + n - 1 of the given
#: profiles (ids ascending), n = the kernel's block length W (:func:`window_length`); each
#: profile's blocks are asked for in order (k0 = 0, n, 2n, …), up to one block ahead of the step
#: the profile is at (so a profile may get one block it does not use), different profiles at
#: different k0 in separate calls.
NoiseSource = Callable[[np.ndarray, int, int], Tuple[np.ndarray, np.ndarray, np.ndarray]]


def array_noise(normal: np.ndarray, u_stop: np.ndarray, u_wait: np.ndarray) -> NoiseSource:
    """A :data:`NoiseSource` reading pre-drawn (K, P) arrays (tests, small fleets)."""
    def draw(profiles, k0, n):
        sl = slice(k0, k0 + n)
        return normal[sl, profiles], u_stop[sl, profiles], u_wait[sl, profiles]
    return draw


@dataclass
class ProfileInputs:
    """Per-profile inputs of :func:`simulate_profiles` (P profiles, flat per-segment arrays).

    seg_start_m: flat segment start arc lengths; profile p's segments are
        ``seg_offset[p]:seg_offset[p+1]``, sorted ascending within the profile.
    seg_target_mps: cruise target of each flat segment.
    stop_m: flat stop-point arc lengths (sorted within a profile), ``stop_offset`` as above.
    horizon_steps: steps of the profile's own horizon (from its start to the scene's end).
    noise: draws the speed normals and stop/wait uniforms of the active profiles per block.
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
    horizon_steps: np.ndarray     # (P,) int >= 1
    noise: NoiseSource


def _flatten(P: int, dt: float, v0: np.ndarray, horizon: np.ndarray, kappa: np.ndarray,
             rec: list) -> Profiles:
    """The recorded steps as flat profiles: per record (profile ids, local steps, a, tau (None:
    every step lasts Δt), label, bridge, s_end, v_end, σξ at the step's end), in any order;
    each record is scattered into place directly (no concatenated copy of every column
    first).  Where no step stops within itself (every tau Δt) ``tau_flat`` is Δt as one
    read-only value, and where no step carries the speed bridge (no speed noise, as the Stone
    Soup peer's targets) ``noise_flat`` is +0 likewise (it is read for bridged steps only):
    each 8 bytes a step of the fleet's memory fewer (the peer's 10 targets: 1.4 MB)."""
    ids_all = (np.concatenate([r[0] for r in rec]) if rec else np.zeros(0, np.int64))
    n_p = np.bincount(ids_all, minlength=P).astype(np.int64)
    del ids_all
    off = np.concatenate([[0], np.cumsum(n_p)]).astype(np.int64)
    n = int(off[-1])
    timed = any(r[3] is not None and bool((r[3] != dt).any()) for r in rec)
    bridged = any(bool(np.any(r[5])) for r in rec)
    a = np.empty(n)
    # the steps of the records without tau (None) last Δt
    tau = np.full(n, dt) if timed else np.broadcast_to(np.float64(dt), (n,))
    mode = np.empty(n, np.uint8)
    bridge = np.empty(n, bool)
    s = np.empty(n + P)
    v = np.empty(n + P)
    w = np.empty(n + P) if bridged else np.broadcast_to(np.float64(0.0), (n + P,))
    first = off[:-1] + np.arange(P)
    s[first] = 0.0
    v[first] = v0
    if bridged:
        w[first] = 0.0
    for ids, k, a_r, tau_r, mode_r, bridge_r, s_r, v_r, w_r in rec:
        i = off[ids] + k
        a[i], mode[i], bridge[i] = a_r, mode_r, bridge_r
        if tau_r is not None and timed:
            tau[i] = tau_r
        g = i + ids + 1
        s[g], v[g] = s_r, v_r
        if bridged:
            w[g] = w_r
    return Profiles(dt_s=dt, n_steps_p=n_p, horizon_steps=horizon, step_offset=off,
                    s_flat=s, v_flat=v, a_flat=a, tau_flat=tau, mode_flat=mode, noise_flat=w,
                    bridge_flat=bridge, kappa=kappa)


#: Segment starts ahead of a window's first step looked up by comparison (more: binary search).
_SEG_AHEAD = 6

#: Profiles per window computation: its (rows, W) temporaries stay cache-sized.
_WINDOW_ROWS = 512

#: A window's (profiles, steps) cells up to which the window length grows for few profiles
#: (their per-window Python cost is then spread over more steps; many profiles keep
#: NOISE_BLOCK_STEPS: their windows are cut short more often, at limits and segment ends);
#: and the longest window.
WINDOW_CELLS = 128 * NOISE_BLOCK_STEPS
MAX_WINDOW_STEPS = 1024

#: Most passes of the fixed-point iteration of one window of tracking steps (module doc).
MAX_SWEEPS = 2

#: Windows start from a guess that follows the speed noise (speculate()) once more than this
#: fraction of the window rows so far (at least 32) needed a second pass (< 0: from the start).
#: Any guess gives the same profiles; this one pays where steps are long.
NOISE_GUESS_ABOVE = 1.0 / 3.0


def window_length(n_profiles: int, n_steps: Optional[int] = None) -> int:
    """Steps per window (and noise block) for ``n_profiles`` of at most ``n_steps`` steps:
    NOISE_BLOCK_STEPS doubled while the (profiles, steps) temporaries stay within
    WINDOW_CELLS, at most MAX_WINDOW_STEPS and at most ``n_steps``."""
    w = NOISE_BLOCK_STEPS
    while (2 * w <= MAX_WINDOW_STEPS and max(n_profiles, 1) * 2 * w <= WINDOW_CELLS
           and (n_steps is None or 2 * w <= n_steps)):
        w *= 2
    return w


def _slowest_targets(seg_offset, seg_target_mps) -> np.ndarray:
    """Per profile, the lowest cruise target of its segments (m/s; 0 without segments)."""
    seg_offset = np.asarray(seg_offset, np.int64)
    out = np.zeros(len(seg_offset) - 1)
    has = np.flatnonzero(np.diff(seg_offset) > 0)
    if has.size:
        out[has] = np.minimum.reduceat(np.asarray(seg_target_mps, float), seg_offset[has])
    return out


def _ahead_wanted(left_m, block_left_s, slow_mps) -> np.ndarray:
    """Whether a profile with ``left_m`` to go, ``block_left_s`` of its current noise block
    left and its route's slowest cruise target ``slow_mps`` should have its next block drawn
    ahead: unless it would end within this block at 90 % of that speed (it then most likely
    ends there, and the block drawn ahead would be drawn for nothing).  Only the cost
    depends on it (a profile without its next block waits for it at the block's end)."""
    return ~(left_m < 0.9 * block_left_s * slow_mps)


def _recurrence(x: np.ndarray, rho: np.ndarray) -> None:
    """x[r] = ρ·x[r - 1] + x[r] for r = 1 .. in order, in place on a (W, n) array: one
    multiply and one add per row, into row views made once and with ``out`` passed
    positionally (the per-call overhead is most of the cost for a few hundred columns:
    2.6x faster than indexing rows and ``out=`` keywords in the loop, 2026-11-28)."""
    mul, add = np.multiply, np.add
    tmp = np.empty(x.shape[1])
    rows = list(x)
    prev = rows[0]
    for row in rows[1:]:
        mul(rho, prev, tmp)
        add(tmp, row, row)
        prev = row


def _running_sums(st: np.ndarray, terms) -> None:
    """st[i + 1] = ((st[i] + terms[0][i]) + terms[1][i]) (+ terms[2][i]) for i = 0 .. W - 1,
    in place on a (W + 1, n) array (two or three terms, (W, n) each): the additions in that
    order, over row views made once, ``out`` passed positionally (as :func:`_recurrence`;
    the 1,000-vehicle fast fleet's windows 4.1 -> 2.2 ms)."""
    add = np.add
    rows = list(st)
    if len(terms) == 3:
        for prev, row, a, b, c in zip(rows[:-1], rows[1:], *terms):
            add(prev, a, row)
            add(row, b, row)
            add(row, c, row)
        return
    for prev, row, a, b in zip(rows[:-1], rows[1:], *terms):
        add(prev, a, row)
        add(row, b, row)


def _leading_true(ok: np.ndarray) -> np.ndarray:
    """Per row, the number of leading True values of a 2-D bool array."""
    pad = np.zeros((ok.shape[0], 1), bool)
    return np.argmin(np.concatenate([ok, pad], axis=1), axis=1)


def _first_true(x: np.ndarray) -> np.ndarray:
    """Per row, the index of the first True (the row length if none)."""
    pad = np.ones((x.shape[0], 1), bool)
    return np.argmax(np.concatenate([x, pad], axis=1), axis=1)


def _runs(V, v_des, rows, c, inc, am, dm, dt, length):
    """Runs of clipped steps starting at column ``c`` of rows ``rows``: the speeds at columns
    c .. c + length - 1 by repeated additions of ``inc`` from V[row, c], and each run's last
    step e (the first t >= 1 at which the speed is within reach of v_des again; ``length`` if
    none)."""
    w = V.shape[1]
    t = np.arange(length)
    col = np.minimum(c[:, None] + t, w - 1)
    chain = np.broadcast_to(inc[:, None], (rows.size, length)).copy()
    chain[:, 0] = V[rows, c]
    chain = np.maximum(np.add.accumulate(chain, axis=1), 0.0)   # speed at column c + t
    rr = (v_des[rows[:, None], col] - chain) / dt
    e = _first_true((rr <= am) & (rr >= -dm) & (t >= 1) & (c[:, None] + t < w))
    return e, chain


def _track_speeds(v0, v_des, amax, dmax, dt, known=None):
    """Start speeds (n, W) of W tracking steps from ``v0`` (n,) for the desired speeds
    ``v_des`` (n, W), as the step loop makes them.  A step within its acceleration limits
    ends at v_des (the speeds are within a factor 2, so v + ((v_des - v)/dt)*dt rounds to
    v_des whatever v); a run of clipped steps adds a dt step by step (a sequential sum) until
    the speed is within reach of v_des again.  ``amax``, ``dmax``: (n, 1).  ``known``:
    (V, k), speeds already known to be right in columns 0 .. k (n,).  A guess: the caller
    checks it step by step."""
    n, w = v_des.shape
    V = np.empty((n, w))
    V[:, 0] = v0
    V[:, 1:] = v_des[:, :-1]
    t = np.arange(w)
    settled = np.zeros(n, np.int64)           # the first step whose class is not known
    if known is not None:
        right = t <= known[1][:, None]
        V[right] = known[0][right]
        settled = known[1].copy()
    for _ in range(4):
        raw = (v_des - V) / dt
        clipped = ((raw > amax) | (raw < -dmax)) & (t >= settled[:, None])
        clipped[:, -1] = False                # its end is not a start speed in the window
        # runs start at a clipped step after a free one (or at the first unsettled column)
        start = clipped & ~np.concatenate([np.zeros((n, 1), bool), clipped[:, :-1]], axis=1)
        rows, c = np.nonzero(start)
        if not rows.size:
            break
        am, dm = amax[rows], dmax[rows]
        inc = np.clip(raw[rows, c], -dm[:, 0], am[:, 0]) * dt
        e, chain = _runs(V, v_des, rows, c, inc, am, dm, dt, min(w, 8))
        long = np.flatnonzero(e >= 8)          # not back within reach in 8 steps: longer
        if long.size and w > 8:
            e_l, chain_l = _runs(V, v_des, rows[long], c[long], inc[long], am[long], dm[long],
                                 dt, w)
            e = e.copy()
            e[long] = e_l
            wide = np.zeros((rows.size, w))
            wide[:, :chain.shape[1]] = chain
            wide[long] = chain_l
            chain = wide
        tc = np.arange(chain.shape[1])
        col = np.minimum(c[:, None] + tc, w - 1)
        inside = c[:, None] + tc < w
        # a run that starts within an earlier run of its row (as guessed) waits for a later pass
        key = rows * (2 * w + 2)
        end = np.maximum.accumulate(key + c + e)
        prev_end = np.concatenate([[-1], end[:-1]])
        ok = key + c > prev_end
        put = (tc >= 1) & (tc <= e[:, None]) & inside & ok[:, None]
        V[np.broadcast_to(rows[:, None], put.shape)[put], col[put]] = chain[put]
        settled_new = np.full(n, w, np.int64)
        np.minimum.at(settled_new, rows[~ok], c[~ok])
        settled = settled_new
        if ok.all():
            break
    return V


def _speed_caps(seg_offset, seg_start_m, seg_target_mps, d_cap):
    """Per flat segment j of profile p: the target T_B and start s_B of the binding segment
    ahead, B(j) = argmin_{b > j} (T_b^2 + 2 d_p s_b) within p's segments (the nearest on
    ties); inf for a profile's last segment.  The profiles with the same number of segments
    are done at once, one row each."""
    seg_t, seg_s = np.asarray(seg_target_mps, float), np.asarray(seg_start_m, float)
    seg_offset = np.asarray(seg_offset, np.int64)
    cap_t = np.full(len(seg_s), np.inf)
    cap_s = np.full(len(seg_s), np.inf)
    n_seg = np.diff(seg_offset)
    for n_b in np.unique(n_seg[n_seg > 1]).tolist():
        ps = np.flatnonzero(n_seg == n_b)
        cells = seg_offset[ps][:, None] + np.arange(n_b - 1)     # segments a0 .. a1 - 2
        tb, sb = seg_t[cells + 1], seg_s[cells + 1]
        r = (tb ** 2 + 2.0 * d_cap[ps][:, None] * sb)[:, ::-1]
        acc = np.minimum.accumulate(r, axis=1)
        pos = np.maximum.accumulate(np.where(r == acc, np.arange(n_b - 1), -1), axis=1)
        best = (n_b - 2 - pos)[:, ::-1]                          # index into a row of tb/sb
        cap_t[cells] = np.take_along_axis(tb, best, axis=1)
        cap_s[cells] = np.take_along_axis(sb, best, axis=1)
    return cap_t, cap_s


def simulate_profiles(inp: ProfileInputs, dt_s: float, progress: bool = False,
                      windows: bool = True, window_steps: Optional[int] = None) -> Profiles:
    """Run the fleet's speed profiles, each for its own horizon or until done (module docstring).

    ``progress`` shows a tqdm bar over the steps (on a terminal only).  ``windows=False``
    takes every step one at a time (the reference the windows must reproduce bit for bit;
    tests)."""
    P = len(inp.length_m)
    dt = float(dt_s)
    horizon = np.asarray(inp.horizon_steps, dtype=np.int64)
    K = int(horizon.max()) if P else 0
    W = window_length(P, K) if window_steps is None else int(window_steps)

    # Segment lookup over all profiles at once: key = s + p * span keeps the flat array sorted.
    span = float(2.0 ** np.ceil(np.log2(max(float(np.max(inp.length_m, initial=0.0)), 1.0)
                                        * 2.0 + 2.0)))
    seg_prof = np.repeat(np.arange(P), np.diff(inp.seg_offset))
    seg_key = inp.seg_start_m + seg_prof * span
    seg_target = np.asarray(inp.seg_target_mps)
    stop_flat = np.concatenate([inp.stop_m, [np.inf]])

    # Anticipation of lower cruise speeds ahead (speed limits, speed-change points): entering
    # segment b at s_b with target T_b allows at most sqrt(T_b^2 + 2 d (s_b - s)) before it.
    # The binding segment ahead of segment j is B(j) = argmin_{b > j} (T_b^2 + 2 d s_b), which
    # does not depend on s, so it is precomputed (the nearest one on ties; d = 0.9 max_decel).
    # The bound is evaluated at the step's look-ahead point and clamped at T_B once past s_B.
    d_cap_all = 0.9 * inp.max_decel_mps2
    cap_t, cap_s = _speed_caps(inp.seg_offset, inp.seg_start_m, inp.seg_target_mps, d_cap_all)
    cap_t2 = cap_t ** 2                 # T_B^2 per segment, squared once (the same values)

    # Per-profile constants (indexed by profile id).
    rho = np.asarray(inp.noise_rho, float)
    kappa = 2.0 * (1.0 - rho)
    rho_c = np.sqrt(1.0 - rho * rho)
    # ∫_0^1 δ df = (σξ_k + σξ_{k+1})/2 · c1 (the bridge at f = 1: q = 1, B term 0)
    c1 = speed_bridge.bridge(np.ones(P), np.ones(P), kappa, 1.0)[2]
    e1_all, e2_all = speed_bridge.rate_bounds(kappa)
    amax_all, dmax_all = inp.max_accel_mps2, inp.max_decel_mps2
    sigma_all, p_stop_all = inp.speed_noise_mps, inp.p_stop
    first_seg, last_seg = inp.seg_offset[:-1], inp.seg_offset[1:] - 1
    prof_base = np.arange(P) * span
    look_a_all = 0.5 * inp.max_accel_mps2 * dt * dt
    stop_end_all = inp.stop_offset[1:]
    length_all = inp.length_m
    points = len(inp.stop_m) > 0      # without stop points their logic is skipped

    # Per-profile state: local step k (profiles run in their own local time, each at its own
    # pace through the rounds below), position, speed, state machine.
    k_at = np.zeros(P, np.int64)
    s_at = np.zeros(P)
    v_at = np.asarray(inp.v0_mps, float).copy()
    state_at = np.full(P, TRACK, dtype=np.int64)
    wait_at = np.zeros(P, dtype=np.int64)
    stop_ptr_at = inp.stop_offset[:-1].copy()
    done = np.zeros(P, bool)

    # Noise of two blocks of W steps per profile: column c holds local step base + c - 1
    # (column 0: the step before, for ξ_{k-1}).  ξ is a function of the draws alone, so it is
    # computed when a block is drawn (the same sequential recurrence as a step loop).  The
    # second block is drawn ahead only while the profile is not expected to end within its
    # current one (_ahead_wanted); ``top`` is each profile's last column drawn (W or 2W), and
    # no part of a round takes a step past it (a profile that gets there waits for the next
    # round, which draws its next block): the steps do not depend on which blocks are ahead.
    xi_buf = np.zeros((P, 2 * W + 1))
    us_buf = np.ones((P, 2 * W + 1))
    uw_buf = np.full((P, 2 * W + 1), 0.5)
    base = np.zeros(P, np.int64)
    top = np.full(P, W, np.int64)
    # (P, W + 2, W) read-only views: [p, c] = columns c .. c + W - 1 of profile p's buffer,
    # so a window's noise is one contiguous run per profile (not W gathered elements)
    xi_win, us_win = (sliding_window_view(b, W, axis=1) for b in (xi_buf, us_buf))
    slow_mps = _slowest_targets(inp.seg_offset, seg_target)

    def fill(pids, blocks, col0):
        """Draw block ``blocks[i]`` of profile ``pids[i]`` into columns col0 .. col0 + W - 1."""
        if not pids.size:
            return
        normal = np.zeros((W, pids.size))
        for b in np.unique(blocks):
            sel = np.flatnonzero(blocks == b)
            nrm, us, uw = inp.noise(pids[sel], int(b) * W, W)
            r = nrm.shape[0]
            normal[:r, sel] = nrm
            us_buf[pids[sel], col0:col0 + r] = us.T
            uw_buf[pids[sel], col0:col0 + r] = uw.T
        rh = rho[pids]
        xi = rho_c[pids] * normal                  # ξ_k = ρ ξ_{k-1} + √(1-ρ²) n_k, in order
        prev = xi_buf[pids, col0 - 1]
        xi[0] = np.where(blocks == 0, normal[0], rh * prev + xi[0])
        # the recurrence, step by step, over the profiles with correlated noise only: with
        # ρ = 0 a step adds 0·ξ_{k-1} = ±0, which leaves a finite ξ_k other than -0 as it is
        # (normals by inversion of u + 2^-54 are never 0, those of a profile without speed
        # noise +0; a -0 or a non-finite value takes the full loop)
        loop = np.flatnonzero(rh != 0.0)
        if loop.size < pids.size and not np.all(np.isfinite(xi)
                                                & ((xi != 0.0) | ~np.signbit(xi))):
            loop = np.arange(pids.size)
        if loop.size:
            part = xi if loop.size == pids.size else xi[:, loop]
            rl = rh[loop]
            _recurrence(part, rl)
            if part is not xi:
                xi[:, loop] = part
        xi_buf[pids, col0:col0 + W] = xi.T

    ar = np.arange(W)
    rec = []
    guess_noise = [NOISE_GUESS_ABOVE < 0]      # speculate(): first guess by the speed noise
    tally = [0, 0]             # window rows with the constant-speed guess, and their 2nd sweeps

    def speculate(ids):
        """A window of up to W tracking steps for each of profiles ``ids`` (all in TRACK), all
        steps at once: from a guess of the start position and speed of every step, one pass
        computes every step as :func:`general` does; the steps whose start state is exactly
        (bit for bit) the previous step's end are right, and are taken up to the first random
        stop or stop point (left to :func:`general`) or the profile's end.  Until that is the
        whole window, the guess is improved from the pass (speeds by the step recurrence in v
        alone, positions by the same additions as the steps make) and the pass repeated, for
        the rows still short.  Returns how many steps each profile took."""
        n = ids.size
        kk = k_at[ids]
        c0 = kk - base[ids] + 1          # the window's first column (at most W)
        rows = ids[:, None]
        sig_a = sigma_all[ids][:, None]
        x1_a = sig_a * xi_win[ids, c0]
        x0_a = np.empty_like(x1_a)          # σξ a step earlier: x1_a shifted by one column
        x0_a[:, 0] = sig_a[:, 0] * xi_buf[ids, c0 - 1]
        x0_a[:, 1:] = x1_a[:, :-1]
        step_a = kk[:, None] + ar
        ev0_a = us_win[ids, c0] < p_stop_all[ids][:, None]
        last_a = step_a + 1 >= horizon[ids][:, None]
        per = {"amx": amax_all, "dmx": dmax_all, "dcap": d_cap_all, "fseg": first_seg,
               "lseg": last_seg, "pbase": prof_base, "c1": c1, "kappa": kappa, "e1": e1_all, "e2": e2_all,
               "look_a": look_a_all,
               "length": length_all, "slow": slow_mps}
        per = {key: val[ids][:, None] for key, val in per.items()}
        per["drawn"] = (top[ids] - (kk - base[ids]))[:, None]     # steps with drawn noise
        j0 = np.clip(np.searchsorted(seg_key, s_at[ids] + prof_base[ids], side="right") - 1,
                     first_seg[ids], last_seg[ids])
        ahead_idx = j0[:, None] + 1 + np.arange(_SEG_AHEAD)
        per["j0"] = j0[:, None]
        per["k0"] = seg_key[j0][:, None]
        per["nk"] = np.where(ahead_idx <= per["lseg"],
                             seg_key[np.minimum(ahead_idx, len(seg_key) - 1)], np.inf)
        if points:
            sp, se = stop_ptr_at[ids], stop_end_all[ids]
            per["nxt"] = np.where(sp < se, stop_flat[np.minimum(sp, len(stop_flat) - 1)],
                                  np.inf)[:, None]
        s0_a, v0_a = s_at[ids], v_at[ids]
        S_a = s0_a[:, None] + (v0_a * dt)[:, None] * ar
        S_a[:, 0] = s0_a
        V_a = np.repeat(v0_a[:, None], W, axis=1)
        todo = np.arange(n)
        S, V, x0, x1, step, sig, s0, v0 = S_a, V_a, x0_a, x1_a, step_a, sig_a, s0_a, v0_a
        c = per
        ev0, last0 = ev0_a, last_a

        def desired(S, V):
            # the segment under each step: the row's segment at s0 plus the starts passed (a
            # binary search over all segments only for a row that passes more of them)
            key = S + c["pbase"]
            nk = c["nk"]
            key_max = key.max(axis=1)
            passed = np.zeros(key.shape, np.uint8)      # segment starts passed (0/1 bytes)
            ge = np.empty(key.shape, bool)
            for q in range(_SEG_AHEAD):
                # start q is compared only in the rows that reach it (elsewhere key >= it is
                # False in every column); the starts ascend, so none reached ends the loop
                rows_q = ~(nk[:, q] > key_max)
                n_q = np.count_nonzero(rows_q)
                if not n_q:
                    break
                if 4 * n_q > rows_q.size:
                    np.greater_equal(key, nk[:, q:q + 1], out=ge)
                    passed += ge.view(np.uint8)
                else:
                    r = np.flatnonzero(rows_q)
                    passed[r] += (key[r] >= nk[r, q:q + 1]).view(np.uint8)
            j = c["j0"] + passed
            far = np.flatnonzero((key_max >= nk[:, -1]) | (key.min(axis=1) < c["k0"][:, 0]))
            if far.size:
                j[far] = np.clip(np.searchsorted(seg_key, key[far], side="right") - 1,
                                 c["fseg"][far], c["lseg"][far])
            target = seg_target[j]
            noisy = target + x1
            # The braking cap is at least T_B, one of the profile's targets or inf (the square
            # root of a square rounds back to it, and 2 d ahead >= 0 only adds), so it cannot
            # bind in rows whose noisy targets are all within the profile's slowest target
            # (no speed noise, as the Stone Soup peer's targets): then it is not computed.
            if (noisy.max(axis=1) <= c["slow"][:, 0]).all():
                return target, noisy, np.maximum(noisy, 0.0)
            with np.errstate(invalid="ignore"):
                ahead = np.maximum(cap_s[j] - (S + V * dt), 0.0)
            cap = np.sqrt(cap_t2[j] + 2.0 * c["dcap"] * ahead)
            return target, noisy, np.maximum(np.minimum(noisy, cap), 0.0)

        if guess_noise[0]:
            # A first guess that follows the window's speed noise: the cruise speed of the
            # segment under s0 plus σξ, reached within the acceleration limits, positions by
            # the trapezoid rule.  Any guess gives the same steps; this one lets more windows
            # pass in the first sweep where the constant-speed guess drifts (by the noise's
            # random walk) across segment starts: long steps (fidelity fast: 52 % -> 15 % of
            # the windows took a second sweep).  Taken once over NOISE_GUESS_ABOVE of the
            # window rows so far needed a second sweep (0.1 s steps: ~13 %; it would not pay).
            V = _track_speeds(v0, np.maximum(seg_target[j0][:, None] + x1, 0.0),
                              c["amx"], c["dmx"], dt)
            S = np.empty_like(S_a)
            S[:, 0] = s0
            S[:, 1:] = s0[:, None] + np.cumsum(0.5 * dt * (V[:, :-1] + V[:, 1:]), axis=1)
        target, noisy, v_des = desired(S, V)
        known = None
        for sweep in range(MAX_SWEEPS):
            amx, dmx = c["amx"], c["dmx"]
            # The steps for these desired speeds: start speeds by the step recurrence in v
            # alone, then every step's kinematics as general() computes them, and positions
            # by the very additions the steps make (so s_end[i] = S[i + 1] exactly).
            V = _track_speeds(v0, v_des, amx, dmx, dt, known)
            raw = (v_des - V) / dt
            a = np.clip(raw, -dmx, amx)
            v_end = np.maximum(V + a * dt, 0.0)
            # A step's terms v·τ, ½aτ², v_end·(Δt − τ), bridge; here τ = Δt, so the third is
            # ±0, and adding ±0 leaves a position as it is (positions are never −0: they
            # start at +0 and a sum is −0 only if both parts are), so it is left out, as is
            # the bridge where no row has speed noise (free cruise needs σ > 0: it is +0).
            noise = bool((sig > 0).any())
            if noise:
                free = ((raw <= amx) & (raw >= -dmx) & (v_des == noisy) & (sig > 0)
                        & (np.abs(V - (target + x0)) <= 1e-9 * np.maximum(V, 1.0))
                        & (np.minimum(V, v_des)
                           >= speed_bridge.GUARD * np.maximum(np.abs(x0), np.abs(x1)))
                        & (step > 0))
                free = speed_bridge.drop_past_limits(free, raw, x0, x1, c["kappa"], c["e1"],
                                                     c["e2"], dt, amx, dmx)
                bridged = np.where(free, 0.5 * (x0 + x1) * c["c1"] * dt, 0.0)
            else:
                free = np.zeros(V.shape, bool)
                bridged = np.zeros(V.shape)
            if todo.size < 64:      # few rows: one running sum along each row
                x = np.empty((todo.size, 3 * W + 1))
                x[:, 0] = s0
                for q, term in enumerate((V * dt, 0.5 * a * dt * dt, bridged)):
                    x[:, q + 1::3] = term
                S_full = np.add.accumulate(x, axis=1)[:, ::3]
            else:                   # many: the same additions column by column (faster)
                # the terms made in (step, row) order (the same operations, no transposing)
                tt = (np.multiply(V.T, dt, order="C"),
                      np.multiply((0.5 * a * dt).T, dt, order="C"),
                      np.ascontiguousarray(bridged.T) if noise else None)
                st = np.empty((W + 1, todo.size))
                st[0] = s0
                _running_sums(st, tt if noise else tt[:2])
                S_full = np.ascontiguousarray(st.T)     # rows: compress and search it fast
            S, s_end = S_full[:, :-1], S_full[:, 1:]
            # Right: step 0 (its start state is exact) and every step after a right one whose
            # start speed is the previous step's end and whose desired speed at its start
            # state is the one used (the position needs no check: it is built that way).
            t2, n2, v2 = desired(S, V)
            same = (v2 == v_des) & (t2 == target)
            ok = same[:, 1:] & (V[:, 1:] == v_end[:, :-1])
            n_exact = np.where(same[:, 0], 1 + _leading_true(ok), 0)
            ev = ev0 & (V > 0)
            if points:
                v_up = V + amx * dt
                reach = S + V * dt + c["look_a"] + v_up * v_up / (2.0 * dmx) >= c["nxt"]
                ev |= reach & (c["nxt"] - S > 0)
            cand = np.minimum(_first_true(ev), _first_true(last0 | (s_end >= c["length"])) + 1)
            cand = np.minimum(cand, c["drawn"][:, 0])
            m = np.minimum(n_exact, cand)
            fin = (m == cand) | (sweep == MAX_SWEEPS - 1)
            if sweep == 0 and not guess_noise[0]:
                tally[0] += fin.size
                tally[1] += fin.size - int(fin.sum())
                guess_noise[0] = tally[0] >= 32 and tally[1] > NOISE_GUESS_ABOVE * tally[0]
            if sweep == 0:      # every row's first pass as it is (the rows not final yet are
                # overwritten by the later passes: every row is final in the last)
                m_out = m
                out = {"a": a, "raw": raw, "s_end": s_end, "v_end": v_end, "free": free}
            else:
                r = todo[fin]
                m_out[r] = m[fin]
                for name, val in (("a", a), ("raw", raw), ("s_end", s_end),
                                  ("v_end", v_end), ("free", free)):
                    out[name][r] = val[fin]
            if fin.all():
                break
            # the rows still short: again, with the desired speeds at this pass's states
            keep = ~fin
            todo = todo[keep]
            # the speeds of the right steps and the next one's start speed are known
            k = np.minimum(n_exact[keep], W - 1)
            Vk = V[keep]
            rk = np.flatnonzero(k > 0)
            Vk[rk, k[rk]] = v_end[keep][rk, k[rk] - 1]
            known = (Vk, k)
            target, noisy, v_des = t2[keep], n2[keep], v2[keep]
            s0, v0, x0, x1 = s0[keep], v0[keep], x0[keep], x1[keep]
            step, sig, ev0, last0 = step[keep], sig[keep], ev0[keep], last0[keep]
            c = {key: val[keep] for key, val in c.items()}
        m = m_out
        took = ar < m[:, None]
        if took.any():
            raw, amx, dmx = out["raw"], per["amx"], per["dmx"]
            label = np.where(raw > amx, np.uint8(MODE_ACCEL),
                             np.where(raw < -dmx, np.uint8(MODE_DECEL), np.uint8(MODE_CRUISE)))
            rec.append((np.broadcast_to(rows, took.shape)[took], step_a[took], out["a"][took],
                        None, label[took], out["free"][took],
                        out["s_end"][took], out["v_end"][took], x1_a[took]))
            moved = m > 0
            r, last = np.flatnonzero(moved), m[moved] - 1
            mid = ids[moved]
            s_at[mid] = out["s_end"][r, last]
            v_at[mid] = out["v_end"][r, last]
            k_at[mid] += m[moved]
            done[mid] = (out["s_end"][r, last] >= length_all[mid]) | last_a[r, last]
        return m

    def wait(ids):
        """Profiles at rest with whole steps of their wait left: those steps at once."""
        kk = k_at[ids]
        m = np.minimum(np.minimum(wait_at[ids], horizon[ids] - kk),
                       np.minimum(W, top[ids] - (kk - base[ids])))  # within the noise drawn
        took = ar < m[:, None]
        cols = np.minimum((kk - base[ids] + 1)[:, None] + ar, 2 * W)
        rows = np.broadcast_to(ids[:, None], took.shape)
        n = int(took.sum())
        sig = np.broadcast_to(sigma_all[ids][:, None], took.shape)
        rec.append((rows[took], (kk[:, None] + ar)[took], np.zeros(n), None,
                    np.full(n, MODE_STOPPED, np.uint8), np.zeros(n, bool),
                    np.broadcast_to(s_at[ids][:, None], took.shape)[took], np.zeros(n),
                    sig[took] * xi_buf[rows, cols][took]))
        wait_at[ids] -= m
        k_at[ids] += m
        v_at[ids] = 0.0
        done[ids] = k_at[ids] >= horizon[ids]

    def brake(ids):
        """Profiles braking for a random stop (no stop point left ahead): the rest of their
        braking at once, up to and including the step in which they come to rest, as
        :func:`general` takes them (a = -max_decel; the speeds by the same additions, the
        positions by the same terms in the same order), and the wait drawn there."""
        if points:
            ids = ids[stop_ptr_at[ids] >= stop_end_all[ids]]
        if not ids.size:
            return
        kk, s0, v0 = k_at[ids], s_at[ids], v_at[ids]
        dmax = dmax_all[ids]
        a = -dmax
        # speeds at the steps' starts by repeated additions of a·Δt (a step that does not
        # stop ends at max(v + aΔt, 0); taken only while that is the plain sum, > 0)
        chain = np.empty((ids.size, W + 1))
        chain[:, 0] = v0
        chain[:, 1:] = (a * dt)[:, None]
        V = np.add.accumulate(chain, axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            t_stop = V / dmax[:, None]
        stop = t_stop <= dt * (1.0 + 1e-9)
        e = _first_true(stop[:, :W])                       # the step that comes to rest
        pos = _leading_true(V[:, 1:W] > 0.0)              # steps whose end speed is > 0
        m = np.where(pos >= e, e + 1, pos)                 # steps taken (e = W: none stops)
        m = np.minimum(m, top[ids] - (kk - base[ids]))     # within the noise drawn
        # the steps' kinematics (general(): tau = Δt, or the time to rest in the stop step)
        Vs = V[:, :W]
        ar_ = ar[None, :]
        is_stop = ar_ == e[:, None]
        tau = np.where(is_stop, np.minimum(t_stop[:, :W], dt), dt)
        v_end = np.where(is_stop, 0.0, np.maximum(Vs + a[:, None] * tau, 0.0))
        a2 = np.broadcast_to(a[:, None], Vs.shape)
        x = np.empty((ids.size, 3 * W + 1))
        x[:, 0] = s0
        x[:, 1::3] = Vs * tau
        x[:, 2::3] = 0.5 * a2 * tau * tau
        x[:, 3::3] = v_end * (dt - tau)
        s_end = np.add.accumulate(x, axis=1)[:, 3::3]
        # the profile's end or horizon: the step that reaches it is its last
        step = kk[:, None] + ar_
        fin = (s_end >= length_all[ids][:, None]) | (step + 1 >= horizon[ids][:, None])
        m = np.minimum(m, _first_true(fin) + 1)
        took = ar_ < m[:, None]
        if not took.any():
            return
        cols = np.minimum((kk - base[ids] + 1)[:, None] + ar_, 2 * W)
        rows = np.broadcast_to(ids[:, None], took.shape)
        n = int(took.sum())
        sig = np.broadcast_to(sigma_all[ids][:, None], took.shape)
        rec.append((rows[took], step[took], a2[took], tau[took],
                    np.full(n, MODE_DECEL, np.uint8), np.zeros(n, bool), s_end[took],
                    v_end[took], sig[took] * xi_buf[rows[took], cols[took]]))
        moved = m > 0
        r, last = np.flatnonzero(moved), m[moved] - 1
        mid = ids[moved]
        s_at[mid] = s_end[r, last]
        v_at[mid] = v_end[r, last]
        k_at[mid] += m[moved]
        rested = moved & (m == e + 1)
        if rested.any():
            q = inp.q_wait[ids][rested]
            q_safe = np.where(q >= 1.0, 0.5, q)
            u_wait = uw_buf[ids[rested], cols[rested, e[rested]]]
            w = np.where(q >= 1.0, 1.0, np.ceil(np.log(u_wait) / np.log1p(-q_safe)))
            w = np.maximum(w, 1.0)
            w = np.minimum(w, inp.max_wait_steps[ids][rested]).astype(np.int64)
            wait_at[ids[rested]] = w
            state_at[ids[rested]] = STOPPED
        done[mid] = ~((s_end[r, last] < length_all[mid]) & (horizon[mid] > k_at[mid]))

    def general(ids):
        """One step of profiles ``ids`` (each at its own local step), any state: the state
        machine of the module doc, step by step."""
        kk = k_at[ids]
        col = kk - base[ids] + 1
        xi, xi_prev = xi_buf[ids, col], xi_buf[ids, col - 1]
        u_stop, u_wait = us_buf[ids, col], uw_buf[ids, col]
        s, v, state, wait_left = s_at[ids], v_at[ids], state_at[ids], wait_at[ids]
        amax, dmax = amax_all[ids], dmax_all[ids]
        stop_ptr, stop_end = stop_ptr_at[ids], stop_end_all[ids]
        # -- target cruise speed of the segment under each vehicle
        j = np.searchsorted(seg_key, s + prof_base[ids], side="right") - 1
        j = np.clip(j, first_seg[ids], last_seg[ids])
        target = seg_target[j]
        # -- state transitions at the step start
        stopped = state == STOPPED
        release = stopped & (wait_left <= 0)
        state[release] = TRACK
        wait_left[stopped & ~release] -= 1
        moving = state != STOPPED
        rand_stop = moving & (state == TRACK) & (v > 0) & (u_stop < p_stop_all[ids])
        state[rand_stop] = BRAKE_RANDOM
        if points:
            next_stop = np.where(stop_ptr < stop_end,
                                 stop_flat[np.minimum(stop_ptr, len(stop_flat) - 1)], np.inf)
            dist = next_stop - s
            v_up = v + amax * dt
            reach = s + v * dt + look_a_all[ids] + v_up * v_up / (2.0 * dmax) >= next_stop
            b_rand = v * v / (2.0 * dmax)
            to_point = (moving & (state != BRAKE_POINT) & reach & (dist > 0)
                        & ~((state == BRAKE_RANDOM) & (b_rand < dist)))
            # At rest within the start-up look-ahead of a stop point (it came to rest just
            # short of it, e.g. by a random stop): that stop counts as made, it drives on.
            served = to_point & (v <= 0.0)
            if served.any():
                stop_ptr[served] += 1
                to_point &= ~served
                next_stop = np.where(stop_ptr < stop_end,
                                     stop_flat[np.minimum(stop_ptr, len(stop_flat) - 1)],
                                     np.inf)
                dist = next_stop - s
            state[to_point] = BRAKE_POINT
        # -- kinematics of the step
        n_act = len(s)
        a = np.zeros(n_act)
        tau = np.full(n_act, dt)
        label = np.full(n_act, MODE_STOPPED, dtype=np.uint8)
        tr = state == TRACK
        with np.errstate(invalid="ignore"):
            ahead = np.maximum(cap_s[j] - (s + v * dt), 0.0)
        cap = np.sqrt(cap_t2[j] + 2.0 * d_cap_all[ids] * ahead)
        sigma = sigma_all[ids]
        noisy = target + sigma * xi
        v_des = np.maximum(np.minimum(noisy, cap), 0.0)
        raw = (v_des - v) / dt
        a_tr = np.clip(raw, -dmax, amax)
        a = np.where(tr, a_tr, a)
        label = np.where(tr, np.where(raw > amax, MODE_ACCEL,
                                      np.where(raw < -dmax, MODE_DECEL, MODE_CRUISE)), label)
        br = state == BRAKE_RANDOM
        t_br = v / dmax
        if points:
            bp = state == BRAKE_POINT
            with np.errstate(divide="ignore", invalid="ignore"):
                a_bp = np.where(dist > 0, -v * v / (2.0 * dist), 0.0)
                t_bp = np.where(v > 0, 2.0 * dist / v, np.inf)
            a = np.where(bp, a_bp, np.where(br, -dmax, a))
            t_stop = np.where(bp, t_bp, np.where(br, t_br, np.inf))
            # A stop point reached up to rounding (the last braking step may leave ~1e-13 m/s
            # and ~1e-12 m) counts as reached in this step.
            braking = bp | br
            stops = braking & (t_stop <= dt * (1.0 + 1e-9))
            stops |= bp & (dist <= 1e-9)
        else:           # no stop points in the fleet: only random stops brake
            a = np.where(br, -dmax, a)
            t_stop = np.where(br, t_br, np.inf)
            braking = br
            stops = br & (t_stop <= dt * (1.0 + 1e-9))
        tau = np.where(stops, np.minimum(t_stop, dt), tau)
        label = np.where(braking, MODE_DECEL, label)
        v_end = np.where(stops, 0.0, np.maximum(v + a * tau, 0.0))
        s_end = s + v * tau + 0.5 * a * tau * tau + v_end * (dt - tau)
        if points:
            s_end = np.where(stops & bp, next_stop, s_end)
        # free cruise from the free target c + σξ_k to c + σξ_{k+1}: the speed bridge
        x0, x1 = sigma * xi_prev, sigma * xi
        free = (tr & (label == MODE_CRUISE) & (v_des == noisy) & (sigma > 0)
                & ~stops & (np.abs(v - (target + x0)) <= 1e-9 * np.maximum(v, 1.0))
                & (np.minimum(v, v_des)
                   >= speed_bridge.GUARD * np.maximum(np.abs(x0), np.abs(x1)))
                & (kk > 0))
        free = speed_bridge.drop_past_limits(free, raw, x0, x1, kappa[ids], e1_all[ids],
                                             e2_all[ids], dt, amax, dmax)
        if free.any():
            s_end = np.where(free, s_end + 0.5 * (x0 + x1) * c1[ids] * dt, s_end)
        still = state == STOPPED
        a = np.where(still, 0.0, a)
        v_end = np.where(still, 0.0, v_end)
        s_end = np.where(still, s, s_end)
        # -- vehicles come to rest: draw the geometric wait, advance past a reached stop point
        if stops.any():
            q = inp.q_wait[ids][stops]
            q_safe = np.where(q >= 1.0, 0.5, q)
            w = np.where(q >= 1.0, 1.0, np.ceil(np.log(u_wait[stops]) / np.log1p(-q_safe)))
            w = np.maximum(w, 1.0)
            w = np.minimum(w, inp.max_wait_steps[ids][stops]).astype(np.int64)
            wait_left[stops] = w
            state[stops] = STOPPED
            if points:
                stop_ptr[stops & bp] += 1
        rec.append((ids, kk, a, tau, label, free, s_end, v_end, x1))
        s_at[ids], v_at[ids], state_at[ids], wait_at[ids] = s_end, v_end, state, wait_left
        stop_ptr_at[ids] = stop_ptr
        k_at[ids] = kk + 1
        # -- profiles that are done or at their horizon leave the active set
        done[ids] = ~((s_end < length_all[ids]) & (horizon[ids] > kk + 1))

    bar = bars.stage_counter(K, progress, desc="truth", unit="step", leave=False,
                             mininterval=0.5)
    def ahead(ids):
        """Draw the block after the current one of those of profiles ``ids`` that have one
        within their horizon and are not expected to end within the current block."""
        ids = ids[(horizon[ids] > base[ids] + W)
                  & _ahead_wanted(length_all[ids] - s_at[ids],
                                  (W - (k_at[ids] - base[ids])) * dt, slow_mps[ids])]
        fill(ids, base[ids] // W + 1, W + 1)
        top[ids] = 2 * W

    act = np.arange(P)
    fill(act, np.zeros(P, np.int64), 1)
    ahead(act)
    shown = 0
    while act.size:
        # slide the noise window of the profiles that entered their second block (drawing
        # it now where it was not drawn ahead)
        sh = act[k_at[act] - base[act] >= W]
        if sh.size:
            for buf in (xi_buf, us_buf, uw_buf):
                buf[sh, :W + 1] = buf[sh, W:]
            base[sh] += W
            late = sh[top[sh] == W]
            fill(late, base[late] // W, 1)
            top[sh] = W
            ahead(sh)
        # A round: windows for the tracking profiles, then one step each (general) for the
        # others and for those whose window was cut short (a random stop, a stop point
        # ahead, no fixed point), then the rest of a random stop's braking and whole waits
        # for the profiles now braking or at rest: a stop takes one or two rounds, not one a
        # step.  Any order gives the step loop's result (each profile's steps are its own);
        # every part stays within the noise drawn (column ``top``, 2W at most).
        st = state_at[act]
        took = np.zeros(act.size, np.int64)
        tr = np.flatnonzero(st == TRACK) if windows else np.zeros(0, np.int64)
        for c0 in range(0, tr.size, _WINDOW_ROWS):    # bounded (cache-sized) temporaries
            part = tr[c0:c0 + _WINDOW_ROWS]
            took[part] = speculate(act[part])
        one = took == 0
        if windows:
            one &= ~((st == STOPPED) & (wait_at[act] > 0))
            one |= (took > 0) & (took < W) & (state_at[act] == TRACK) & ~done[act]
            one &= k_at[act] - base[act] < top[act]        # its step's noise is drawn
        rest = act[one]
        if rest.size:
            general(rest)
        if windows:
            live = act[~done[act] & (k_at[act] - base[act] < top[act])]
            br = live[state_at[live] == BRAKE_RANDOM]
            if br.size:
                brake(br)
                live = live[~done[live]]
            wt = live[(state_at[live] == STOPPED) & (wait_at[live] > 0)]
            if wt.size:
                wait(wt)
        act = act[~done[act]]
        if act.size and progress:
            low = int(k_at[act].min())
            bar.update(max(low - shown, 0))
            shown = max(shown, low)
    bar.close()
    return _flatten(P, dt, np.asarray(inp.v0_mps, float), horizon, kappa, rec)
