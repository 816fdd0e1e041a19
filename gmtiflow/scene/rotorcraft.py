"""Rotorcraft ("UAV-copter", paper §4): straight legs between waypoints, hovering at each one.

The loop is: hover ``hover_s[0]`` at waypoint 0, fly to waypoint 1, hover ``hover_s[1]``, ...,
fly back to waypoint 0, and repeat; time zero is the arrival at waypoint 0 (start of its hover).
These holds are the paper's helicopter "stop events": the platform is at rest, bank zero.

On each leg of horizontal length ``L`` the speed follows a trapezoid: accelerate at
``a = accel_mps2`` from rest to the cruise speed ``v = speed_mps``, cruise, brake at ``a`` to rest
(a triangle with peak ``√(a L)`` when the leg is shorter than ``v²/a``).  The leg lasts
``L/v + v/a`` (or ``2√(L/a)``).  Position is C¹: the velocity is continuous and is the exact
derivative of the position.  Altitude changes linearly with horizontal path length along a leg,
so the vertical speed is ``slope × speed``: continuous, zero at both ends of the leg.

Attitude: the heading is that of the leg while flying; during a hover the aircraft yaws at a
constant rate from the arriving leg's heading to the next leg's (the shorter way round), so the
heading is continuous when ``hover_s > 0``.  Pitch is the flight-path angle (0 while hovering),
bank is 0 throughout (no coordinated turns: the legs are straight, corners are flown at rest).
"""
from __future__ import annotations

import numpy as np

from gmtiflow import frames
from gmtiflow.scene import flight
from gmtiflow.scene.platform_config import PlatformConfig
from gmtiflow.tables import Table


class Rotorcraft:
    """State of the rotorcraft at any instants (vectorised); ``cfg`` must be validated."""

    def __init__(self, cfg: PlatformConfig, origin: frames.Origin):
        self.cfg = cfg
        self.origin = origin
        wps = np.asarray(cfg.waypoints_m, float)
        self.xyz_m = wps
        delta = np.roll(wps, -1, axis=0) - wps                  # leg i: wp i -> wp i+1
        self.leg_len_m = np.hypot(delta[:, 0], delta[:, 1])
        self.leg_head_rad = frames.heading_rad(delta[:, 0], delta[:, 1])
        self.leg_slope = delta[:, 2] / self.leg_len_m          # d(alt)/d(horizontal path)
        a, v = float(cfg.accel_mps2), float(cfg.speed_mps)
        self.accel_mps2 = a
        self.peak_mps = np.minimum(v, np.sqrt(a * self.leg_len_m))
        ramp_s = self.peak_mps / a
        self.leg_s = 2.0 * ramp_s + (self.leg_len_m - self.peak_mps * ramp_s) / self.peak_mps
        self.hover_s = cfg.hover_times_s()
        # Timeline: hover 0, leg 0, hover 1, leg 1, ...
        durations = np.column_stack([self.hover_s, self.leg_s]).ravel()
        self.start_s = np.concatenate([[0.0], np.cumsum(durations)[:-1]])
        self.period_s = float(durations.sum())
        arriving = np.roll(self.leg_head_rad, 1)                # heading arriving at wp i
        self.yaw_rad = flight.signed_turn_rad(arriving, self.leg_head_rad)
        self.arrive_head_rad = arriving

    def state_at(self, time_s) -> Table:
        """The /platform columns (docs/tables.md) at each of ``time_s``."""
        t = np.atleast_1d(np.asarray(time_s, float))
        tau_all = np.mod(t, self.period_s)
        seg = np.clip(np.searchsorted(self.start_s, tau_all, side="right") - 1, 0,
                      len(self.start_s) - 1)
        i = seg // 2                                   # waypoint / leg index
        flying = (seg % 2) == 1
        tau = tau_all - self.start_s[seg]

        # Along-leg distance and speed of the trapezoid (zero while hovering).
        a = self.accel_mps2
        vp, T, L = self.peak_mps[i], self.leg_s[i], self.leg_len_m[i]
        ramp = vp / a
        tl = np.clip(tau, 0.0, T)
        accel = tl < ramp
        brake = tl > T - ramp
        dist = np.where(accel, 0.5 * a * tl ** 2,
                        np.where(brake, L - 0.5 * a * (T - tl) ** 2, 0.5 * vp * ramp
                                 + vp * (tl - ramp)))
        speed = np.where(accel, a * tl, np.where(brake, a * (T - tl), vp))
        dist = np.where(flying, np.clip(dist, 0.0, L), 0.0)
        speed = np.where(flying, np.maximum(speed, 0.0), 0.0)

        head_leg = self.leg_head_rad[i]
        hover_len = np.where(self.hover_s[i] > 0, self.hover_s[i], 1.0)
        frac = np.where(self.hover_s[i] > 0, np.clip(tau / hover_len, 0.0, 1.0), 1.0)
        head_hover = self.arrive_head_rad[i] + self.yaw_rad[i] * frac
        heading = np.mod(np.where(flying, head_leg, head_hover), 2.0 * np.pi)

        x0, y0, z0 = self.xyz_m[i, 0], self.xyz_m[i, 1], self.xyz_m[i, 2]
        x = x0 + dist * np.sin(head_leg)
        y = y0 + dist * np.cos(head_leg)
        z = z0 + dist * self.leg_slope[i]
        vx, vy = speed * np.sin(head_leg), speed * np.cos(head_leg)
        vz = speed * self.leg_slope[i]
        pitch = np.where(flying, np.arctan(self.leg_slope[i]), 0.0)
        return flight.state_table(self.origin, t, x, y, z, vx, vy, vz, heading, pitch,
                                  np.zeros_like(t))
