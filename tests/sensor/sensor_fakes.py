"""Small fakes of the Fleet, Platform and Terrain interfaces (docs/architecture.md).

The real implementations are written in parallel; these implement only what the sensor stage
uses, with geometry simple enough to check against formulas:

* :class:`LineFleet` — vehicles moving in straight lines at constant velocity from a start
  position, active between a start and an end time, optionally on an invisible road.
* :class:`LevelPlatform` — straight-and-level flight at constant speed with a settable bank.
* :class:`FlatTerrain` (``flat=True``, height 0, always visible) and :class:`WallTerrain`, flat
  ground with a wall that blocks rays crossing it below its top.

The default scene: the platform flies west along y = −30 km at 6 km altitude (heading 270°), so
its right side-looking antenna looks north at the scene around the origin.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from gmtiflow import frames

ORIGIN = frames.Origin(48.0, 11.0, 500.0)
#: The round earth of the scenes run with ORIGIN (the model's sphere: its radius is a
#: parameter of the model, the triangle below is the independent part).
RADIUS_M = frames.sphere_radius_m(ORIGIN)


def ground_angles(height_m, slant_m=None, depression_rad=None, radius_m=RADIUS_M):
    """Textbook round-earth triangle of a platform at ``height_m`` above a ground point at
    slant range ``slant_m`` (or at depression ``depression_rad``): (ground arc distance m,
    depression at the platform rad, slant range m).  Law of cosines / law of sines on the
    sphere, independent of gmtiflow's implementation."""
    a = radius_m + height_m
    if slant_m is not None:
        cos_t = (a * a + radius_m * radius_m - slant_m * slant_m) / (2.0 * a * radius_m)
        theta = math.acos(cos_t)
        # depression: angle below the platform's horizontal, from the law of sines
        sin_dep = (a * a + slant_m * slant_m - radius_m * radius_m) / (2.0 * a * slant_m)
        return radius_m * theta, math.asin(sin_dep), slant_m
    # the ray at depression δ meets the sphere where sin(angle at the centre + δ) ... :
    # central angle θ = δ − acos(a cos δ / R) (the nearer intersection, sine rule)
    theta = depression_rad - math.acos(a * math.cos(depression_rad) / radius_m)
    slant = math.sqrt(a * a + radius_m * radius_m - 2 * a * radius_m * math.cos(theta))
    return radius_m * theta, depression_rad, slant


class LineFleet:
    """Constant-velocity vehicles: ``x(t) = p0 + v (t − t_start)`` while active."""

    def __init__(self, p0, v, *, start_s=None, end_s=None, invisible=None, types=None):
        self.p0 = np.atleast_2d(np.asarray(p0, float))
        n = len(self.p0)
        self.v = np.broadcast_to(np.atleast_2d(np.asarray(v, float)), (n, 3)).copy()
        self.start = np.zeros(n) if start_s is None else np.asarray(start_s, float)
        self.end = np.full(n, np.inf) if end_s is None else np.asarray(end_s, float)
        self.inv = np.zeros(n, bool) if invisible is None else np.asarray(invisible, bool)
        types = ["car"] * n if types is None else list(types)
        self.vehicles = {
            "vehicle_id": np.arange(n, dtype=np.int64),
            "name": np.array([f"v{i}" for i in range(n)]),
            "convoy_id": np.full(n, -1, np.int64),
            "vehicle_type": np.array(types),
            "start_time_s": self.start.copy(),
            "route_length_m": np.full(n, 1e5),
            "off_road": np.zeros(n, bool),
        }
        self._speed = np.hypot(self.v[:, 0], self.v[:, 1])
        self._heading = frames.heading_rad(self.v[:, 0], self.v[:, 1])

    def state_at(self, time_s, vehicle_id, columns=None):   # every column, whatever asked
        t, vid = np.broadcast_arrays(np.asarray(time_s, float), np.asarray(vehicle_id))
        t, vid = t.ravel(), vid.ravel().astype(np.int64)
        active = (t >= self.start[vid]) & (t <= self.end[vid])
        dt = t - self.start[vid]
        n = t.size
        zeros = np.zeros(n)
        out = {"time_s": t, "vehicle_id": vid, "convoy_id": np.full(n, -1, np.int64)}
        for k, c in enumerate("xyz"):
            out[f"{c}_m"] = self.p0[vid, k] + self.v[vid, k] * dt
            out[f"v{c}_mps"] = self.v[vid, k]
            out[f"a{c}_mps2"] = zeros
        out.update({
            "speed_mps": self._speed[vid], "heading_rad": self._heading[vid],
            "route_s_m": self._speed[vid] * dt, "edge_id": np.zeros(n, np.int64),
            "mode": np.zeros(n, np.uint8), "invisible": self.inv[vid], "active": active,
        })
        if not np.all(active):
            for k in ("x_m", "y_m", "z_m", "vx_mps", "vy_mps", "vz_mps"):
                out[k] = np.where(active, out[k], np.nan)
        return out


@dataclass
class LevelPlatform:
    """Straight-and-level flight: position p0 + v t, constant heading, settable bank."""

    p0: tuple = (0.0, -30_000.0, 6_000.0)
    heading_deg: float = 270.0
    speed_mps: float = 200.0
    bank_deg: float = 0.0

    def state_at(self, time_s):
        t = np.atleast_1d(np.asarray(time_s, float))
        hd = np.radians(self.heading_deg)
        v = np.array([np.sin(hd), np.cos(hd), 0.0]) * self.speed_mps
        pos = np.asarray(self.p0, float)[None, :] + t[:, None] * v[None, :]
        n = t.size
        return {
            "time_s": t, "x_m": pos[:, 0], "y_m": pos[:, 1], "z_m": pos[:, 2],
            "vx_mps": np.full(n, v[0]), "vy_mps": np.full(n, v[1]), "vz_mps": np.zeros(n),
            "heading_rad": np.full(n, hd % (2 * np.pi)), "pitch_rad": np.zeros(n),
            "bank_rad": np.full(n, np.radians(self.bank_deg)),
        }


class FlatTerrain:
    flat = True

    def height_at(self, x_m, y_m):
        return np.zeros(np.broadcast(np.asarray(x_m), np.asarray(y_m)).shape)

    def line_of_sight(self, from_xyz, to_xyz, step_m=30.0, earth_radius_m=None):
        return np.ones(len(to_xyz), bool)


@dataclass
class WallTerrain:
    """Flat ground (z = 0) and a wall along y = wall_y_m, wall_top_m high, across all x."""

    wall_y_m: float = -1_000.0
    wall_top_m: float = 500.0
    flat: bool = False
    calls: list = field(default_factory=list)

    def height_at(self, x_m, y_m):
        return np.zeros(np.broadcast(np.asarray(x_m), np.asarray(y_m)).shape)

    def line_of_sight(self, from_xyz, to_xyz, step_m=30.0, earth_radius_m=None):
        a, b = np.asarray(from_xyz, float), np.asarray(to_xyz, float)
        self.calls.append(len(b))
        dy = b[:, 1] - a[:, 1]
        with np.errstate(divide="ignore", invalid="ignore"):
            s = (self.wall_y_m - a[:, 1]) / dy
        crosses = (s > 0) & (s < 1)
        z = a[:, 2] + np.where(crosses, s, 0.0) * (b[:, 2] - a[:, 2])
        return ~(crosses & (z < self.wall_top_m))


def grid_fleet(n, *, speed=10.0, seed=0, extent=8_000.0):
    """n vehicles spread over a square of side ``extent`` around the origin, random headings."""
    g = np.random.default_rng(seed)
    p0 = np.column_stack([g.uniform(-extent / 2, extent / 2, n),
                          g.uniform(-extent / 2, extent / 2, n), np.zeros(n)])
    hd = g.uniform(0, 2 * np.pi, n)
    v = np.column_stack([np.sin(hd) * speed, np.cos(hd) * speed, np.zeros(n)])
    return LineFleet(p0, v)


def run(cfg, fleet, platform=None, terrain=None, *, seed=7, duration_s=None, **kw):
    """One sensor run over the fakes (one revisit by default)."""
    from gmtiflow.sensor.model import simulate
    from gmtiflow.sensor import scan

    if duration_s is None:
        duration_s = scan.n_dwells(cfg) * cfg.cpi_s
    return simulate(cfg, fleet, platform or LevelPlatform(), terrain or FlatTerrain(), seed,
                    duration_s, ORIGIN, **kw)


def still(points, **kw):
    """Stationary vehicles at the given (x, y[, z]) points."""
    p = np.atleast_2d(np.asarray(points, float))
    if p.shape[1] == 2:
        p = np.column_stack([p, np.zeros(len(p))])
    return LineFleet(p, np.zeros(3), **kw)
