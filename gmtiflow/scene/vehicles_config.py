"""Schema of the ``vehicles`` config group: listed vehicles, convoys and a random fleet.

The meaning of each field and the driving behaviour they configure: docs/scene.md and
:mod:`gmtiflow.scene.vehicles` (which builds the fleet from these specs).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, ClassVar, Dict, List, Optional, Tuple

from gmtiflow import schema


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

    problems_include = ("convoy", "speed_changes")
    """Fields whose problems :meth:`problems` reports (``config.problems_of``)."""

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
            out += schema.points_problems("off_road", self.off_road, geodetic=True)
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

    def share_starting_after(self, duration_s: float) -> float:
        """The share of the fleet whose start time, uniform in [start_time_min_s,
        start_time_max_s], is after ``duration_s`` (0 without vehicles): valid, but those
        vehicles never appear in a scene that short."""
        lo, hi = float(self.start_time_min_s), float(self.start_time_max_s)
        if self.count <= 0 or hi <= duration_s:
            return 0.0
        if lo >= duration_s:        # lo == duration_s: all but a start at the last instant
            return 1.0
        return (hi - duration_s) / (hi - lo)


@dataclass
class VehiclesConfig:
    """Schema of the ``vehicles`` config group: listed vehicles plus a random fleet.

    This is the group once the config is converted; as composed, the group also takes ``file``
    (:class:`VehiclesGroupConfig`: vehicles read from a YAML file past Hydra)."""

    vehicles: List[VehicleSpec] = field(default_factory=list)
    random: RandomFleetSpec = field(default_factory=RandomFleetSpec)

    problems_include = ("vehicles", "random")
    """Fields whose problems :meth:`problems` reports (``config.problems_of``)."""

    source_file: ClassVar[Optional[str]] = None
    """The vehicles file the listed vehicles were read from (absolute), set on the instance
    :func:`gmtiflow.scene.vehicles_file.expand` returns; None otherwise.  Not a config key (the
    config holds the vehicles, not the path: /config and the stage cache keys follow the
    vehicles), but errors found when the fleet is built name the file (:meth:`entry_name`)."""

    def entry_name(self, index: int) -> str:
        """How an error names listed vehicle ``index``: by its place in :attr:`source_file`
        (``vehicles.file /x/big.yaml: vehicles[12]``), else by its key (``vehicles.vehicles[12]``),
        as the config's own checks name it."""
        if self.source_file:
            return f"vehicles.file {self.source_file}: vehicles[{index}]"
        return f"vehicles.vehicles[{index}]"

    def problem_key(self, key: str) -> str:
        """A key of :meth:`problems` (``vehicles[3].name``, ``random.count``) as the user wrote
        it: a listed vehicle's in :attr:`source_file`, if any."""
        if self.source_file and key.startswith("vehicles["):
            return f"vehicles.file {self.source_file}: {key}"
        return f"vehicles.{key}"

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

    def starting_after(self, duration_s: float) -> List[Tuple[int, str, float]]:
        """(index, name, start_time_s) of the listed vehicles that start after ``duration_s``:
        valid (a vehicles list reused for a shorter scene), but they never appear in it.  A
        start at ``duration_s`` itself appears at the scene's last instant."""
        return [(i, spec.name, float(spec.start_time_s)) for i, spec in enumerate(self.vehicles)
                if spec.start_time_s > duration_s]


@dataclass
class VehiclesGroupConfig(VehiclesConfig):
    """The ``vehicles`` group as Hydra composes it: :class:`VehiclesConfig` plus ``file``.

    ``file``: None, or the path of a YAML file holding ``vehicles: [...]`` in the schema of
    ``vehicles`` above (a vehicles group file works as is; a top-level ``random:`` only with
    ``count: 0``, as conf/vehicles/default.yaml ends),
    relative to the directory the command was launched from.  For a long list (1,000 vehicles):
    Hydra sees only the path, and :mod:`gmtiflow.scene.vehicles_file` reads the file with libyaml
    and the same type checks.  Refused when the group itself lists vehicles (the file's list is
    the scene's list: ``vehicles=file vehicles.file=big.yaml``); the ``random`` fleet applies as
    usual.  ``config.to_object`` returns the plain :class:`VehiclesConfig` holding the file's
    vehicles, so the run's ``/config`` and the stage cache keys list them, not the path: the
    same vehicles as a group file or as ``file`` give the same run file.
    """

    file: Optional[str] = None
