"""Road targets: vehicles on routes, their speed profiles and their truth (paper §3, DESIGN §3).

``build_fleet(cfg, roadmap, seed, duration_s, dt_s)`` expands the vehicle specs (single
vehicles, convoys, off-road vehicles, a random fleet), routes them (:mod:`routes`), draws each
vehicle's random numbers from its own stream ``rng.stream(seed, "truth", "vehicle", name)``, and
runs the fleet-vectorised speed-profile kernel (:mod:`motion`) for each trip. The
:class:`~gmtiflow.scene.fleet.Fleet` evaluates the truth of any vehicle at any instant exactly
(``state_at``) and builds ``/truth`` tables.  The config schema is in :mod:`.vehicles_config`;
its classes are re-exported here.

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
from dataclasses import dataclass
from typing import Any, Dict, List, Optional, Tuple

import numpy as np

from gmtiflow import frames, rng
from gmtiflow.errors import ConfigError, RoadMapError
from gmtiflow.scene import motion
from gmtiflow.scene import wander as wander_mod
from gmtiflow.scene.fleet import TRUTH_COLUMNS, Fleet
from gmtiflow.scene.roadmap import RoadMap
from gmtiflow.scene.routes import (Route, off_road_route, off_road_routes, shortest_route,
                                   shortest_routes)
from gmtiflow.scene.streams import first_words, streams
from gmtiflow.scene.vehicles_config import (ConvoySpec, RandomFleetSpec, SpeedChangeSpec,
                                            VehicleSpec, VehiclesConfig)

__all__ = ["ConvoySpec", "Fleet", "RandomFleetSpec", "SpeedChangeSpec", "TRUTH_COLUMNS",
           "VehicleSpec", "VehiclesConfig", "build_fleet"]

_HALF_ULP = 2.0 ** -54
_BELOW_ONE = 1.0 - 2.0 ** -53     # the largest float below 1


def _normals_by_inversion(u: np.ndarray) -> np.ndarray:
    """Standard normals from uniforms ``u`` in [0, 1) (``Generator.random``), inverting
    Φ at u + 2^-54, in (0, 1): 0 is never inverted (-inf), and the one draw that rounds to 1
    (u = 1 - 2^-53, a chance of 2^-53) is inverted at 1 - 2^-53 (8.3σ), not at 1 (+inf, which
    made a vehicle's speed noise NaN).  A new array."""
    from scipy.special import ndtri   # imported here: scipy.special costs start-up time
    p = u + _HALF_ULP
    np.minimum(p, _BELOW_ONE, out=p)
    return ndtri(p, out=p)


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
    sigma_pos: Tuple[float, float, float]    # σ along, across, up (m)
    pos_corr_s: float


@dataclass
class _ProfileSpec:
    route: int
    t0: float
    length_m: float
    v0: float
    cruise_mps: float             # the cruise speed (of every segment unless seg_cruise_mps)
    seg_cruise_mps: Optional[np.ndarray]   # per segment, where speed changes vary it
    obey_speed_limits: bool
    stops: np.ndarray
    spec: Any
    name: str


def _check(cfg: VehiclesConfig) -> None:
    problems = cfg.problems()
    if problems:
        raise ConfigError("; ".join(f"{cfg.problem_key(p.key)}: {p.message}"
                                    for p in problems))


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


_NO_STOPS = np.zeros(0)
_NO_STOPS.flags.writeable = False
"""The stops of a profile without stop points (one array, shared: read-only)."""


def _expand(cfg: VehiclesConfig, roadmap: RoadMap, seed: int):
    """Specs -> (list of _ProfileSpec, list of _Vehicle, list of Route)."""
    routes: List[Route] = []
    profiles: List[_ProfileSpec] = []
    vehicles: List[_Vehicle] = []
    n_convoys = 0
    specs = list(cfg.vehicles)
    if cfg.random.count > 0:
        specs += _random_specs(cfg.random, roadmap, seed)
    pre = _batch_routes(specs, roadmap)
    n_listed = len(cfg.vehicles)
    for i, (spec, route) in enumerate(zip(specs, pre)):
        # errors name a listed vehicle's entry (in its file, if any), a random one by name
        who = (f"{cfg.entry_name(i)} (vehicle {spec.name!r})" if i < n_listed
               else f"vehicle {spec.name!r}")
        if route is not None:
            pass
        elif spec.off_road:
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
                if ("unknown node" in str(exc) and roadmap.source != "default scene"
                        and not cfg.source_file):
                    raise RoadMapError(f"{exc}. Note: the vehicles=default preset names nodes "
                                       f"of roadmap=default; vehicles=random works on any "
                                       f"map") from None
                raise
        r = len(routes)
        routes.append(route)
        cruise = float(spec.cruise_speed_mps)
        base = None
        if spec.speed_changes:
            base = np.full(len(route.edge_id), cruise)
            hits = _node_positions(route, roadmap, [sc.at for sc in spec.speed_changes], who)
            changes = sorted((int(h), float(sc.cruise_speed_mps))
                             for hs, sc in zip(hits, spec.speed_changes) for h in hs)
            for node_pos, speed in changes:
                base[node_pos:] = speed
        stops = _NO_STOPS
        if spec.stop_points:
            hits = _node_positions(route, roadmap, spec.stop_points, who)
            stops = np.unique(route.s_m[np.concatenate(hits)])
            stops = stops[stops > 0]
        if spec.start_speed_mps is None:    # the first segment's target (_segment_targets)
            v0 = cruise if base is None else float(base[0])
            lim0 = float(route.speed_limit_mps[0])
            if spec.obey_speed_limits and math.isfinite(lim0):
                v0 = min(v0, lim0)
        else:
            v0 = float(spec.start_speed_mps)
        count = int(spec.convoy.count)
        if count > 1:
            gap = (float(spec.convoy.spacing_m) if spec.convoy.spacing_m is not None
                   else float(spec.convoy.spacing_s) * v0)
            if gap <= 0:
                raise ConfigError(f"{who}: convoy spacing_s with a zero start speed gives no "
                                  f"gap; use spacing_m")
            convoy_id = n_convoys
            n_convoys += 1
            members = [(f"{spec.name}-{i + 1}", i * gap) for i in range(count)]
        else:
            convoy_id = -1
            members = [(spec.name, 0.0)]
        p = len(profiles)
        profiles.append(_ProfileSpec(route=r, t0=float(spec.start_time_s),
                                     length_m=route.length_m + members[-1][1], v0=v0,
                                     cruise_mps=cruise, seg_cruise_mps=base,
                                     obey_speed_limits=bool(spec.obey_speed_limits),
                                     stops=stops, spec=spec,
                                     name=members[0][0]))
        sig = tuple(map(float, spec.position_noise_m))
        for name, off in members:
            vehicles.append(_Vehicle(name=name, type=str(spec.type), convoy_id=convoy_id,
                                     profile=p, route=r, offset_m=off,
                                     off_road=bool(spec.off_road), sigma_pos=sig,
                                     pos_corr_s=float(spec.position_noise_corr_s)))
    names = [v.name for v in vehicles]
    if len(set(names)) != len(names):
        dup = next(n for n in names if names.count(n) > 1)
        where = f"vehicles.file {cfg.source_file}" if cfg.source_file else "vehicles"
        raise ConfigError(f"{where}: vehicle name {dup!r} occurs twice (convoy members are "
                          f"named <name>-1, <name>-2, …)")
    return profiles, vehicles, routes


def _segment_targets(profiles: List[_ProfileSpec], routes: List[Route]) -> np.ndarray:
    """The cruise target (m/s) of every segment of every profile, flat in profile order: its
    cruise speed (after any speed-change points), capped by the road's speed limit where the
    segment has one and the vehicle obeys limits; the same operation on each element as
    profile by profile, on all segments at once."""
    if not profiles:
        return np.zeros(0)
    n_seg = np.asarray([len(routes[p.route].edge_id) for p in profiles], np.int64)
    base = np.repeat(np.asarray([p.cruise_mps for p in profiles], float), n_seg)
    first = np.cumsum(n_seg) - n_seg
    for p, a in zip(profiles, first.tolist()):
        if p.seg_cruise_mps is not None:
            base[a:a + len(p.seg_cruise_mps)] = p.seg_cruise_mps
    limit = np.concatenate([routes[p.route].speed_limit_mps for p in profiles]).astype(float)
    obey = np.repeat(np.asarray([p.obey_speed_limits for p in profiles], bool), n_seg)
    return np.where(obey & np.isfinite(limit), np.minimum(base, limit), base)


def _batch_routes(specs, roadmap: RoadMap) -> List[Any]:
    """The routes of the vehicles without stopovers (road) and of the off-road ones, all at
    once (:func:`shortest_routes`, :func:`off_road_routes`: the same routes); None for the
    others and where a route would be refused (the vehicle's own call then says why, in the
    order of the vehicles)."""
    out: List[Any] = [None] * len(specs)
    road = [i for i, s in enumerate(specs) if not s.off_road and not s.stopovers]
    if len(road) > 1:
        for i, r in zip(road, shortest_routes(roadmap, [specs[i].start for i in road],
                                              [specs[i].end for i in road])):
            out[i] = r
    off, pts = [], []
    for i, s in enumerate(specs):
        if s.off_road:
            try:
                pts.append([frames.point_to_enu(p, roadmap.origin) for p in s.off_road])
                off.append(i)
            except (KeyError, TypeError, ValueError):
                pass
    if len(off) > 1:
        for i, r in zip(off, off_road_routes(pts)):
            out[i] = r
    return out


def _random_specs(spec: RandomFleetSpec, roadmap: RoadMap, seed: int) -> List[VehicleSpec]:
    """The random fleet as plain vehicle specs, each drawn from its own named stream."""
    nodes = roadmap.largest_component()
    if len(nodes) < 2:
        raise RoadMapError(f"{roadmap.source}: the largest connected part of the road graph has "
                           f"fewer than two nodes; no random routes are possible")
    types = sorted(spec.types)
    weights = np.asarray([float(spec.types[t]) for t in types])
    cdf = (np.cumsum(weights) / weights.sum()).tolist()
    xy = roadmap.node_xyz(nodes)[:, :2]
    n_nodes, top = len(nodes), len(types) - 1
    min_route_m = spec.min_route_m
    # every two distinct nodes qualify: no distance to compute
    any_pair = min_route_m <= 0 and bool(np.isfinite(xy).all())
    node_name = [str(x) for x in np.asarray(roadmap.nodes["name"])[nodes].tolist()]
    st_lo, st_hi = float(spec.start_time_min_s), float(spec.start_time_max_s)
    cs_lo, cs_hi = float(spec.cruise_speed_min_mps), float(spec.cruise_speed_max_mps)
    names = [f"{spec.name_prefix}-{i:04d}" for i in range(int(spec.count))]
    # Each vehicle's start and end nodes, then three uniforms (type, start time, cruise speed:
    # random() and two uniform(lo, hi) = lo + (hi - lo) * random()), from its own stream:
    # read for all vehicles at once (_spec_draws); a vehicle whose pair does not qualify
    # draws again from its own stream (_spec_draws_one), as a vehicle-by-vehicle loop would.
    pair, u, plain = _spec_draws(
        first_words(seed, ("truth", "vehicle"), names, ("spec",), 4), n_nodes,
        rng.stream(seed, "truth", "vehicle", names[0], "spec") if names else None)
    ok = plain & (pair[:, 0] != pair[:, 1])
    if not any_pair:
        d = xy[pair[:, 0]] - xy[pair[:, 1]]
        ok &= np.hypot(d[:, 0], d[:, 1]) >= min_route_m
    for i in np.flatnonzero(~ok).tolist():
        pair[i], u[i] = _spec_draws_one(rng.stream(seed, "truth", "vehicle", names[i], "spec"),
                                        n_nodes, xy, any_pair, min_route_m, roadmap.source,
                                        names[i])
    vtype = np.minimum(np.maximum(np.searchsorted(cdf, u[:, 0], side="right"), 0), top)
    start_s = (st_lo + (st_hi - st_lo) * u[:, 1]).tolist()
    cruise_mps = (cs_lo + (cs_hi - cs_lo) * u[:, 2]).tolist()
    return [VehicleSpec(
        name=name, type=types[k], start=node_name[a], end=node_name[b], start_time_s=t0,
        cruise_speed_mps=cruise, speed_noise_mps=spec.speed_noise_mps,
        speed_noise_corr_s=spec.speed_noise_corr_s,
        position_noise_m=list(spec.position_noise_m),
        position_noise_corr_s=spec.position_noise_corr_s,
        max_accel_mps2=spec.max_accel_mps2, max_decel_mps2=spec.max_decel_mps2,
        random_stop_rate_per_s=spec.random_stop_rate_per_s, mean_wait_s=spec.mean_wait_s,
        max_wait_s=spec.max_wait_s)
        for name, k, (a, b), t0, cruise in zip(names, vtype.tolist(), pair.tolist(), start_s,
                                               cruise_mps)]


def _spec_draws(raw: np.ndarray, n_nodes: int, check: Optional[np.random.Generator]):
    """Per stream, from its first four raw 64-bit words ``raw`` (N, 4)
    (:func:`~gmtiflow.scene.streams.first_words`): ``integers(0, n_nodes, size=2)`` (a node
    pair, (N, 2)) then ``random(3)`` ((N, 3)), as those calls draw them (the calls and a
    generator cost ~10 µs a vehicle, 1,000 random vehicles ~8 ms).  With fewer than 2^32
    nodes numpy's ``integers`` takes the two 32-bit halves of one word, low then high, by
    Lemire's method: node = (half * n) >> 32, unless (half * n) mod 2^32 falls below
    (2^32 - n) mod n, which draws again; ``random`` is (word >> 11) * 2^-53.  ``plain``
    (N,): False where a draw again would be needed (a chance of ~n / 2^32): those vehicles
    are left to their own calls (_spec_draws_one), as are all when ``check`` (a fresh copy of
    the first stream) draws differently from this reading (another numpy's integers or
    random), or its first vehicle draws again."""
    n = len(raw)
    pair = np.zeros((n, 2), np.int64)
    u = np.zeros((n, 3))
    if not n or n_nodes >= 1 << 32:
        return pair, u, np.zeros(n, bool)
    halves = np.stack([raw[:, 0] & np.uint64(0xFFFFFFFF), raw[:, 0] >> np.uint64(32)], axis=1)
    m = halves * np.uint64(n_nodes)                      # < 2^64: no wrap
    low = m & np.uint64(0xFFFFFFFF)
    plain = ~(low < np.uint64(((1 << 32) - n_nodes) % n_nodes)).any(axis=1)
    pair[:] = m >> np.uint64(32)
    u[:] = (raw[:, 1:] >> np.uint64(11)).astype(np.float64) * (1.0 / 9007199254740992.0)
    if check is not None and not (
            plain[0] and check.integers(0, n_nodes, size=2).tolist() == pair[0].tolist()
            and check.random(3).tobytes() == u[0].tobytes()):
        plain[:] = False
    return pair, u, plain


def _spec_draws_one(g: np.random.Generator, n_nodes: int, xy: np.ndarray, any_pair: bool,
                    min_route_m: float, source: str, name: str):
    """One random vehicle's node pair and three uniforms from its stream ``g`` (fresh), call by
    call: pairs drawn until one qualifies (distinct nodes at least ``min_route_m`` apart), up
    to 100 draws, then ``random(3)``."""
    for _attempt in range(100):
        a, b = g.integers(0, n_nodes, size=2).tolist()
        if a != b and (any_pair or np.hypot(*(xy[a] - xy[b])) >= min_route_m):
            return (a, b), g.random(3)
    raise RoadMapError(f"{source}: random vehicle {name!r}: no two nodes at least "
                       f"min_route_m = {min_route_m} m apart were found")


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

    seg_start, seg_off = [], [0]
    stop_m, stop_off = [], [0]
    for p in profiles:
        route = routes[p.route]
        seg_start.append(route.s_m[:-1])
        seg_off.append(seg_off[-1] + len(route.edge_id))
        stop_m.append(p.stops)
        stop_off.append(stop_off[-1] + len(p.stops))
    specs = [p.spec for p in profiles]
    arr = lambda f: np.asarray([float(f(s)) for s in specs], dtype=float)  # noqa: E731
    sigma = arr(lambda s: s.speed_noise_mps)
    inp = motion.ProfileInputs(
        length_m=np.asarray([p.length_m for p in profiles], dtype=float),
        v0_mps=np.asarray([p.v0 for p in profiles], dtype=float),
        seg_start_m=np.concatenate(seg_start) if P else np.zeros(0),
        seg_target_mps=_segment_targets(profiles, routes),
        seg_offset=np.asarray(seg_off, dtype=np.int64),
        stop_m=np.concatenate(stop_m) if P else np.zeros(0),
        stop_offset=np.asarray(stop_off, dtype=np.int64),
        max_accel_mps2=arr(lambda s: s.max_accel_mps2),
        max_decel_mps2=arr(lambda s: s.max_decel_mps2),
        speed_noise_mps=sigma,
        noise_rho=np.exp(-dt / np.maximum(arr(lambda s: s.speed_noise_corr_s), 1e-300)),
        p_stop=-np.expm1(-arr(lambda s: s.random_stop_rate_per_s) * dt),
        q_wait=np.minimum(1.0, dt / arr(lambda s: s.mean_wait_s)),
        max_wait_steps=np.asarray([int(math.floor(s.max_wait_s / dt + 1e-9)) for s in specs],
                                  dtype=np.int64),
        # one step past the scene's end, so the state at its last instant is the one a longer
        # scene has there (the step's start state and acceleration)
        horizon_steps=horizon + 1,
        noise=_trip_noise(seed, [leader[p] for p in range(P)], sigma > 0))
    prof = motion.simulate_profiles(inp, dt, progress=progress)
    on, off = _on_off(vehicles, routes, prof)
    wander = _draw_wander(vehicles, seed, t0, on, off, horizon * dt, dt)
    return Fleet(vehicles, routes, prof, wander, t0, horizon * dt, on, off, roadmap)


def _trip_noise(seed: int, names: List[str], noisy: np.ndarray) -> motion.NoiseSource:
    """The speed-profile noise of each profile from its leader's stream ``rng.stream(seed,
    "truth", "vehicle", name)``: per local step k, row k of 6 uniforms (normal by inversion of
    column 0, stop uniform 1, wait uniform 2; 3-5 spare), drawn step-major block by block while
    the trip lasts, so the draws follow the trip and a longer scene extends, never changes,
    them.  ``noisy`` (per profile): whether it has speed noise; a profile without (σ = 0) gets
    normals +0 instead of inverting its column 0 (drawn all the same: σξ is 0 either way)."""
    gens: Dict[int, np.random.Generator] = {}

    def draw(profiles, k0, n):
        buf = np.empty((len(profiles), n, 6))      # each profile's rows in place, as drawn
        pids = profiles.tolist()
        if k0 == 0:
            gens.update(zip(pids, streams(seed, ("truth", "vehicle"), [names[p] for p in pids])))
        for c, p in enumerate(pids):
            gens[p].random(out=buf[c])
        # each used column as its own contiguous array (u + 2^-54, as before); the normals
        # by inversion
        inv = noisy[profiles]
        if inv.all():
            normal = _normals_by_inversion(buf[:, :, 0])
        else:
            normal = np.zeros((len(pids), n))
            rows = np.flatnonzero(inv)
            if rows.size:
                normal[rows] = _normals_by_inversion(buf[rows, :, 0])
        return normal.T, (buf[:, :, 1] + _HALF_ULP).T, (buf[:, :, 2] + _HALF_ULP).T
    return draw


def _on_off(vehicles: List["_Vehicle"], routes: List[Route], prof: "motion.Profiles"):
    """Local times at which each vehicle enters and leaves its route (inf: not in its horizon)."""
    n = len(vehicles)
    if not n:
        return np.zeros(0), np.zeros(0)
    p = np.asarray([v.profile for v in vehicles], np.int64)
    offset = np.asarray([v.offset_m for v in vehicles], float)
    length = np.asarray([routes[v.route].length_m for v in vehicles], float)
    t = prof.times_at(np.concatenate([p, p]), np.concatenate([offset, length + offset]))
    return t[:n], t[n:]


def _draw_wander(vehicles, seed, t0, on, off, horizon_s, dt):
    """Each wandering vehicle's knots from ``rng.stream(…, name, "wander")`` for its own trip
    (its start to its arrival, or to the scene's end), knot-major: a prefix of the same draws
    for a longer trip (:mod:`wander`)."""
    N = len(vehicles)
    w_t0 = np.zeros(N)
    w_h = np.ones(N)
    n_k = np.zeros(N, np.int64)
    sigma = np.asarray([v.sigma_pos for v in vehicles], float).reshape(N, 3)    # σ (m), (N, 3)
    wanders = np.flatnonzero((sigma > 0).any(axis=1) & np.isfinite(on))
    if wanders.size:
        prof = np.asarray([vehicles[vi].profile for vi in wanders], np.int64)
        w_t0[wanders] = t0[prof]
        w_h[wanders] = wander_mod.knot_spacing_s([vehicles[vi].pos_corr_s for vi in wanders],
                                                 dt)
        end = t0[prof] + np.minimum(off[wanders], horizon_s[prof])
        n_k[wanders] = wander_mod.n_knots(w_t0[wanders], end, w_h[wanders])
    knot_off = np.concatenate([[0], np.cumsum(n_k)]).astype(np.int64)
    knots = np.empty((int(knot_off[-1]), 3))
    gens = streams(seed, ("truth", "vehicle"), [vehicles[vi].name for vi in wanders.tolist()],
                   ("wander",))
    rows = knot_off.tolist()
    for vi, g in zip(wanders.tolist(), gens):      # N(0, 1) in place, scaled by σ below
        g.standard_normal(out=knots[rows[vi]:rows[vi + 1]])
    if wanders.size:
        knots *= np.repeat(sigma, n_k, axis=0)
    return knots, knot_off, w_t0, w_h
