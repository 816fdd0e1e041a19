r"""Speed profiles, stored flat, and the state of a vehicle on its route at any instant
(DESIGN §3): what :func:`gmtiflow.scene.motion.simulate_profiles` produces.

A vehicle is a speed profile along its route polyline: on a time grid
:math:`\tau_k = k\,\Delta t` (local time since the profile's start) each step stores the arc length
:math:`s_k`, the speed :math:`v_k` at the step start, a constant acceleration :math:`a_k` that acts
for :math:`\tau'_k \le \Delta t` (the exact in-step instant at which a braking vehicle reaches
:math:`v = 0`; afterwards the speed stays :math:`v_{k+1}`), and a mode label. Hence for
:math:`u = \tau - \tau_k`

.. math::
    s(\tau) = s_k + v_k u + \tfrac12 a_k u^2 \quad (u < \tau'_k), \qquad
    s(\tau) = s_{k+1} - v_{k+1} (\Delta t - u) \quad (u \ge \tau'_k),

exact at any instant, plus, in a free-cruise step, the speed bridge's integral
(:mod:`gmtiflow.scene.speed_bridge`).  Units: s in m, v in m/s, a in m/s², τ and Δt in s.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from gmtiflow.scene import speed_bridge

MODE_CRUISE, MODE_DECEL, MODE_STOPPED, MODE_ACCEL = 0, 1, 2, 3
"""The mode label of a step (``mode``; /truth's ``mode``): cruise, decelerate, stopped,
accelerate."""


@dataclass
class Profiles:
    """Speed profiles on the grid tau_k = k dt, stored flat per profile (P profiles).

    Profile p has ``n_steps_p[p]`` steps (until it is done or reaches its horizon): its step
    values (``a_flat``, ``tau_flat``, ``mode_flat``) are at ``step_offset[p] + k`` and its grid
    values (``s_flat``, ``v_flat``, ``noise_flat``, one more) at ``step_offset[p] + p + k``;
    ``bridge_flat`` marks the free-cruise steps that carry the speed bridge (module doc) and
    ``kappa`` is 2(1 − ρ) per profile.  The dense (K+1, P) / (K, P) views ``s_m``, ``v_mps``,
    ``noise_mps``, ``a_mps2``, ``tau_s``, ``mode``, ``bridge`` (K = the longest horizon) are for
    inspection and tests: after its last step a profile holds its end position at rest (a = 0,
    tau = dt, mode cruise, no noise).
    """

    dt_s: float
    n_steps_p: np.ndarray      # (P,) steps stored
    horizon_steps: np.ndarray  # (P,) steps of each profile's horizon
    step_offset: np.ndarray    # (P+1,)
    s_flat: np.ndarray
    v_flat: np.ndarray
    a_flat: np.ndarray
    tau_flat: np.ndarray       # (Δt as one read-only value where no step stops inside)
    mode_flat: np.ndarray
    noise_flat: np.ndarray     # σξ_k at the grid points (+0, read-only, if none is bridged)
    bridge_flat: np.ndarray    # bool per step
    kappa: np.ndarray          # (P,)
    _dense: dict = field(default_factory=dict, repr=False)
    _bconst: Optional[tuple] = field(default=None, repr=False)    # bridge_constants(kappa)

    @property
    def n_steps(self) -> int:
        """Steps of the longest horizon (the dense views' K)."""
        return int(self.horizon_steps.max()) if self.horizon_steps.size else 0

    def _view(self, name: str) -> np.ndarray:
        if name not in self._dense:
            P, K = len(self.n_steps_p), self.n_steps
            p = np.repeat(np.arange(P), self.n_steps_p)
            k = np.arange(len(p)) - self.step_offset[p]
            last = self.step_offset[1:] + np.arange(P)      # each profile's last grid value
            if name in ("s_m", "v_mps", "noise_mps"):
                flat = {"s_m": self.s_flat, "v_mps": self.v_flat,
                        "noise_mps": self.noise_flat}[name]
                out = (np.broadcast_to(flat[last], (K + 1, P)).copy() if name == "s_m"
                       else np.zeros((K + 1, P)))
                out[0] = flat[self.step_offset[:-1] + np.arange(P)]
                out[k + 1, p] = flat[self.step_offset[p] + p + k + 1]
            else:
                flat, fill, dtype = {"a_mps2": (self.a_flat, 0.0, float),
                                     "tau_s": (self.tau_flat, self.dt_s, float),
                                     "mode": (self.mode_flat, MODE_CRUISE, np.uint8),
                                     "bridge": (self.bridge_flat, False, bool)}[name]
                out = np.full((K, P), fill, dtype=dtype)
                out[k, p] = flat
            self._dense[name] = out
        return self._dense[name]

    s_m = property(lambda self: self._view("s_m"))          # (K+1, P)
    v_mps = property(lambda self: self._view("v_mps"))      # (K+1, P)
    a_mps2 = property(lambda self: self._view("a_mps2"))    # (K, P)
    tau_s = property(lambda self: self._view("tau_s"))      # (K, P) duration of a_k in the step
    mode = property(lambda self: self._view("mode"))        # (K, P) uint8 label of the step
    noise_mps = property(lambda self: self._view("noise_mps"))  # (K+1, P) σξ_k
    bridge = property(lambda self: self._view("bridge"))    # (K, P) bool

    def evaluate(self, tau_s, p):
        """(s, v, a, mode) of profiles ``p`` at local times ``tau_s`` (broadcast arrays).

        Times are clipped to the profile's stored steps; beyond them its last state holds.
        """
        dt = self.dt_s
        tau, p = np.broadcast_arrays(np.asarray(tau_s, float), np.asarray(p, dtype=np.int64))
        n = self.n_steps_p[p]
        tau = np.clip(tau, 0.0, n * dt)
        k = np.clip(np.floor(tau / dt).astype(np.int64), 0, n - 1)
        u = tau - k * dt
        i = self.step_offset[p] + k
        g = i + p
        s0 = self.s_flat[g]
        v0 = self.v_flat[g]
        a = self.a_flat[i]
        tk = self.tau_flat[i]
        early = u < tk
        # rows past the in-step instant τ'_k (at rest after a stop within the step): few
        late = np.flatnonzero(~early) if early.ndim == 1 else None
        if late is not None and 4 * late.size < early.size:
            # each row's value is that of its branch below, computed for the rows it picks
            s = s0 + v0 * u + 0.5 * a * u * u
            v = np.maximum(v0 + a * u, 0.0)
            acc = a                          # (a gathered copy of its own)
            if late.size:
                g1 = g[late] + 1
                v1 = self.v_flat[g1]
                s[late] = self.s_flat[g1] - v1 * (dt - u[late])
                v[late] = v1
                acc[late] = 0.0
        else:
            s1 = self.s_flat[g + 1]
            v1 = self.v_flat[g + 1]
            s = np.where(early, s0 + v0 * u + 0.5 * a * u * u, s1 - v1 * (dt - u))
            v = np.where(early, np.maximum(v0 + a * u, 0.0), v1)
            acc = np.where(early, a, 0.0)
        br = self.bridge_flat[i] & early      # at u = Δt the grid value s_{k+1} holds
        nb = np.count_nonzero(br)
        if 2 * nb > br.size:
            # most rows bridged (free cruise with speed noise): the bridge of every row
            # (finite for any grid values) and a select, instead of gathers and scatters
            if self._bconst is None:
                self._bconst = speed_bridge.bridge_constants(self.kappa)
            d, dd, integral = speed_bridge.bridge(self.noise_flat[g], self.noise_flat[g + 1],
                                                  self.kappa[p], u / dt,
                                                  tuple(c[p] for c in self._bconst))
            s, v, acc = np.broadcast_arrays(s, v, acc)
            s = np.where(br, s + integral * dt, s)
            v = np.where(br, v + d, v)
            acc = np.where(br, acc + dd / dt, acc)
        elif nb:
            j = np.flatnonzero(br)
            gb = g[br]
            d, dd, integral = speed_bridge.bridge(self.noise_flat[gb],
                                                  self.noise_flat[gb + 1],
                                                  self.kappa[p[br]], u[br] / dt)
            s, v, acc = (np.array(x, float, copy=True) for x in np.broadcast_arrays(s, v, acc))
            s.flat[j] += integral * dt
            v.flat[j] += d
            acc.flat[j] += dd / dt
        mode = self.mode_flat[i]
        if late is not None:    # only rows past τ'_k can be at rest (a gathered copy of its own)
            rest = late[(v[late] == 0.0) & (mode[late] == MODE_DECEL)]
            mode[rest] = MODE_STOPPED
            return s, v, acc, mode.astype(np.uint8, copy=False)
        mode = np.where((v == 0.0) & (mode == MODE_DECEL) & ~early, MODE_STOPPED, mode)
        return s, v, acc, mode.astype(np.uint8)

    def time_at(self, p: int, s_target: float) -> float:
        """First local time at which profile ``p`` reaches arc length ``s_target`` (inf: never
        within its stored steps); :meth:`times_at` of one pair."""
        return float(self.times_at(np.asarray([p], np.int64), np.asarray([s_target], float))[0])

    def times_at(self, p, s_target) -> np.ndarray:
        """First local times at which profiles ``p`` (n,) reach arc lengths ``s_target`` (n,)
        (inf: never within their stored steps), all pairs at once.

        The step is found by a binary search in each profile's own run of grid values; within
        it, s(τ) is inverted in closed form (constant acceleration, then rest), in a bridged
        step (:func:`~gmtiflow.scene.speed_bridge.bridge`) by Newton's method from u = Δt/2
        with bisection as a fallback (:meth:`_bridged_times`)."""
        p = np.asarray(p, np.int64).ravel()
        x = np.asarray(s_target, float).ravel()
        dt = self.dt_s
        i0 = self.step_offset[p]
        g0 = i0 + p                              # each profile's first grid value
        n_col = self.n_steps_p[p] + 1
        # leftmost i with s[i] >= x (numpy's searchsorted 'left' on the profile's column)
        lo = np.zeros(p.size, np.int64)
        hi = n_col.copy()
        while True:
            open_ = lo < hi
            if not open_.any():
                break
            mid = lo + ((hi - lo) >> 1)
            below = open_ & (self.s_flat[g0 + np.minimum(mid, n_col - 1)] < x)
            above = open_ & ~below
            lo = np.where(below, mid + 1, lo)
            hi = np.where(above, mid, hi)
        i = lo
        out = np.zeros(p.size)
        out[i >= n_col] = np.inf
        r = np.flatnonzero((i > 0) & (i < n_col))
        if not r.size:
            return out
        k = i[r] - 1
        ks = i0[r] + k
        gs = g0[r] + k
        xr = x[r]
        s0, v0 = self.s_flat[gs], self.v_flat[gs]
        a, tk = self.a_flat[ks], self.tau_flat[ks]
        br = self.bridge_flat[ks]
        u = np.empty(r.size)
        plain = np.flatnonzero(~br)
        if plain.size:
            s0p, v0p, ap, tkp, xp = s0[plain], v0[plain], a[plain], tk[plain], xr[plain]
            s_tau = s0p + v0p * tkp + 0.5 * ap * tkp * tkp
            d = xp - s0p
            early = xp <= s_tau
            with np.errstate(divide="ignore", invalid="ignore"):
                root = np.sqrt(np.maximum(v0p * v0p + 2.0 * ap * d, 0.0))
                den = v0p + root
                u_early = np.where(den <= 0, 0.0, 2.0 * d / den)
                v1 = self.v_flat[gs[plain] + 1]
                u_late = np.where(v1 > 0, tkp + (xp - s_tau) / v1, dt)
            u[plain] = np.minimum(np.maximum(np.where(early, u_early, u_late), 0.0), dt)
        bridged = np.flatnonzero(br)
        if bridged.size:
            u[bridged] = self._bridged_times(gs[bridged], ks[bridged], p[r[bridged]],
                                             xr[bridged])
        out[r] = k * dt + u
        return out

    def _bridged_times(self, g, i, p, s_target) -> np.ndarray:
        """Times into bridged steps (grid index ``g``, step index ``i``, profile ``p``) at
        which s reaches ``s_target``: Newton on s(u) from u = Δt/2 (s is increasing and smooth
        there, v > 0), bisection as a fallback; per element the scalar iteration, its
        operations in its order (so the result does not depend on the other elements)."""
        dt = self.dt_s
        s0, v0, a = self.s_flat[g], self.v_flat[g], self.a_flat[i]
        x0, x1 = self.noise_flat[g], self.noise_flat[g + 1]
        kap = self.kappa[p]
        n = len(g)
        lo = np.zeros(n)
        hi = np.full(n, dt)
        u = np.full(n, 0.5 * dt)
        tol = 1e-12 * np.where(np.abs(s_target) > 1.0, np.abs(s_target), 1.0)
        act = np.arange(n)
        for _ in range(60):
            if not act.size:
                break
            ua = u[act]
            d, integral = speed_bridge.bridge_exact(x0[act], x1[act], kap[act], ua / dt)
            a_ = a[act]
            su = s0[act] + v0[act] * ua + 0.5 * a_ * ua * ua + integral * dt
            vu = v0[act] + a_ * ua + d
            err = su - s_target[act]
            conv = np.abs(err) <= tol[act]
            low = err < 0
            lo_a = np.where(low, ua, lo[act])
            hi_a = np.where(low, hi[act], ua)
            mid = 0.5 * (lo_a + hi_a)
            with np.errstate(divide="ignore", invalid="ignore"):
                nxt = np.where(vu > 0, ua - err / vu, mid)
            u_new = np.where((lo_a < nxt) & (nxt < hi_a), nxt, mid)
            go = ~conv
            lo[act] = np.where(go, lo_a, lo[act])
            hi[act] = np.where(go, hi_a, hi[act])
            u[act] = np.where(go, u_new, ua)
            act = act[go & ~(hi_a - lo_a < 1e-12 * dt)]
        return u
