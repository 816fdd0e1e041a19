"""Road targets: vehicles on routes, their speed profiles and their truth (paper §3, DESIGN §3).

``build_fleet(cfg, roadmap, seed, duration_s, dt_s)`` expands the vehicle specs (single
vehicles, convoys, off-road vehicles, a random fleet), routes them (:mod:`routes`), draws each
vehicle's random numbers from its own stream ``rng.stream(seed, "truth", "vehicle", name)``, and
runs the fleet-vectorised speed-profile kernel (:mod:`motion`). The :class:`Fleet` evaluates the
truth of any vehicle at any instant exactly (``state_at``) and builds ``/truth`` tables.

Choices (documented in docs/scene.md):

* Random stops are a Poisson rate per second of driving (``random_stop_rate_per_s``); the
  per-step probability is ``1 - exp(-rate * dt)``, so the behaviour does not depend on dt.
* A vehicle appears at ``start_time_s`` at the start node, at ``start_speed_mps`` (default: the
  cruise speed of its first road), and disappears when it reaches the end (no stop there unless
  the end node is a stop point).
* Convoys are rigid: all members share the leader's speed profile (the leader's speed noise and
  stops) at fixed gaps ``spacing_m`` behind it (or ``spacing_s`` times the leader's start speed);
  member i enters the route when the leader is ``i * gap`` down it and stops behind the leader
  at stop points, like a queue. Each member has its own position noise from its own stream.
* Speed noise: σ about the cruise speed, independent per step as in the paper
  (``speed_noise_corr_s = 0``) or Gauss-Markov with that correlation time, which makes the
  speed wander and the accelerations it implies independent of dt.
* Position noise (σ along, across, up) is drawn on the profile's time grid (independent per
  step as in the paper, or Gauss-Markov with ``position_noise_corr_s``) and interpolated
  linearly in time, so ``state_at`` is reproducible at any t. Velocity and acceleration are along
  the road (tangential acceleration only; corners are sharp as in the paper).
* The random fleet draws its start/end nodes, type, cruise speed and start time from
  ``rng.stream(seed, "truth", "vehicle", name, "spec")``, a stream of that vehicle only.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional

import numpy as np

from gmtiflow import frames, rng, schema
from gmtiflow.errors import ConfigError, RoadMapError
from gmtiflow.scene import motion
from gmtiflow.scene import wander as wander_mod
from gmtiflow.scene.roadmap import RoadMap
from gmtiflow.scene.routes import Route, off_road_route, shortest_route
from gmtiflow.tables import Table

_HALF_ULP = 2.0 ** -54


@dataclass
class SpeedChangeSpec:
    """At node ``at`` (name, OSM id or [x, y]) the cruise speed becomes ``cruise_speed_mps``."""

    at: Any = None
    cruise_speed_mps: float = 13.9

    def problems(self) -> List[schema.Problem]:
        out = schema.positive(self, "cruise_speed_mps")
        if self.at is None:
            out.append(schema.Problem("at", "a node reference is required"))
        return out


@dataclass
class ConvoySpec:
    """A convoy of ``count`` members (count 1 = no convoy); gap ``spacing_m`` or ``spacing_s``."""

    count: int = 1
    spacing_m: Optional[float] = None
    spacing_s: Optional[float] = None

    def problems(self) -> List[schema.Problem]:
        out = schema.in_range(self, "count", 1, 1000)
        out += schema.positive(self, "spacing_m", "spacing_s")
        if self.count > 1 and (self.spacing_m is None) == (self.spacing_s is None):
            out.append(schema.Problem("spacing_m", "give exactly one of spacing_m or spacing_s"))
        return out


@dataclass
class VehicleSpec:
    """One vehicle (or convoy) with its route and driving behaviour.

    Node references (start, end, stopovers, stop_points, speed_changes[].at) may be a node name,
    an OSM id, or [x, y] metres (nearest node). ``off_road``: waypoints [x, y(, z)] in metres; when
    given, the vehicle drives them without the road graph and start/end are ignored.

    Fields (units in the suffix): ``type`` key into the sensor's RCS models; ``start_speed_mps``
    None = cruise speed of the first road; ``obey_speed_limits`` caps cruise by road limits;
    ``speed_noise_mps`` σ of the speed, ``speed_noise_corr_s`` its correlation time (0 =
    independent per step); ``position_noise_m`` σ [along, across, up], ``position_noise_corr_s``
    likewise; ``stop_points`` nodes where it stops exactly; ``random_stop_rate_per_s`` Poisson
    rate of random stops while driving; ``mean_wait_s``/``max_wait_s`` the geometric wait;
    ``speed_changes`` permanent new cruise speeds from a node on; ``convoy`` count and gap.
    """

    name: str = "???"
    type: str = "car"
    start: Any = None
    end: Any = None
    stopovers: List[Any] = field(default_factory=list)
    start_time_s: float = 0.0
    cruise_speed_mps: float = 13.9
    start_speed_mps: Optional[float] = None
    obey_speed_limits: bool = True
    speed_noise_mps: float = 0.0
    speed_noise_corr_s: float = 0.0
    position_noise_m: List[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    position_noise_corr_s: float = 0.0
    max_accel_mps2: float = 2.0
    max_decel_mps2: float = 4.0
    stop_points: List[Any] = field(default_factory=list)
    random_stop_rate_per_s: float = 0.0
    mean_wait_s: float = 10.0
    max_wait_s: float = 60.0
    speed_changes: List[SpeedChangeSpec] = field(default_factory=list)
    convoy: ConvoySpec = field(default_factory=ConvoySpec)
    off_road: List[Any] = field(default_factory=list)   # [[x, y(, z)], ...] metres

    def problems(self) -> List[schema.Problem]:
        out = []
        if not self.name or self.name == "???":
            out.append(schema.Problem("name", "every vehicle needs a name"))
        out += schema.non_negative(self, "start_time_s", "speed_noise_mps",
                                   "speed_noise_corr_s", "random_stop_rate_per_s",
                                   "start_speed_mps", "position_noise_corr_s")
        out += schema.positive(self, "cruise_speed_mps", "max_accel_mps2", "max_decel_mps2",
                               "mean_wait_s", "max_wait_s")
        out += schema.ordered(self, "mean_wait_s", "max_wait_s", strict=False)
        if len(self.position_noise_m) != 3 or not all(
                isinstance(v, (int, float)) and math.isfinite(v) and v >= 0
                for v in self.position_noise_m):
            out.append(schema.Problem("position_noise_m", f"must be [σ_along, σ_across, σ_up] "
                                                          f"metres >= 0, got "
                                                          f"{list(self.position_noise_m)!r}"))
        if self.off_road:
            if len(self.off_road) < 2:
                out.append(schema.Problem("off_road", "needs at least two waypoints"))
            for i, point in enumerate(self.off_road):
                out += schema.point_problems(f"off_road[{i}]", point, geodetic=True)
            if self.stop_points or self.speed_changes:
                out.append(schema.Problem("off_road", "an off-road vehicle has no road nodes for "
                                                      "stop_points or speed_changes"))
        else:
            for end in ("start", "end"):
                if getattr(self, end) is None:
                    out.append(schema.Problem(end, "a node reference is required (or give "
                                                   "off_road waypoints)"))
        out += schema.prefixed("convoy", self.convoy.problems())
        for i, sc in enumerate(self.speed_changes):
            out += schema.prefixed(f"speed_changes[{i}]", sc.problems())
        return out


@dataclass
class RandomFleetSpec:
    """``count`` vehicles named ``<name_prefix>-0000`` … between random nodes of the largest
    strongly connected part of the road graph; ``types``: vehicle type -> weight; cruise speed
    and start time uniform in their [min, max]; start and end at least ``min_route_m`` apart
    in a straight line. The other fields are as in :class:`VehicleSpec`."""

    count: int = 0
    name_prefix: str = "random"
    types: Dict[str, float] = field(default_factory=lambda: {"car": 0.8, "truck": 0.2})
    cruise_speed_min_mps: float = 10.0
    cruise_speed_max_mps: float = 25.0
    start_time_min_s: float = 0.0
    start_time_max_s: float = 0.0
    speed_noise_mps: float = 0.3
    speed_noise_corr_s: float = 5.0
    position_noise_m: List[float] = field(default_factory=lambda: [0.5, 0.5, 0.05])
    position_noise_corr_s: float = 5.0
    max_accel_mps2: float = 2.0
    max_decel_mps2: float = 4.0
    random_stop_rate_per_s: float = 0.0
    mean_wait_s: float = 10.0
    max_wait_s: float = 60.0
    min_route_m: float = 0.0

    def problems(self) -> List[schema.Problem]:
        out = schema.in_range(self, "count", 0, 1_000_000)
        out += schema.positive(self, "cruise_speed_min_mps", "cruise_speed_max_mps",
                               "max_accel_mps2", "max_decel_mps2", "mean_wait_s", "max_wait_s")
        out += schema.non_negative(self, "start_time_min_s", "start_time_max_s",
                                   "speed_noise_mps", "speed_noise_corr_s",
                                   "position_noise_corr_s", "random_stop_rate_per_s",
                                   "min_route_m")
        out += schema.ordered(self, "cruise_speed_min_mps", "cruise_speed_max_mps", strict=False)
        out += schema.ordered(self, "start_time_min_s", "start_time_max_s", strict=False)
        out += schema.ordered(self, "mean_wait_s", "max_wait_s", strict=False)
        bad_weight = any(not (schema.is_number(w) and w >= 0) for w in self.types.values())
        if bad_weight or (self.count and (not self.types or sum(self.types.values()) <= 0)):
            out.append(schema.Problem("types", f"needs finite weights >= 0 with a positive sum, got "
                                               f"{dict(self.types)!r}"))
        if len(self.position_noise_m) != 3 or any(not (schema.is_number(v) and v >= 0)
                                                  for v in self.position_noise_m):
            out.append(schema.Problem("position_noise_m", f"must be 3 finite values >= 0 "
                                                          f"[σ_along, σ_across, σ_up] in metres, "
                                                          f"got {list(self.position_noise_m)!r}"))
        return out


@dataclass
class VehiclesConfig:
    """Schema of the ``vehicles`` config group: listed vehicles plus a random fleet."""

    vehicles: List[VehicleSpec] = field(default_factory=list)
    random: RandomFleetSpec = field(default_factory=RandomFleetSpec)

    def problems(self) -> List[schema.Problem]:
        out = []
        seen = set()
        for i, spec in enumerate(self.vehicles):
            out += schema.prefixed(f"vehicles[{i}]", spec.problems())
            if spec.name in seen:
                out.append(schema.Problem(f"vehicles[{i}].name",
                                          f"vehicle name {spec.name!r} is used twice"))
            seen.add(spec.name)
        out += schema.prefixed("random", self.random.problems())
        return out


# --------------------------------------------------------------------------------------------
@dataclass
class _Vehicle:
    name: str
    type: str
    convoy_id: int
    profile: int
    route: int
    offset_m: float
    off_road: bool
    sigma_pos: np.ndarray
    pos_corr_s: float


@dataclass
class _ProfileSpec:
    route: int
    t0: float
    length_m: float
    v0: float
    seg_target: np.ndarray
    stops: np.ndarray
    spec: Any
    name: str


def _check(cfg: VehiclesConfig) -> None:
    problems = cfg.problems()
    if problems:
        raise ConfigError("; ".join(f"vehicles.{p.key}: {p.message}" for p in problems))


def _node_positions(route: Route, roadmap: RoadMap, refs, who: str) -> List[np.ndarray]:
    out = []
    for ref in refs:
        try:
            nid = roadmap.node_index(ref)
        except RoadMapError as exc:
            raise RoadMapError(f"{who}: {exc}") from None
        hits = np.flatnonzero(route.node_ids == nid)
        if hits.size == 0:
            raise RoadMapError(f"{who}: node {ref!r} is not on the vehicle's route")
        out.append(hits)
    return out


def _expand(cfg: VehiclesConfig, roadmap: RoadMap, seed: int):
    """Specs -> (list of _ProfileSpec, list of _Vehicle, list of Route)."""
    routes: List[Route] = []
    profiles: List[_ProfileSpec] = []
    vehicles: List[_Vehicle] = []
    n_convoys = 0
    specs = list(cfg.vehicles)
    if cfg.random.count > 0:
        specs += _random_specs(cfg.random, roadmap, seed)
    for spec in specs:
        who = f"vehicle {spec.name!r}"
        if spec.off_road:
            try:    # waypoints in metres or {lat_deg, lon_deg, height_m} (frames.point_to_enu)
                pts = [frames.point_to_enu(p, roadmap.origin) for p in spec.off_road]
            except (KeyError, TypeError, ValueError):
                raise RoadMapError(f"{who}: off_road waypoints must be [x, y(, z)] metres or "
                                   f"{{lat_deg, lon_deg, height_m}}") from None
            route = off_road_route(pts, who=who)
        else:
            try:
                route = shortest_route(roadmap, spec.start, spec.end, spec.stopovers, who=who)
            except RoadMapError as exc:
                if "unknown node" in str(exc) and roadmap.source != "default scene":
                    raise RoadMapError(f"{exc}. Note: the vehicles=default preset names nodes "
                                       f"of roadmap=default; vehicles=random works on any "
                                       f"map") from None
                raise
        r = len(routes)
        routes.append(route)
        nseg = len(route.edge_id)
        base = np.full(nseg, float(spec.cruise_speed_mps))
        if spec.speed_changes:
            hits = _node_positions(route, roadmap, [sc.at for sc in spec.speed_changes], who)
            changes = sorted((int(h), float(sc.cruise_speed_mps))
                             for hs, sc in zip(hits, spec.speed_changes) for h in hs)
            for node_pos, speed in changes:
                base[node_pos:] = speed
        target = base
        if spec.obey_speed_limits:
            lim = route.speed_limit_mps
            target = np.where(np.isfinite(lim), np.minimum(base, lim), base)
        stops = np.zeros(0)
        if spec.stop_points:
            hits = _node_positions(route, roadmap, spec.stop_points, who)
            stops = np.unique(route.s_m[np.concatenate(hits)])
            stops = stops[stops > 0]
        v0 = float(target[0] if spec.start_speed_mps is None else spec.start_speed_mps)
        count = int(spec.convoy.count)
        if count > 1:
            gap = (float(spec.convoy.spacing_m) if spec.convoy.spacing_m is not None
                   else float(spec.convoy.spacing_s) * v0)
            if gap <= 0:
                raise ConfigError(f"vehicles: {who}: convoy spacing_s with a zero start speed "
                                  f"gives no gap; use spacing_m")
            convoy_id = n_convoys
            n_convoys += 1
            members = [(f"{spec.name}-{i + 1}", i * gap) for i in range(count)]
        else:
            convoy_id = -1
            members = [(spec.name, 0.0)]
        p = len(profiles)
        profiles.append(_ProfileSpec(route=r, t0=float(spec.start_time_s),
                                     length_m=route.length_m + members[-1][1], v0=v0,
                                     seg_target=target, stops=stops, spec=spec,
                                     name=members[0][0]))
        sig = np.asarray([float(x) for x in spec.position_noise_m], dtype=float)
        for name, off in members:
            vehicles.append(_Vehicle(name=name, type=str(spec.type), convoy_id=convoy_id,
                                     profile=p, route=r, offset_m=off,
                                     off_road=bool(spec.off_road), sigma_pos=sig,
                                     pos_corr_s=float(spec.position_noise_corr_s)))
    names = [v.name for v in vehicles]
    if len(set(names)) != len(names):
        dup = next(n for n in names if names.count(n) > 1)
        raise ConfigError(f"vehicles: vehicle name {dup!r} occurs twice (convoy members are "
                          f"named <name>-1, <name>-2, …)")
    return profiles, vehicles, routes


def _random_specs(spec: RandomFleetSpec, roadmap: RoadMap, seed: int) -> List[VehicleSpec]:
    """The random fleet as plain vehicle specs, each drawn from its own named stream."""
    nodes = roadmap.largest_component()
    if len(nodes) < 2:
        raise RoadMapError(f"{roadmap.source}: the largest connected part of the road graph has "
                           f"fewer than two nodes; no random routes are possible")
    types = sorted(spec.types)
    weights = np.asarray([float(spec.types[t]) for t in types])
    cdf = np.cumsum(weights) / weights.sum()
    xy = roadmap.node_xyz(nodes)[:, :2]
    out = []
    for i in range(int(spec.count)):
        name = f"{spec.name_prefix}-{i:04d}"
        g = rng.stream(seed, "truth", "vehicle", name, "spec")
        for _attempt in range(100):
            a, b = g.integers(0, len(nodes), size=2)
            if a != b and np.hypot(*(xy[a] - xy[b])) >= spec.min_route_m:
                break
        else:
            raise RoadMapError(f"{roadmap.source}: random vehicle {name!r}: no two nodes at least "
                               f"min_route_m = {spec.min_route_m} m apart were found")
        vtype = types[int(np.searchsorted(cdf, g.random(), side="right").clip(0, len(types) - 1))]
        out.append(VehicleSpec(
            name=name, type=vtype, start=str(roadmap.nodes["name"][nodes[a]]),
            end=str(roadmap.nodes["name"][nodes[b]]),
            start_time_s=float(g.uniform(spec.start_time_min_s, spec.start_time_max_s)),
            cruise_speed_mps=float(g.uniform(spec.cruise_speed_min_mps, spec.cruise_speed_max_mps)),
            speed_noise_mps=spec.speed_noise_mps, speed_noise_corr_s=spec.speed_noise_corr_s,
            position_noise_m=list(spec.position_noise_m),
            position_noise_corr_s=spec.position_noise_corr_s,
            max_accel_mps2=spec.max_accel_mps2, max_decel_mps2=spec.max_decel_mps2,
            random_stop_rate_per_s=spec.random_stop_rate_per_s, mean_wait_s=spec.mean_wait_s,
            max_wait_s=spec.max_wait_s))
    return out


def build_fleet(cfg: VehiclesConfig, roadmap: RoadMap, seed: int, duration_s: float,
                dt_s: float, progress: bool = False) -> "Fleet":
    """Route every vehicle, draw its randomness from its own stream and run the profiles
    (``progress``: a tqdm bar over the time steps, on a terminal only)."""
    _check(cfg)
    if not (dt_s > 0 and math.isfinite(dt_s)):
        raise ConfigError(f"vehicles: time step dt_s must be > 0, got {dt_s!r}")
    if not (duration_s >= 0 and math.isfinite(duration_s)):
        raise ConfigError(f"vehicles: duration_s must be >= 0, got {duration_s!r}")
    profiles, vehicles, routes = _expand(cfg, roadmap, seed)
    P = len(profiles)
    dt = float(dt_s)
    t0 = np.asarray([p.t0 for p in profiles], dtype=float)
    # Each profile's own horizon: the steps from its start to the scene's end (at least one).
    horizon = np.maximum(np.ceil((float(duration_s) - t0) / dt - 1e-9), 1).astype(np.int64)
    leader = {v.profile: v.name for v in vehicles if v.offset_m == 0.0}

    seg_start, seg_target, seg_off = [], [], [0]
    stop_m, stop_off = [], [0]
    for p in profiles:
        route = routes[p.route]
        seg_start.append(route.s_m[:-1])
        seg_target.append(p.seg_target)
        seg_off.append(seg_off[-1] + len(p.seg_target))
        stop_m.append(p.stops)
        stop_off.append(stop_off[-1] + len(p.stops))
    specs = [p.spec for p in profiles]
    arr = lambda f: np.asarray([float(f(s)) for s in specs], dtype=float)  # noqa: E731
    inp = motion.ProfileInputs(
        length_m=np.asarray([p.length_m for p in profiles], dtype=float),
        v0_mps=np.asarray([p.v0 for p in profiles], dtype=float),
        seg_start_m=np.concatenate(seg_start) if P else np.zeros(0),
        seg_target_mps=np.concatenate(seg_target) if P else np.zeros(0),
        seg_offset=np.asarray(seg_off, dtype=np.int64),
        stop_m=np.concatenate(stop_m) if P else np.zeros(0),
        stop_offset=np.asarray(stop_off, dtype=np.int64),
        max_accel_mps2=arr(lambda s: s.max_accel_mps2),
        max_decel_mps2=arr(lambda s: s.max_decel_mps2),
        speed_noise_mps=arr(lambda s: s.speed_noise_mps),
        noise_rho=np.exp(-dt / np.maximum(arr(lambda s: s.speed_noise_corr_s), 1e-300)),
        p_stop=-np.expm1(-arr(lambda s: s.random_stop_rate_per_s) * dt),
        q_wait=np.minimum(1.0, dt / arr(lambda s: s.mean_wait_s)),
        max_wait_steps=np.asarray([int(math.floor(s.max_wait_s / dt + 1e-9)) for s in specs],
                                  dtype=np.int64),
        # one step past the scene's end, so the state at its last instant is the one a longer
        # scene has there (the step's start state and acceleration)
        horizon_steps=horizon + 1, noise=_trip_noise(seed, [leader[p] for p in range(P)]))
    prof = motion.simulate_profiles(inp, dt, progress=progress)
    on, off = _on_off(vehicles, routes, prof)
    wander = _draw_wander(vehicles, seed, t0, on, off, horizon * dt, dt)
    return Fleet(vehicles, routes, prof, wander, t0, horizon * dt, on, off, roadmap)


def _trip_noise(seed: int, names: List[str]) -> motion.NoiseSource:
    """The speed-profile noise of each profile from its leader's stream ``rng.stream(seed,
    "truth", "vehicle", name)``: per local step k, row k of 6 uniforms (normal by inversion of
    column 0, stop uniform 1, wait uniform 2; 3-5 spare), drawn step-major block by block while
    the trip lasts, so the draws follow the trip and a longer scene extends, never changes,
    them."""
    from scipy.special import ndtri   # imported here: scipy.special costs start-up time
    gens: Dict[int, np.random.Generator] = {}

    def draw(profiles, k0, n):
        u = np.empty((n, len(profiles), 3))
        for c, p in enumerate(profiles.tolist()):
            if k0 == 0:
                gens[p] = rng.stream(seed, "truth", "vehicle", names[p])
            u[:, c, :] = gens[p].random((n, 6))[:, :3]
        u += _HALF_ULP
        return ndtri(u[:, :, 0]), u[:, :, 1], u[:, :, 2]
    return draw


def _on_off(vehicles: List["_Vehicle"], routes: List[Route], prof: "motion.Profiles"):
    """Local times at which each vehicle enters and leaves its route (inf: not in its horizon)."""
    n = len(vehicles)
    on = np.zeros(n)
    off = np.zeros(n)
    for i, v in enumerate(vehicles):
        on[i] = prof.time_at(v.profile, v.offset_m)
        off[i] = prof.time_at(v.profile, routes[v.route].length_m + v.offset_m)
    return on, off


def _draw_wander(vehicles, seed, t0, on, off, horizon_s, dt):
    """Each wandering vehicle's knots from ``rng.stream(…, name, "wander")`` for its own trip
    (its start to its arrival, or to the scene's end), knot-major: a prefix of the same draws
    for a longer trip (:mod:`wander`)."""
    N = len(vehicles)
    knots, knot_off = [], [0]
    w_t0 = np.zeros(N)
    w_h = np.ones(N)
    for vi, veh in enumerate(vehicles):
        n_k = 0
        if np.any(veh.sigma_pos > 0) and math.isfinite(on[vi]):
            p = veh.profile
            w_t0[vi] = t0[p]
            w_h[vi] = wander_mod.knot_spacing_s(veh.pos_corr_s, dt)
            end = t0[p] + min(off[vi], horizon_s[p])
            n_k = wander_mod.n_knots(w_t0[vi], end, w_h[vi])
            gen = rng.stream(seed, "truth", "vehicle", veh.name, "wander")
            knots.append(wander_mod.draw_knots(gen, veh.sigma_pos, n_k))
        knot_off.append(knot_off[-1] + n_k)
    return (np.concatenate(knots) if knots else np.zeros((0, 3)),
            np.asarray(knot_off, np.int64), w_t0, w_h)


# --------------------------------------------------------------------------------------------
class Fleet:
    """All vehicles of a scene; truth at any instant (``state_at``) and ``/truth`` tables."""

    def __init__(self, vehicles, routes, prof, wander, t0, horizon_s, on, off, roadmap):
        self._veh = vehicles
        self._routes = routes
        self.routes = [routes[v.route] for v in vehicles]
        self.profiles = prof
        self._w_knots, self._w_off, self._w_t0, self._w_h = wander
        self.roadmap = roadmap
        n = len(vehicles)
        self._profile = np.asarray([v.profile for v in vehicles], dtype=np.int64)
        self._route = np.asarray([v.route for v in vehicles], dtype=np.int64)
        self._offset = np.asarray([v.offset_m for v in vehicles], dtype=float)
        self._t0 = t0[self._profile] if n else np.zeros(0)
        self._horizon = horizon_s[self._profile] if n else np.zeros(0)
        self._on, self._off = on, off
        #: Time each vehicle appears and reaches its end (inf: not within the simulated time).
        self.start_time_s = self._t0 + on
        self.end_time_s = self._t0 + off
        self.vehicles: Table = {
            "vehicle_id": np.arange(n, dtype=np.int64),
            "name": np.asarray([v.name for v in vehicles], dtype=str),
            "convoy_id": np.asarray([v.convoy_id for v in vehicles], dtype=np.int64),
            "vehicle_type": np.asarray([v.type for v in vehicles], dtype=str),
            "start_time_s": self.start_time_s.copy(),
            "route_length_m": np.asarray([routes[v.route].length_m for v in vehicles], float),
            "off_road": np.asarray([v.off_road for v in vehicles], dtype=bool),
        }
        # Flat route arrays for vectorised look-ups: key = s + route * span is sorted.
        self._span = float(2.0 ** np.ceil(np.log2(max([r.length_m for r in routes] + [1.0])
                                                  * 2.0 + 2.0)))
        self._vx_off = np.concatenate([[0], np.cumsum([len(r.s_m) for r in routes],
                                                      dtype=np.int64)]).astype(np.int64)
        self._vx_xyz = np.concatenate([r.xyz_m for r in routes]) if routes else np.zeros((0, 3))
        self._vx_s = np.concatenate([r.s_m for r in routes]) if routes else np.zeros(0)
        pad = lambda a, fill: np.concatenate([a, [fill]])  # noqa: E731
        self._seg_edge = (np.concatenate([pad(r.edge_id, -1) for r in routes])
                          if routes else np.zeros(0, np.int64))
        self._seg_inv = (np.concatenate([pad(r.invisible, False) for r in routes])
                         if routes else np.zeros(0, bool))
        route_of_vx = np.repeat(np.arange(len(routes)), np.diff(self._vx_off))
        self._vx_key = self._vx_s + route_of_vx * self._span
        # Road-frame heading per segment (indexed by its first vertex) and the corner blend
        # (half-width, turn) per vertex, for the wander's smoothly turning frame.
        psi, blend, turn = [], [], []
        for r in routes:
            h = wander_mod.segment_headings(r.xyz_m)
            b, t = wander_mod.corner_blends(r.s_m, h)
            psi.append(pad(h, h[-1] if len(h) else 0.0))
            blend.append(b)
            turn.append(t)
        self._seg_psi = np.concatenate(psi) if routes else np.zeros(0)
        self._vx_blend = np.concatenate(blend) if routes else np.zeros(0)
        self._vx_turn = np.concatenate(turn) if routes else np.zeros(0)

    @property
    def n_vehicles(self) -> int:
        return len(self._veh)

    def state_at(self, time_s, vehicle_id) -> Table:
        """Truth of ``vehicle_id[i]`` at ``time_s[i]`` (broadcast): /truth columns + ``active``.

        ``active`` is False before the vehicle appears, from its arrival on, and after the
        simulated horizon (the profile grid covers at least ``duration_s``); inactive rows hold
        NaN, -1 ids, mode 255 and invisible False.
        """
        t, vid = np.broadcast_arrays(np.asarray(time_s, dtype=float),
                                     np.asarray(vehicle_id, dtype=np.int64))
        shape = t.shape
        t = t.ravel()
        vid = vid.ravel()
        n = t.size
        valid = (vid >= 0) & (vid < self.n_vehicles)
        vs = np.where(valid, vid, 0)
        out = _empty_truth(n)
        out["time_s"] = t.copy()
        out["vehicle_id"] = vid.copy()
        if self.n_vehicles == 0:
            out["active"] = np.zeros(n, bool)
            return {k: c.reshape(shape) for k, c in out.items()}
        tau = t - self._t0[vs]
        active = (valid & (tau >= self._on[vs]) & (tau < self._off[vs])
                  & (tau <= self._horizon[vs])
                  & np.isfinite(t))
        idx = np.flatnonzero(active)
        out["active"] = active
        out["convoy_id"] = np.where(valid, self.vehicles["convoy_id"][vs], -1)
        if idx.size:
            v_ids = vs[idx]
            p = self._profile[v_ids]
            s_p, speed, acc, mode = self.profiles.evaluate(tau[idx], p)
            r = self._route[v_ids]
            length = self._vx_s[self._vx_off[r + 1] - 1]
            s = np.clip(s_p - self._offset[v_ids], 0.0, length)
            # Segment under s; one correction step on each side absorbs rounding of the key.
            j = np.searchsorted(self._vx_key, s + r * self._span, side="right") - 1
            lo = self._vx_off[r]
            hi = self._vx_off[r + 1] - 2
            j = np.clip(j, lo, hi)
            j = np.where((s < self._vx_s[j]) & (j > lo), j - 1, j)
            j = np.where((s >= self._vx_s[j + 1]) & (j < hi), j + 1, j)
            p0 = self._vx_xyz[j]
            d = self._vx_xyz[j + 1] - p0
            seg_len = self._vx_s[j + 1] - self._vx_s[j]
            safe = np.where(seg_len > 0, seg_len, 1.0)
            f = np.where(seg_len > 0, (s - self._vx_s[j]) / safe, 0.0)
            unit = d / safe[:, None]
            pos = p0 + f[:, None] * d
            vel = speed[:, None] * unit
            accel = acc[:, None] * unit
            # Wander: a smooth process in continuous time, in a frame that turns smoothly
            # through corners; its rates are added, so velocity = d/dt position exactly.
            moving = np.flatnonzero(self._w_off[v_ids + 1] > self._w_off[v_ids])
            if moving.size:
                m_ids = v_ids[moving]
                n, nd, ndd = wander_mod.evaluate(t[idx][moving], m_ids, self._w_knots,
                                                 self._w_off, self._w_t0, self._w_h)
                jm = j[moving]
                psi, dpsi, d2psi = wander_mod.corner_heading(
                    s[moving], self._vx_s[jm], self._vx_s[jm + 1], self._seg_psi[jm],
                    self._vx_blend[jm], self._vx_turn[jm], self._vx_blend[jm + 1],
                    self._vx_turn[jm + 1])
                off, v_off, a_off = wander_mod.world_offset(n, nd, ndd, psi, dpsi, d2psi,
                                                            speed[moving], acc[moving])
                pos[moving] += off
                vel[moving] += v_off
                accel[moving] += a_off
            out["x_m"][idx], out["y_m"][idx], out["z_m"][idx] = pos.T
            out["vx_mps"][idx], out["vy_mps"][idx], out["vz_mps"][idx] = vel.T
            out["ax_mps2"][idx], out["ay_mps2"][idx], out["az_mps2"][idx] = accel.T
            out["speed_mps"][idx] = speed
            out["heading_rad"][idx] = frames.heading_rad(unit[:, 0], unit[:, 1])
            out["route_s_m"][idx] = s
            out["edge_id"][idx] = self._seg_edge[j]
            out["mode"][idx] = mode
            out["invisible"][idx] = self._seg_inv[j]
        return {k: c.reshape(shape) for k, c in out.items()}

    def truth_table(self, times_s, chunk_rows: int = 500_000) -> Table:
        """``/truth`` rows of the active vehicles at ``times_s``, sorted by time then vehicle.

        Only the (time, vehicle) pairs within each vehicle's trip (one sample of margin on each
        side, then the exact ``active`` test) are evaluated, so the cost is the rows written,
        not vehicles x times."""
        times = np.sort(np.asarray(times_s, dtype=float).ravel(), kind="stable")
        n = self.n_vehicles
        if n and len(times):
            end = np.minimum(self.end_time_s, self._t0 + self._horizon)
            i0 = np.maximum(np.searchsorted(times, self.start_time_s, side="left") - 1, 0)
            i1 = np.minimum(np.searchsorted(times, end, side="right") + 1, len(times))
            count = np.maximum(i1 - i0, 0)
        else:
            count = np.zeros(n, np.int64)
        vid = np.repeat(np.arange(n, dtype=np.int64), count)
        first = np.cumsum(count) - count
        ti = np.arange(len(vid), dtype=np.int64) - np.repeat(first - i0[:n], count) \
            if len(vid) else np.zeros(0, np.int64)
        order = np.argsort(ti * max(n, 1) + vid, kind="stable")
        vid, ti = vid[order], ti[order]
        parts = []
        for a in range(0, len(vid), chunk_rows):
            st = self.state_at(times[ti[a:a + chunk_rows]], vid[a:a + chunk_rows])
            mask = st.pop("active")
            parts.append({k: c[mask] for k, c in st.items()})
        if not parts:
            st = self.state_at(np.zeros(0), np.zeros(0, np.int64))
            st.pop("active")
            return st
        return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}


TRUTH_COLUMNS = ("time_s", "vehicle_id", "convoy_id", "x_m", "y_m", "z_m", "vx_mps", "vy_mps",
                 "vz_mps", "ax_mps2", "ay_mps2", "az_mps2", "speed_mps", "heading_rad",
                 "route_s_m", "edge_id", "mode", "invisible")


def _empty_truth(n: int) -> Table:
    out: Table = {}
    for c in TRUTH_COLUMNS:
        if c in ("vehicle_id", "convoy_id", "edge_id"):
            out[c] = np.full(n, -1, dtype=np.int64)
        elif c == "mode":
            out[c] = np.full(n, 255, dtype=np.uint8)
        elif c == "invisible":
            out[c] = np.zeros(n, dtype=bool)
        else:
            out[c] = np.full(n, np.nan)
    return out
