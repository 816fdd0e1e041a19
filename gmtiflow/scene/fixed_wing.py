"""Fixed-wing platform: a waypoint loop flown with coordinated turns (paper §4, DESIGN §4).

The orbit is the closed polygon through the waypoints (x, y, altitude in scene ENU metres),
flown at constant horizontal speed ``v`` and looping back to the first waypoint.  At a corner
whose heading changes by ``α`` the aircraft does not fly the sharp edge but a circle tangent to
both legs, entered ``s = v·t`` before the corner (``t`` = ``turn_lead_s``).  Paper eq. 4 gives its
radius and eq. 3 the bank of a coordinated turn:

.. math::  r = \\frac{s}{\\tan(α/2)}, \\qquad φ = \\arctan\\frac{v^2}{r g}
           = \\arctan\\frac{v \\tan(α/2)}{t g}

(the paper's eq. 5 drops a ``v``; DESIGN §4).  Conventions: heading clockwise from north,
bank ``+`` = right wing down (a right turn), as STANAG 4607 D23.  Roll is applied instantly at the
start and end of the arc.  Each waypoint's altitude is reached at the middle of its turn; between
two such knots the altitude follows the cosine profile of :func:`gmtiflow.scene.flight.cosine_blend`
in path length, so the vertical speed is zero at each knot and continuous everywhere.  Pitch is
the flight-path angle.

Time zero is the end of the turn around the first waypoint, on the leg to the second one.
The path is a sequence of straight and circular pieces with a cumulative path length, so the
state at any set of instants is one vectorised evaluation (no time stepping).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gmtiflow import frames
from gmtiflow.scene import flight
from gmtiflow.scene.platform_config import PlatformConfig
from gmtiflow.tables import Table


@dataclass(frozen=True)
class Orbit:
    """The flown path as pieces: straight (``radius_m`` = inf) or circular arcs."""

    start_s_m: np.ndarray      # cumulative path length at the start of each piece
    length_m: np.ndarray
    start_xy_m: np.ndarray     # (n, 2) position where each piece starts
    heading_rad: np.ndarray    # heading at the start of each piece
    turn_sign: np.ndarray      # +1 right (clockwise) turn, -1 left, 0 straight
    radius_m: np.ndarray
    bank_rad: np.ndarray
    alt_knots_s_m: np.ndarray  # path length of each altitude knot (middle of each turn)
    alt_knots_m: np.ndarray
    total_m: float
    speed_mps: float


def build_orbit(cfg: PlatformConfig) -> Orbit:
    """Lay out the closed orbit of straight legs and coordinated-turn arcs."""
    wps = np.asarray(cfg.waypoints_m, float)
    n = len(wps)
    xy, alt = wps[:, :2], wps[:, 2]
    v = float(cfg.speed_mps)
    delta = np.roll(xy, -1, axis=0) - xy                    # leg i: wp i -> wp i+1
    leg_len = np.linalg.norm(delta, axis=1)
    leg_head = frames.heading_rad(delta[:, 0], delta[:, 1])
    alpha = flight.signed_turn_rad(np.roll(leg_head, 1), leg_head)   # turn at wp i
    lead = np.full(n, v * cfg.turn_lead_s)
    half_alpha = np.abs(alpha) / 2.0
    turning = half_alpha > 1e-12
    tan_half = np.tan(np.minimum(half_alpha, np.pi / 2.0 - 1e-12))
    radius = np.where(turning, lead / np.where(turning, tan_half, 1.0), np.inf)
    lead = np.where(turning, lead, 0.0)
    with np.errstate(divide="ignore"):
        bank = np.where(turning, np.arctan2(v * v, radius * flight.G_MPS2), 0.0) * np.sign(alpha)

    # Pieces in flight order from the end of the turn at wp 0: leg 0, turn 1, leg 1, ... turn 0.
    starts_xy, heads, lengths, signs, radii, banks = [], [], [], [], [], []
    for i in range(n):
        j = (i + 1) % n
        u = delta[i] / leg_len[i]
        starts_xy.append(xy[i] + u * lead[i])
        heads.append(leg_head[i])
        lengths.append(max(leg_len[i] - lead[i] - lead[j], 0.0))
        signs.append(0.0)
        radii.append(np.inf)
        banks.append(0.0)
        starts_xy.append(xy[j] - u * lead[j])
        heads.append(leg_head[i])
        lengths.append(radius[j] * abs(alpha[j]) if turning[j] else 0.0)
        signs.append(float(np.sign(alpha[j])) if turning[j] else 0.0)
        radii.append(radius[j])
        banks.append(bank[j])
    lengths = np.asarray(lengths)
    start_s = np.concatenate([[0.0], np.cumsum(lengths)[:-1]])
    total = float(lengths.sum())
    # Altitude knot of wp j at the middle of its turn (piece 2i+1 is the turn at wp i+1).
    knot_s = start_s[1::2] + lengths[1::2] / 2.0
    knot_alt = alt[(np.arange(n) + 1) % n]
    order = np.argsort(knot_s, kind="stable")
    return Orbit(start_s_m=start_s, length_m=lengths, start_xy_m=np.asarray(starts_xy),
                 heading_rad=np.asarray(heads), turn_sign=np.asarray(signs),
                 radius_m=np.asarray(radii), bank_rad=np.asarray(banks),
                 alt_knots_s_m=knot_s[order], alt_knots_m=knot_alt[order], total_m=total,
                 speed_mps=v)


class FixedWing:
    """State of the aircraft at any instants (vectorised); ``cfg`` must be validated."""

    def __init__(self, cfg: PlatformConfig, origin: frames.Origin):
        self.cfg = cfg
        self.origin = origin
        self.orbit = build_orbit(cfg)

    def _altitude(self, s: np.ndarray):
        """Altitude and its slope d(alt)/ds: cosine profile between knots, periodic in s."""
        o = self.orbit
        ks = np.concatenate([o.alt_knots_s_m - o.total_m, o.alt_knots_s_m,
                             o.alt_knots_s_m + o.total_m])
        ka = np.tile(o.alt_knots_m, 3)
        i = np.clip(np.searchsorted(ks, s, side="right") - 1, 0, len(ks) - 2)
        ds = ks[i + 1] - ks[i]
        span = np.where(ds > 0, ds, 1.0)
        u = np.clip((s - ks[i]) / span, 0.0, 1.0)
        blend, dblend = flight.cosine_blend(u)
        dz = ka[i + 1] - ka[i]
        alt = ka[i] + dz * blend
        slope = np.where(ds > 0, dz * dblend / span, 0.0)
        return alt, slope

    def state_at(self, time_s) -> Table:
        """The /platform columns (docs/tables.md) at each of ``time_s``."""
        o = self.orbit
        t = np.atleast_1d(np.asarray(time_s, float))
        s = np.mod(o.speed_mps * t, o.total_m)
        k = np.clip(np.searchsorted(o.start_s_m, s, side="right") - 1, 0, len(o.length_m) - 1)
        u = s - o.start_s_m[k]
        h0 = o.heading_rad[k]
        sign = o.turn_sign[k]
        radius = o.radius_m[k]
        x0, y0 = o.start_xy_m[k, 0], o.start_xy_m[k, 1]
        arc = sign != 0.0
        # Straight: advance along the heading.  Arc: heading turns by sign*u/r; the chord of a
        # circular arc is 2 r sin(θ/2) along the mean heading h0 + sign θ/2.
        safe_r = np.where(arc, radius, 1.0)
        theta = np.where(arc, u / safe_r, 0.0)
        heading = np.mod(h0 + sign * theta, 2.0 * np.pi)
        chord = np.where(arc, 2.0 * safe_r * np.sin(theta / 2.0), u)
        mean_head = h0 + sign * theta / 2.0
        x = x0 + chord * np.sin(mean_head)
        y = y0 + chord * np.cos(mean_head)
        z, slope = self._altitude(s)
        v = o.speed_mps
        vx, vy, vz = v * np.sin(heading), v * np.cos(heading), v * slope
        return flight.state_table(self.origin, t, x, y, z, vx, vy, vz, heading,
                                  np.arctan2(vz, v), o.bank_rad[k].copy())
