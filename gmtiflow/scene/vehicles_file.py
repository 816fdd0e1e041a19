"""Vehicles read from a YAML file (``vehicles.file``), past Hydra.

A scene listing 1,000 vehicles in a vehicles group file spent ~28 s CPU in Hydra before the
simulation started (two composes of ~12 s each: pure-Python YAML, ``OmegaConf.create``, merging
every vehicle into the typed schema; then the job's deep copy).  ``vehicles.file`` names a YAML
file holding ``vehicles: [...]`` in exactly the schema of the vehicles group's list (a vehicles
group file works as is); Hydra sees only the path.  :func:`load` reads it here:

* parsed by libyaml (``yaml.CSafeLoader``; ``yaml.SafeLoader`` where PyYAML lacks libyaml) with
  the scalar rules of OmegaConf's own loader: its implicit resolvers (``1e3`` is a float, dates
  stay strings) and duplicate keys refused;
* converted into :class:`~gmtiflow.scene.vehicles_config.VehicleSpec` dataclasses as
  OmegaConf's typed nodes convert (``OmegaConf.merge(OmegaConf.structured(VehicleSpec), entry)``,
  tests/scene/test_vehicles_file.py compares the two): a float field takes a float, an int or a
  string ``float()`` reads (``14`` -> 14.0, ``"1e3"`` -> 1000.0), never a bool; an int field an
  int or a string ``int()`` reads, never a float; a str field any scalar but bytes (``str()``
  of it); a bool field a bool, an int (non-zero is true) or yes/no/on/off/true/false/y/n;
  ``Optional`` fields also null, no other field; ``Any`` fields (node references, waypoints)
  scalars and lists or mappings of them; ``List[...]`` fields a list; nested ``speed_changes``
  items and ``convoy`` mappings of their own fields.  Unknown keys are refused, and so are
  ``???`` (OmegaConf's missing value) and ``${...}`` (interpolations: the file is plain YAML).

Every refusal is one :class:`~gmtiflow.errors.ConfigError` naming the file and the entry:
``vehicles.file /x/big.yaml: vehicles[12].cruise_speed_mps: expected a number, got 'fast'``;
YAML syntax errors give the line and column.  Range and cross-field checks (``problems()``,
duplicate names) run afterwards on the whole config (``gmtiflow.config.to_object``), their keys
naming the file the same way.

A top-level ``random:`` is accepted only when it adds no vehicles (``count: 0``, as
conf/vehicles/default.yaml ends; checked, then ignored): the random fleet is set in the config
(``vehicles.random.*``).  A file given while the vehicles group itself lists vehicles is
refused: the file's list is the scene's list (``vehicles=file vehicles.file=…``,
conf/vehicles/file.yaml).
"""
from __future__ import annotations

import dataclasses
import difflib
import functools
import os
import stat
import typing
from typing import Any, Callable, Dict, List, Optional, Tuple

from gmtiflow.errors import ConfigError, InputFileError
from gmtiflow.paths import check_input_file
from gmtiflow.scene.vehicles_config import RandomFleetSpec, VehiclesConfig, VehicleSpec

KEY = "vehicles.file"
"""The config key, as errors name it."""

MAX_FILE_BYTES = 256 * 2**20
"""The largest vehicles file read: about a million vehicles (240 B each in the group file's
own style), the most ``vehicles.random.count`` allows too."""

MEMORY_FACTOR = 50.0
"""Memory the parse needs per byte of file: 41x measured (tracemalloc peak of :func:`load`
on 8,000 vehicles, 1.9 MB of YAML), with a margin."""

_MISSING = "???"


class _Refused(Exception):
    """A value the schema refuses: ``where`` (``vehicles[3].convoy.count``) and why."""

    def __init__(self, where: str, message: str):
        super().__init__(where, message)
        self.where = where
        self.message = message


def resolve_path(path: str, base_dir: Optional[str] = None) -> str:
    """``path`` with ``~`` expanded, made absolute against ``base_dir`` (default: the working
    directory, which is the launch directory: conf/config.yaml sets ``hydra.job.chdir: false``)."""
    path = os.path.expanduser(str(path))
    return os.path.normpath(os.path.join(base_dir or os.getcwd(), path))


def expand(group, base_dir: Optional[str] = None) -> Tuple[VehiclesConfig, Optional[str]]:
    """The vehicles group as :class:`VehiclesConfig` (no ``file`` field) and the absolute path
    of the file its vehicles came from (None without ``file``).

    ``group`` is the converted group (``VehiclesGroupConfig`` or a plain ``VehiclesConfig``);
    its ``random`` fleet is kept as it is.  Raises ConfigError as the module docstring says."""
    file = getattr(group, "file", None)
    if file is None:
        if type(group) is VehiclesConfig:
            return group, None
        return VehiclesConfig(vehicles=group.vehicles, random=group.random), None
    if not isinstance(file, str) or not file.strip():
        raise ConfigError(f"{KEY}: no file given (got {file!r}); give the path of a YAML file "
                          f"holding 'vehicles: [...]', e.g. vehicles.file=big.yaml")
    path = resolve_path(file, base_dir)
    if group.vehicles:
        raise ConfigError(
            f"{KEY} {path}: the vehicles group also lists {len(group.vehicles)} vehicle(s) "
            f"(vehicles.vehicles, e.g. {group.vehicles[0].name!r}); the file's list is the "
            f"scene's list: put them in the file, or choose a group that lists none "
            f"(vehicles=file vehicles.file={file})")
    out = VehiclesConfig(vehicles=load(path), random=group.random)
    out.source_file = path      # beside the config, for errors found later (not a key)
    return out, path


def load(path: str) -> List[VehicleSpec]:
    """The vehicles of the YAML file at ``path`` (absolute), type-checked (module docstring).

    Only a regular file of at most :data:`MAX_FILE_BYTES` whose parse (about
    :data:`MEMORY_FACTOR` times its size) fits in the available memory is read: a device such
    as ``/dev/zero`` used to be read without end."""
    try:
        if stat.S_ISDIR(os.stat(path).st_mode):     # FileNotFoundError: "no such file"
            raise IsADirectoryError(path)
        check_input_file(path, KEY, MAX_FILE_BYTES, memory_factor=MEMORY_FACTOR)
        with open(path, "rb") as f:
            raw = f.read(MAX_FILE_BYTES + 1)
    except FileNotFoundError:
        raise ConfigError(f"{KEY} {path}: no such file") from None
    except IsADirectoryError:
        raise ConfigError(f"{KEY} {path}: is a directory, not a YAML file") from None
    except OSError as exc:
        raise ConfigError(f"{KEY} {path}: cannot read it: {exc.strerror or exc}") from None
    except InputFileError as exc:       # not a regular file, too large for the cap or memory
        raise ConfigError(str(exc)) from None
    if len(raw) > MAX_FILE_BYTES:       # it grew after the check
        raise ConfigError(f"{KEY} {path}: over the {MAX_FILE_BYTES // 2**20} MiB a vehicles "
                          f"file may have")
    data = parse(raw, path)
    if not isinstance(data, dict):
        got = "an empty file" if data is None else f"a {_kind(data)}"
        raise ConfigError(f"{KEY} {path}: expected a mapping with a 'vehicles' list, got {got}")
    if "random" in data:
        _no_fleet(data["random"], path)
    unknown = [k for k in data if k not in ("vehicles", "random")]
    if unknown:
        raise ConfigError(f"{KEY} {path}: unknown top-level key {unknown[0]!r}; a vehicles file "
                          f"holds 'vehicles: [...]' (and at most a 'random:' of count 0)")
    if "vehicles" not in data:
        raise ConfigError(f"{KEY} {path}: no 'vehicles' list")
    entries = data["vehicles"]
    if not isinstance(entries, list):
        raise ConfigError(f"{KEY} {path}: vehicles: expected a list of vehicles, got "
                          f"{_shown(entries)}")
    try:
        return [vehicle(entry, f"vehicles[{i}]") for i, entry in enumerate(entries)]
    except _Refused as exc:
        raise ConfigError(f"{KEY} {path}: {exc.where}: {exc.message}") from None


def _no_fleet(random, path: str) -> None:
    """A file's ``random:`` is accepted when it adds no vehicles (``count: 0``, as
    conf/vehicles/default.yaml ends), type-checked and ignored; a fleet is refused."""
    try:
        count = _record(RandomFleetSpec, random, "random").count
    except _Refused as exc:
        raise ConfigError(f"{KEY} {path}: {exc.where}: {exc.message}") from None
    if count != 0:
        raise ConfigError(f"{KEY} {path}: random.count: a vehicles file brings no random fleet "
                          f"(got count {count}); set it in the config instead, e.g. "
                          f"vehicles.random.count={count}")


def vehicle(entry, where: str = "vehicle") -> VehicleSpec:
    """One ``vehicles`` entry (a mapping) as a VehicleSpec; raises :class:`_Refused`."""
    return _record(VehicleSpec, entry, where)


# --- YAML ------------------------------------------------------------------------------------

def parse(raw: bytes, path: str = "<bytes>"):
    """The YAML document of ``raw``, read as OmegaConf reads a config file; a syntax error is
    a ConfigError naming the file, line and column."""
    import yaml
    try:
        return yaml.load(raw, Loader=_loader())
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark else ""
        what = ", ".join(str(p) for p in (exc.context, exc.problem) if p)
        raise ConfigError(f"{KEY} {path}: {where}{_one_line(what)}") from None
    except yaml.YAMLError as exc:     # a reader error: bytes that are not text
        raise ConfigError(f"{KEY} {path}: not YAML: {_one_line(str(exc))}") from None


@functools.lru_cache(maxsize=None)
def _loader():
    """libyaml's parser with OmegaConf's loader's resolvers and duplicate-key refusal."""
    import yaml
    from omegaconf._utils import get_yaml_loader

    omegaconf_loader = get_yaml_loader()
    base = getattr(yaml, "CSafeLoader", None) or yaml.SafeLoader

    def construct_mapping(self, node, deep=False):
        keys = set()
        for key_node, _ in node.value:
            if key_node.tag != yaml.resolver.BaseResolver.DEFAULT_SCALAR_TAG:
                continue
            if key_node.value in keys:
                raise yaml.constructor.ConstructorError(
                    "while constructing a mapping", node.start_mark,
                    f"found duplicate key {key_node.value}", key_node.start_mark)
            keys.add(key_node.value)
        return base.construct_mapping(self, node, deep=deep)

    resolvers = {k: list(v) for k, v in omegaconf_loader.yaml_implicit_resolvers.items()}
    return type("VehiclesFileLoader", (base,), {"construct_mapping": construct_mapping,
                                                "yaml_implicit_resolvers": resolvers})


def _one_line(text: str) -> str:
    return " ".join(text.split())


# --- conversions (OmegaConf's typed nodes) ---------------------------------------------------

_PRIMITIVES = (int, float, bool, str, bytes, type(None))
"""What an OmegaConf ``Any`` node holds (``is_primitive_type_annotation`` for YAML's types)."""


def _shown(value) -> str:
    if isinstance(value, (list, dict)):
        return f"a {_kind(value)}"
    return f"{value!r}" if value is not None else "null"


def _kind(value) -> str:
    return {list: "list", dict: "mapping"}.get(type(value), type(value).__name__)


def _special(value, where: str) -> None:
    """Refuse OmegaConf's special strings: ``???`` (missing) and interpolations."""
    if value == _MISSING:
        raise _Refused(where, "'???' (a missing value) is not allowed in a vehicles file")
    if "${" in value:
        raise _Refused(where, f"interpolations are not resolved in a vehicles file, got "
                              f"{value!r}")


def _float(value, where: str) -> float:
    kind = type(value)
    if kind is float:
        return value
    if kind is int or kind is str:
        if kind is str:
            _special(value, where)
        try:
            return float(value)
        except (ValueError, OverflowError):
            pass
    raise _Refused(where, f"expected a number, got {_shown(value)}")


def _int(value, where: str) -> int:
    kind = type(value)
    if kind is int:
        return value
    if kind is str:
        _special(value, where)
        try:
            return int(value)
        except ValueError:
            pass
    raise _Refused(where, f"expected an integer, got {_shown(value)}")


def _str(value, where: str) -> str:
    kind = type(value)
    if kind is str:
        _special(value, where)
        return value
    if kind in (int, float, bool):
        return str(value)
    raise _Refused(where, f"expected a string, got {_shown(value)}")


_TRUE = frozenset({"yes", "y", "on", "true"})
_FALSE = frozenset({"no", "n", "off", "false"})


def _bool(value, where: str) -> bool:
    kind = type(value)
    if kind is bool:
        return value
    if kind is int:
        return value != 0
    if kind is str:
        _special(value, where)
        try:
            return int(value) != 0
        except ValueError:
            if value.lower() in _TRUE:
                return True
            if value.lower() in _FALSE:
                return False
    raise _Refused(where, f"expected true or false, got {_shown(value)}")


def _any(value, where: str):
    """A scalar, or a fresh list or mapping of them (an alias in the YAML is not shared)."""
    kind = type(value)
    if kind is str:
        _special(value, where)
        return value
    if kind in _PRIMITIVES:
        return value
    if kind is list:
        return [_any(v, f"{where}[{i}]") for i, v in enumerate(value)]
    if kind is dict:
        return {k: _any(v, f"{where}.{k}") for k, v in value.items()}
    raise _Refused(where, f"expected a value, a list or a mapping, got {_shown(value)}")


def _optional(convert: Callable) -> Callable:
    def optional(value, where):
        return None if value is None else convert(value, where)
    return optional


def _required(convert: Callable) -> Callable:
    """A field (or list item) that is not Optional: null refused, as OmegaConf does."""
    def required(value, where):
        if value is None:
            raise _Refused(where, "must not be null")
        return convert(value, where)
    return required


def _list_of(convert: Callable) -> Callable:
    def list_of(value, where):
        if type(value) is not list:
            raise _Refused(where, f"expected a list, got {_shown(value)}")
        return [convert(v, f"{where}[{i}]") for i, v in enumerate(value)]
    return list_of


def _dict_of(convert: Callable) -> Callable:
    def dict_of(value, where):
        if type(value) is not dict:
            raise _Refused(where, f"expected a mapping, got {_shown(value)}")
        out = {}
        for k, v in value.items():
            if type(k) is not str:
                raise _Refused(where, f"expected string keys, got {k!r}")
            out[k] = convert(v, f"{where}.{k}")
        return out
    return dict_of


_SCALAR = {float: _float, int: _int, str: _str, bool: _bool}


def _converter(hint) -> Callable:
    """The conversion of a field (or list item) annotated ``hint``; null only where allowed."""
    if hint is Any:
        return _any
    origin = typing.get_origin(hint)
    args = typing.get_args(hint)
    if origin is typing.Union and type(None) in args:
        (inner,) = [a for a in args if a is not type(None)]
        return _optional(_converter(inner))
    if origin in (list, List):
        return _required(_list_of(_converter(args[0])))
    if origin in (dict, Dict) and args[0] is str:
        return _required(_dict_of(_converter(args[1])))
    if hint in _SCALAR:
        return _required(_SCALAR[hint])
    if dataclasses.is_dataclass(hint):
        return _required(functools.partial(_record, hint))
    raise TypeError(f"no conversion for {hint!r}")   # a schema change this module must follow


@functools.lru_cache(maxsize=None)
def _fields(cls) -> Dict[str, Callable]:
    hints = typing.get_type_hints(cls)
    return {f.name: _converter(hints[f.name]) for f in dataclasses.fields(cls)}


def _record(cls, value, where: str):
    """A dataclass from a mapping of its fields (missing ones take their defaults)."""
    if type(value) is not dict:
        raise _Refused(where, f"expected a mapping of {cls.__name__} fields, got "
                              f"{_shown(value)}")
    fields = _fields(cls)
    kwargs = {}
    for key, item in value.items():
        convert = fields.get(key)
        if convert is None:
            raise _Refused(where, _unknown(cls, key))
        kwargs[key] = convert(item, f"{where}.{key}")
    return cls(**kwargs)


def _unknown(cls, key) -> str:
    names = list(_fields(cls))
    close = difflib.get_close_matches(str(key), names, n=1)
    hint = f" (did you mean {close[0]!r}?)" if close else f" ({cls.__name__} has {', '.join(names)})"
    return f"unknown key {key!r}{hint}"
