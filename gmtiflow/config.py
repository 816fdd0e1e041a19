"""The application config: one dataclass tree registered with Hydra's ConfigStore.

Each group's schema is declared next to the code that uses it and typed here, at the top level
(``roadmap: RoadmapConfig``), so that group YAML files need no ``defaults:`` list and
``group=glob(*)`` sweeps see only real options (``../shared/reference/hydra.md`` §3).
Hydra/OmegaConf reject unknown keys, wrong types and unknown options at compose time;
:func:`to_object` then converts to dataclasses, reads ``vehicles.file`` (a long vehicle list
kept out of Hydra, :mod:`gmtiflow.scene.vehicles_file`) and :func:`validate` runs every
``problems()`` check, raising one :class:`~gmtiflow.errors.ConfigError` that names each full key
path.  Hydra composes :class:`ComposedConfig`; the run gets the plain :class:`AppConfig`.
"""
from __future__ import annotations

import dataclasses
import functools
import logging
import math
from dataclasses import dataclass, field
from datetime import datetime, timezone
from enum import Enum
from itertools import chain
from typing import Dict, List, Optional, Tuple

import numpy as np
from hydra.core.config_store import ConfigStore
from omegaconf import MISSING, DictConfig, OmegaConf
from omegaconf._utils import YAML_BOOL_TYPES, is_float, is_int   # loaded with omegaconf
from omegaconf.errors import OmegaConfBaseException

from gmtiflow import config_yaml
from gmtiflow.cache import CacheConfig
from gmtiflow.config_tree import (SCALARS, field_names, field_values, holds_only_scalars,
                                  is_empty, numeric_leaves, record_columns, unknown_keys)
from gmtiflow.errors import ConfigError
from gmtiflow.evaluate.config import MetricsConfig, TrackerConfig
from gmtiflow.export_config import ExportConfig
from gmtiflow.report.config import ReportConfig
from gmtiflow.scene import vehicles_file
from gmtiflow.scene.platform_config import PlatformConfig
from gmtiflow.scene.roadmap_config import RoadmapConfig
from gmtiflow.scene.terrain_config import TerrainConfig
from gmtiflow.scene.vehicles_config import VehiclesConfig, VehiclesGroupConfig
from gmtiflow.schema import MAX_MAGNITUDE, Problem, positive
from gmtiflow.sensor.clutter import ClutterConfig
from gmtiflow.sensor.config import SensorConfig

log = logging.getLogger(__name__)


@dataclass
class SceneConfig:
    """What the whole scene shares: its length and the UTC instant of ``time_s = 0``."""

    duration_s: float = 300.0
    epoch_utc: str = "2026-06-01T08:00:00Z"

    def problems(self) -> List[Problem]:
        out = positive(self, "duration_s")
        try:
            parsed = datetime.fromisoformat(self.epoch_utc.replace("Z", "+00:00"))
        except ValueError:
            return out + [Problem("epoch_utc", f"must be an ISO-8601 UTC instant such as "
                                               f"2026-06-01T08:00:00Z, got {self.epoch_utc!r}")]
        if parsed.utcoffset() is None:
            out.append(Problem("epoch_utc", f"must carry a time zone (Z for UTC), got "
                                            f"{self.epoch_utc!r}"))
            return out
        # Exports write dates with 4-digit years: the whole scene must end within year 9999.
        last = datetime(9999, 12, 31, 23, 59, 59, tzinfo=timezone.utc)
        first = datetime(1970, 1, 1, tzinfo=timezone.utc)
        if parsed < first:
            out.append(Problem("epoch_utc", f"must be 1970-01-01 or later, got "
                                            f"{self.epoch_utc!r}"))
        elif not out and (last - parsed).total_seconds() < self.duration_s:
            out.append(Problem("epoch_utc", f"the scene ({self.duration_s:g} s from "
                                            f"{self.epoch_utc}) must end by "
                                            f"9999-12-31T23:59:59Z"))
        return out


class DwellMode(str, Enum):
    """How a scan is evaluated (DESIGN §5, §7)."""

    dwell_resolved = "dwell_resolved"   # every dwell at its own time and beam centre
    instant_scan = "instant_scan"       # whole scan at one instant, beam on each target


@dataclass
class FidelityConfig:
    """What a scene models and how finely: the speed/accuracy trade (DESIGN §7)."""

    name: str = "standard"
    time_step_s: float = 0.5
    """Step of the vehicle speed profiles (motion integration)."""
    truth_output_dt_s: float = 1.0
    """Sampling interval of the /truth table written to the run file."""
    dwell_mode: DwellMode = DwellMode.dwell_resolved
    terrain_step_m: float = 30.0
    """Ray-marching step of terrain line-of-sight checks (unused on flat terrain)."""
    merge_iterate: bool = False
    """Merge until no pair is left (dense scenes) rather than one pass (paper §5.3)."""

    def problems(self) -> List[Problem]:
        out = positive(self, "time_step_s", "truth_output_dt_s", "terrain_step_m")
        if not out and self.time_step_s > 10.0:
            out.append(Problem("time_step_s", f"must be at most 10 s, got {self.time_step_s}"))
        if not out and self.terrain_step_m < MIN_TERRAIN_STEP_M:
            out.append(Problem("terrain_step_m", f"must be at least {MIN_TERRAIN_STEP_M:g} m "
                                                 f"(finer than any DEM), got "
                                                 f"{self.terrain_step_m!r}"))
        return out


MIN_TERRAIN_STEP_M = 0.1
"""The finest line-of-sight ray step: a tenth of a 1 m lidar grid's cell.  A ray holds about
(its length / step) samples, its work and memory growing as 1/step: 0.1 m took 1.9 s and 260 MB
on a 20 s hills scene, 1e-4 m 2.9 GB and over a minute (1e-6 m: no end)."""


MAIN_SENSOR = "main"
"""The default name of the first sensor; its draws use the root seed's streams."""


@dataclass
class SensorSlotConfig:
    """One more airborne sensor of the scene: a platform preset and a sensor preset.

    Declared under ``sensors.<name>`` (docs/sensor.md, "Several sensors"), composed from the
    same groups as the first sensor with package overrides, e.g. in an ``experiment/`` file
    ``- /platform@sensors.east.platform: default`` and ``- /sensor@sensors.east.sensor: wide_fov``
    (on the command line ``+platform@sensors.east.platform=default ...``).
    """

    platform: PlatformConfig = MISSING
    sensor: SensorConfig = MISSING


@dataclass
class AppConfig:
    """The whole run.  Groups are chosen in ``conf/config.yaml`` and on the command line."""

    seed: int = 1
    progress: bool = True
    """Show tqdm progress bars on long stages (only on a terminal)."""
    scene: SceneConfig = field(default_factory=SceneConfig)
    roadmap: RoadmapConfig = MISSING
    vehicles: VehiclesConfig = MISSING
    platform: PlatformConfig = MISSING
    terrain: TerrainConfig = MISSING
    sensor: SensorConfig = MISSING
    sensor_name: str = MAIN_SENSOR
    """Name of the first sensor (``platform`` + ``sensor``, sensor_id 0)."""
    sensors: Dict[str, SensorSlotConfig] = field(default_factory=dict)
    """More sensors by name (sensor_id 1, 2 ... in this order); each its own platform + radar."""
    clutter: ClutterConfig = MISSING
    tracker: TrackerConfig = MISSING
    metrics: MetricsConfig = field(default_factory=MetricsConfig)
    fidelity: FidelityConfig = MISSING
    export: ExportConfig = MISSING
    report: ReportConfig = field(default_factory=ReportConfig)
    cache: CacheConfig = field(default_factory=CacheConfig)
    """Stage cache (gmtiflow.cache): where, and whether, stage outputs are reused."""
    chunk_s: float = 600.0
    """Scene time per block of /truth rows built and appended at once (bounds memory)."""
    sensor_workers: int = 1
    """Chunks of revisits the sensor computes at once in threads (same output for any value)."""

    def problems(self) -> List[Problem]:
        out = []
        if not (0 <= self.seed < 2 ** 63):
            out.append(Problem("seed", f"must be in [0, 2^63), got {self.seed}"))
        out += positive(self, "chunk_s")
        if not (isinstance(self.sensor_workers, int) and 1 <= self.sensor_workers <= 256):
            out.append(Problem("sensor_workers", f"must be an integer in [1, 256], got "
                                                 f"{self.sensor_workers!r}"))
        return out + sensor_problems(self)


@dataclass(frozen=True)
class SensorSlot:
    """One sensor of the scene, resolved: its id, name, platform, radar and stream seed."""

    sensor_id: int
    name: str
    platform: PlatformConfig
    sensor: SensorConfig
    platform_id: str
    """STANAG 4607 platform id (P8) of its aircraft (:func:`platform_id`)."""
    stream_seed: int
    """The seed its draws derive from (:func:`stream_seed`)."""


def stream_seed(seed: int, name: str) -> int:
    """The seed of sensor ``name``'s draws: keyed by its name, nothing else.

    The sensor named ``main`` (the default scene's one sensor) draws from the root seed's own
    streams, so a one-sensor scene is what it always was; any other sensor from
    ``derived_seed(seed, "sensors", name)``.  A sensor's dwells, detections and looks therefore
    depend on the seed, its name and its own settings only: adding, removing or reordering
    other sensors never changes them (common random numbers), and a sensor run alone reproduces
    its rows of a several-sensor run.
    """
    return int(seed) if name == MAIN_SENSOR else derived_seed(seed, "sensors", name)


def derived_seed(seed: int, *names: str) -> int:
    """A 63-bit seed derived by name from the root seed (independent streams per name)."""
    from gmtiflow import rng
    return int(rng.seed_sequence(seed, *names).generate_state(1, np.uint64)[0] >> np.uint64(1))


def platform_id(base: str, sensor_id: int, n_sensors: int) -> str:
    """The STANAG 4607 platform id of a sensor's aircraft, as the 4607 writer makes it: one
    sensor: ``export.platform_id``; several: that id with the sensor id appended, within 10
    characters (GMTIFLOW0, GMTIFLOW1 ...)."""
    if n_sensors <= 1:
        return base
    suffix = str(sensor_id)
    return base[:10 - len(suffix)] + suffix


def sensor_slots(cfg: "AppConfig") -> List[SensorSlot]:
    """The scene's sensors in sensor_id order: the first (``platform`` + ``sensor``), then
    ``sensors`` in declaration order."""
    named = [(str(cfg.sensor_name), cfg.platform, cfg.sensor)] + [
        (str(name), extra.platform, extra.sensor) for name, extra in (cfg.sensors or {}).items()]
    base = getattr(cfg.export, "platform_id", "GMTIFLOW")
    slots = [SensorSlot(i, name, plat, sens, platform_id(base, i, len(named)),
                        stream_seed(cfg.seed, name))
             for i, (name, plat, sens) in enumerate(named)]
    return slots


def sensor_problems(cfg: "AppConfig") -> List[Problem]:
    """Sensor names (and so their 4607 platform ids) must be unique; each names its key."""
    out: List[Problem] = []
    where = {}
    if not str(cfg.sensor_name).strip():
        out.append(Problem("sensor_name", "must not be empty"))
    seen_names = {str(cfg.sensor_name): "sensor_name"}
    for name in (cfg.sensors or {}):
        key = f"sensors.{name}"
        if str(name) in seen_names:
            out.append(Problem(key, f"sensor name {name!r} is already used by "
                                    f"{seen_names[str(name)]}; every sensor needs its own name"))
        seen_names.setdefault(str(name), key)
    names = [str(cfg.sensor_name)] + [str(n) for n in (cfg.sensors or {})]
    base = getattr(cfg.export, "platform_id", "GMTIFLOW")
    for i, name in enumerate(names):
        key = "sensor_name" if i == 0 else f"sensors.{name}"
        pid = platform_id(str(base), i, len(names))
        if pid in where:
            out.append(Problem("export.platform_id", f"gives sensors {where[pid]} and {key} the "
                                                     f"same STANAG 4607 platform id {pid!r}; "
                                                     f"choose another"))
        where.setdefault(pid, key)
    return out


@dataclass
class ComposedConfig(AppConfig):
    """The schema Hydra composes (``base_config``): :class:`AppConfig` whose ``vehicles`` group
    also takes ``file`` (:class:`~gmtiflow.scene.vehicles_config.VehiclesGroupConfig`).
    :func:`to_object` reads that file and returns the :class:`AppConfig`, which has no ``file``
    key: its ``/config`` text and cache keys are those of the same vehicles listed in a group."""

    vehicles: VehiclesGroupConfig = MISSING


def register() -> None:
    """Register the schema as ``base_config`` (the first entry of config.yaml's defaults)."""
    ConfigStore.instance().store(name="base_config", node=ComposedConfig)


register()


def to_object(cfg: DictConfig) -> AppConfig:
    """Convert a composed config into validated dataclasses, or raise ConfigError.

    Every missing value (``???``) is listed when there are any.  ``OmegaConf.to_object``
    refuses a config with one, so the walk that lists them (``OmegaConf.missing_keys``: ~0.9 s
    CPU for 1,000 listed vehicles) runs only when the conversion fails.

    ``vehicles.file`` is read here (:func:`resolved`), relative to the working directory (the
    launch directory), before validation: the problems of its vehicles are named by the file
    and their index in it (``vehicles.file /x/big.yaml: vehicles[12].cruise_speed_mps: …``)."""
    try:
        obj = OmegaConf.to_object(cfg)
    except Exception as exc:
        missing = sorted(OmegaConf.missing_keys(cfg))
        if missing:
            raise ConfigError("missing config value(s): " + ", ".join(missing)
                              + " (set them on the command line, e.g. key=value)") from None
        if isinstance(exc, OmegaConfBaseException):
            raise ConfigError(f"invalid config: {exc}") from None
        raise
    unknown = unknown_key_problems(obj)
    if unknown:
        raise ConfigError("invalid config: " + "; ".join(f"{p.key}: {p.message}"
                                                         for p in unknown))
    obj, file_path = resolved(obj)
    validate(obj, vehicles_file=file_path)
    for message in late_start_warnings(obj, vehicles_file=file_path):
        log.warning("%s", message)
    return obj


def unknown_key_problems(obj) -> List[Problem]:
    """A Problem for each key of the composed tree that its schema lacks (added with ``+``:
    Hydra accepts it, the dataclass carries it as a stray attribute and nothing reads it), with
    the closest known key when there is one."""
    import difflib
    out = []
    for key, known in unknown_keys(obj):
        parent, _, name = key.rpartition(".")
        close = difflib.get_close_matches(name, known, n=1, cutoff=0.6)
        hint = f"; did you mean {parent + '.' if parent else ''}{close[0]}?" if close else ""
        out.append(Problem(key, f"unknown config key (nothing reads it){hint}"))
    return out


def resolved(obj: AppConfig, base_dir: Optional[str] = None) -> Tuple[AppConfig, Optional[str]]:
    """``obj`` as an :class:`AppConfig` whose vehicles group is a plain ``VehiclesConfig``: the
    vehicles of ``vehicles.file`` read (:mod:`gmtiflow.scene.vehicles_file`, relative paths
    against ``base_dir``, default the working directory), and the absolute path of that file
    (None without one).  Not validated."""
    vehicles, path = vehicles_file.expand(obj.vehicles, base_dir)
    if type(obj) is AppConfig and vehicles is obj.vehicles:
        return obj, None
    values = {name: getattr(obj, name) for name in field_names(AppConfig)}
    values["vehicles"] = vehicles
    return AppConfig(**values), path


def problems_of(obj, prefix: str = "", reported: bool = False) -> List[Problem]:
    """All problems of a dataclass tree, with full key paths.

    Plain leaves and empty containers are skipped without a call, and so are lists (or lists
    of lists, such as waypoints) of plain scalars, checked in bulk: no dataclass inside, nothing
    to check.  A dataclass whose ``problems()`` already reports those of the dataclasses in some
    of its fields (directly or as their list items) names them in a class attribute
    ``problems_include``; their ``problems()`` is not called again (``reported``): the same
    problems, each listed once (:func:`validate`), at half the calls for a long vehicle list.
    """
    out: List[Problem] = []
    if dataclasses.is_dataclass(obj):
        check = getattr(obj, "problems", None)
        if callable(check) and not reported:
            out += [Problem(f"{prefix}{p.key}", p.message) for p in check()]
        included = getattr(obj, "problems_include", ())
        for name, value in zip(field_names(obj), field_values(obj)):
            if type(value) not in SCALARS and not is_empty(value):
                out += problems_of(value, f"{prefix}{name}.", name in included)
    elif isinstance(obj, (list, tuple)):
        if holds_only_scalars(obj) or _reported_records(obj, reported):
            return out
        for i, item in enumerate(obj):
            out += problems_of(item, f"{prefix[:-1]}[{i}].", reported)
    elif isinstance(obj, dict):
        for key, item in obj.items():
            out += problems_of(item, f"{prefix}{key}.")
    return out


def _reported_records(items, reported: bool) -> bool:
    """Walking ``items`` would find no problem: two or more dataclasses of one class whose
    ``problems()`` is not to be called (``reported``, or it has none), whose fields hold, across
    the whole list, plain scalars, lists of them (waypoints ...) or dataclasses of one class for
    which the same holds (``problems_include``).  Checked field by field across the list (a
    long vehicle list), not item by item; anything else (False) is walked item by item."""
    columns = record_columns(items)
    if columns is None:
        return False
    cls = type(items[0])
    if not reported and callable(getattr(cls, "problems", None)):
        return False
    included = getattr(cls, "problems_include", ())
    for name, column in columns:
        kinds = set(map(type, column))
        if kinds <= SCALARS:
            continue
        if kinds <= {list, tuple}:
            joined = list(chain.from_iterable(column))
            if not (holds_only_scalars(joined) or _reported_records(joined, name in included)):
                return False
        elif len(kinds) != 1 or not _reported_records(column, name in included):
            return False
    return True


_MAGNITUDE_EXEMPT = {"seed"}


def magnitude_problems(obj) -> List[Problem]:
    """A Problem for every numeric leaf of the tree beyond ±:data:`MAX_MAGNITUDE`."""
    return [Problem(key, f"must be within ±{MAX_MAGNITUDE:g}, got {value!r}")
            for key, value in numeric_leaves(obj, bound=MAX_MAGNITUDE)
            if key not in _MAGNITUDE_EXEMPT and math.isfinite(value)
            and abs(value) > MAX_MAGNITUDE]


def validate(obj: AppConfig, vehicles_file: Optional[str] = None) -> None:
    """Raise one ConfigError listing every invalid value by its full key path.

    With ``vehicles_file`` (the vehicles were read from that file), the keys of listed vehicles
    name the file instead: ``vehicles.file <path>: vehicles[12].name``."""
    # A group's problems() may already report its nested items; list each problem once.
    found = list(dict.fromkeys(problems_of(obj) + magnitude_problems(obj)))
    if found:
        lines = [f"{_file_key(p.key, vehicles_file)}: {p.message}" for p in found]
        raise ConfigError("invalid config: " + "; ".join(lines))


_LATE_LISTED_SHOWN = 5
"""Late vehicles named in the warning (the rest are counted)."""


def late_start_warnings(obj: AppConfig, vehicles_file: Optional[str] = None) -> List[str]:
    """Warnings (not errors) for vehicles that start after the scene's end and so never
    appear: listed ones (a vehicles file reused for a shorter scene is a legitimate use) named
    by index and name, in ``vehicles_file`` when they came from one, and a random fleet whose
    ``start_time_max_s`` is after the end, with the share of it that never appears."""
    duration_s = float(obj.scene.duration_s)
    out = []
    late = obj.vehicles.starting_after(duration_s)
    if late:
        where = f"vehicles.file {vehicles_file}" if vehicles_file else "vehicles.vehicles"
        shown = ", ".join(f"vehicles[{i}] {name!r} at {t:g} s"
                          for i, name, t in late[:_LATE_LISTED_SHOWN])
        more = len(late) - _LATE_LISTED_SHOWN
        out.append(f"{where}: {len(late)} vehicle(s) start after the scene's end "
                   f"(scene.duration_s = {duration_s:g} s) and never appear: {shown}"
                   + (f" and {more} more" if more > 0 else ""))
    random = obj.vehicles.random
    share = random.share_starting_after(duration_s)
    if share > 0:
        amount = "all" if share == 1.0 else f"{100 * share:.2g}%"
        out.append(f"vehicles.random.start_time_max_s = {random.start_time_max_s:g} s is after "
                   f"the scene's end (scene.duration_s = {duration_s:g} s): {amount} of the "
                   f"random vehicles (start times uniform in [{random.start_time_min_s:g}, "
                   f"{random.start_time_max_s:g}] s) start after it and never appear")
    return out


_LISTED = "vehicles.vehicles["


def _file_key(key: str, vehicles_file: Optional[str]) -> str:
    """The key of a problem as the user wrote it: a listed vehicle's in its file, if any."""
    if vehicles_file is None or not key.startswith(_LISTED):
        return key
    return f"vehicles.file {vehicles_file}: {key[len('vehicles.'):]}"


def to_yaml(obj: AppConfig) -> str:
    """The resolved config as YAML (stored as /config in the run file): the text of
    ``OmegaConf.to_yaml(OmegaConf.structured(obj))``, written from the dataclasses directly
    (that round trip deep-copies every node: ~70 s for a scene that lists 1,000 vehicles).

    :mod:`gmtiflow.config_yaml` writes the text of plain values itself (PyYAML's representer
    walks every node in Python: ~0.5 s for those 1,000 vehicles); where it cannot be sure of
    PyYAML's text, PyYAML writes the whole document (:func:`pyyaml_text`)."""
    if not _yaml_dumper().yaml_path_resolvers:
        text = config_yaml.dump(obj, _resolves_as_str)
        if text is not None:
            return text
    return pyyaml_text(obj)


def omegaconf_text(cfg: DictConfig) -> str:
    """``OmegaConf.to_yaml(cfg)`` (interpolations kept), what Hydra writes as
    ``.hydra/config.yaml``: OmegaConf's plain container, written by :mod:`gmtiflow.config_yaml`
    with the key limit of PyYAML's pure-Python emitter, which OmegaConf uses (the same text,
    tests/test_config_yaml.py; that emitter took ~2 s for a scene listing 1,000 vehicles), or by
    OmegaConf itself where that writer leaves the document to PyYAML."""
    from omegaconf._utils import get_omega_conf_dumper

    dumper = get_omega_conf_dumper()
    if not dumper.yaml_path_resolvers and (dumper.yaml_implicit_resolvers
                                           == _yaml_dumper().yaml_implicit_resolvers):
        container = OmegaConf.to_container(cfg, resolve=False, enum_to_str=True)
        text = config_yaml.dump(container, _resolves_as_str, max_key=config_yaml.PYTHON_MAX_KEY)
        if text is not None:
            return text
    return OmegaConf.to_yaml(cfg)


def pyyaml_text(obj) -> str:
    """The YAML PyYAML writes for the config tree as plain data: what :func:`to_yaml` gives."""
    import yaml
    return yaml.dump(_plain(obj), default_flow_style=False, allow_unicode=True,
                     sort_keys=False, Dumper=_yaml_dumper())


def _resolves_as_str(text: str) -> bool:
    """A bare ``text`` reads back as the string itself: OmegaConf's dumper does not quote it
    (it quotes what reads as a bool or number) and no implicit resolver of the dumper claims it
    (null, timestamps ...), as ``Resolver.resolve`` decides."""
    if text in _YAML_BOOLS or _reads_as_number(text):
        return False
    resolvers = _yaml_dumper().yaml_implicit_resolvers
    candidates = resolvers.get(text[:1])        # those for its first character ...
    anywhere = resolvers.get(None)              # ... and those for any (none, usually)
    if anywhere:
        candidates = (candidates or []) + anywhere
    for tag, regexp in candidates or ():
        if regexp.match(text):
            return tag == "tag:yaml.org,2002:str"
    return True


_YAML_BOOLS = frozenset(YAML_BOOL_TYPES)
"""OmegaConf's ``yaml_is_bool`` words (its list, as a set: one hash, not 22 comparisons)."""

_WORD_NUMBERS = frozenset({"inf", "infinity", "nan"})


def _reads_as_number(text: str) -> bool:
    """OmegaConf's ``is_int(text) or is_float(text)`` (``int()`` or ``float()`` accepts it),
    without raising for the usual word: an ASCII string that starts with a letter is never an
    int, and a float only as inf, infinity or nan (any case, trailing ASCII whitespace)."""
    if text[:1].isalpha() and text.isascii():
        return text.rstrip(" \t\n\v\f\r").lower() in _WORD_NUMBERS
    return is_int(text) or is_float(text)


@functools.lru_cache(maxsize=None)
def _yaml_dumper():
    """OmegaConf's dumper (its representers: strings that read as bool or number quoted) on
    libyaml's emitter when PyYAML has it: the same text (tests/test_config.py compares them)
    at a third of the pure-Python emitter's time."""
    import yaml
    from omegaconf._utils import get_omega_conf_dumper
    dumper = get_omega_conf_dumper()
    if not getattr(yaml, "__with_libyaml__", False):
        return dumper
    return type("OmegaConfCDumper", (yaml.CDumper,),
                {"yaml_representers": dict(dumper.yaml_representers),
                 "yaml_multi_representers": dict(dumper.yaml_multi_representers)})


def _plain(value):
    """Dataclasses, Enums (by name), lists and dicts as plain containers, as OmegaConf's
    ``to_container(enum_to_str=True)`` gives them."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: _plain(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, Enum):
        return value.name
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return {(k.name if isinstance(k, Enum) else k): _plain(v) for k, v in value.items()}
    return value

