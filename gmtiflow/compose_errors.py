"""Hydra's composition errors as one line naming what is wrong (plus at most a hint line).

Hydra reports an unknown group option (``sensor=wide_fvo``), an unknown key
(``sensor.freq_hzz=1``), a value of the wrong type or an override it cannot parse in 6-12
lines: its message, OmegaConf's ``full_key``/``object_type`` block, the config search path and
"Set the environment variable HYDRA_FULL_ERROR=1 ...".  :func:`composition_error` turns each
into a :class:`~gmtiflow.errors.CompositionError` whose message is one line naming the override,
the group or key, and the choices (the closest known option or key first), and whose ``hint`` is
at most one more line.  Used by :func:`gmtiflow.compose.compose_dictconfig` (the Python API) and
by the ``gmtiflow`` command (:mod:`gmtiflow.cli`), which prints it and exits 1 without a
traceback (``HYDRA_FULL_ERROR=1`` still gives Hydra's own report with the stack).

Imports only Hydra's and OmegaConf's error classes: the command needs this before the pipeline.
"""
from __future__ import annotations

import dataclasses
import difflib
import re
from importlib import resources
from typing import List, Optional, Sequence

from hydra.errors import (CompactHydraException, ConfigCompositionException,
                          MissingConfigException, OverrideParseException)
from omegaconf.errors import ConfigAttributeError, ConfigKeyError, OmegaConfBaseException

from gmtiflow.errors import CompositionError

COMPOSITION_ERRORS = (ConfigCompositionException, OverrideParseException, ValueError)
"""What Hydra raises when the overrides cannot be composed into a config (a ValueError only from
its defaults list, ``sensor=1``: :func:`composition_error` tells; any other is re-raised)."""

_OPTIONS_OF = re.compile(r"Available options in '([^']+)'")
_NOT_FOUND = re.compile(r"Could not (?:find|load) '([^']+)'")
_GRAMMAR = "https://hydra.cc/docs/1.3/advanced/override_grammar/basic/"


def composition_error(exc: BaseException) -> Optional[CompositionError]:
    """The one-line error for Hydra's composition error ``exc``; None for any other exception
    (a sweep job's failure, a bug)."""
    if not isinstance(exc, COMPOSITION_ERRORS):
        return None
    if not isinstance(exc, CompactHydraException):
        return _group_value(exc)
    if isinstance(exc, OverrideParseException):
        return _parse_error(exc)
    if isinstance(exc, MissingConfigException):
        found = _missing_option(exc)
        if found is not None:
            return found
    cause = exc.__cause__
    if isinstance(cause, (ConfigKeyError, ConfigAttributeError)):     # an unknown key
        return _unknown_key(cause)
    if isinstance(cause, OmegaConfBaseException) and getattr(cause, "full_key", None):
        return CompositionError(f"invalid config: {cause.full_key}: {_first_line(cause)}")
    return _plain(exc)


def _group_value(exc: BaseException) -> Optional[CompositionError]:
    """Hydra's defaults list refuses a group override whose value is no option name
    (``sensor=1``, ``sensor=null``) with a bare ValueError; None for a ValueError raised
    anywhere else (a bug: re-raised as it is)."""
    tb = exc.__traceback__
    while tb is not None and tb.tb_next is not None:
        tb = tb.tb_next
    if tb is None or tb.tb_frame.f_globals.get("__name__") != "hydra._internal.defaults_list":
        return None
    override = tb.tb_frame.f_locals.get("override")
    line = getattr(override, "input_line", None)
    what = f"the override {line!r}" if line else "an override"
    return CompositionError(f"cannot use {what}: {_first_line(exc)}",
                            hint="a config group takes an option name, GROUP=OPTION "
                                 "(gmtiflow --help lists the groups and their options)")


def _missing_option(exc: MissingConfigException) -> Optional[CompositionError]:
    """``GROUP=OPTION`` whose option is not a config of the group: the group, the option, the
    closest option and all of them."""
    text = str(exc)
    missing = exc.missing_cfg_file or ""
    m = _NOT_FOUND.search(text)
    if not missing and m:
        missing = m.group(1)
    listed = _OPTIONS_OF.search(text)
    if listed:
        group = listed.group(1)
    elif "/" in missing:
        group = missing.split("/", 1)[0]
    else:
        return None
    if not missing.startswith(group + "/"):
        return None
    option = missing[len(group) + 1:]
    options = _options(group, exc.options or ())
    close = difflib.get_close_matches(option, options, n=1, cutoff=0.6)
    guess = f"; did you mean {group}={close[0]}?" if close else ""
    known = f" (options: {', '.join(options)})" if options else ""
    return CompositionError(f"config group {group} has no option {option!r}{guess}{known}")


def _options(group: str, listed: Sequence[str]) -> List[str]:
    """The options Hydra listed for ``group`` and those of the packaged config, with the ones
    in its sub-folders (``experiment=challenge/convoy``), which Hydra's list leaves out."""
    out = list(listed)
    try:
        root = resources.files("gmtiflow.conf").joinpath(*group.split("/"))
        if root.is_dir():
            stack = [(root, "")]
            while stack:
                folder, prefix = stack.pop()
                for item in sorted(folder.iterdir(), key=lambda p: p.name):
                    if item.is_dir() and not item.name.startswith("__"):
                        stack.append((item, f"{prefix}{item.name}/"))
                    elif item.name.endswith(".yaml"):
                        out.append(f"{prefix}{item.name[:-5]}")
    except (ModuleNotFoundError, OSError):
        pass
    return sorted(dict.fromkeys(out), key=lambda o: (o.count("/"), o))


def _unknown_key(cause: OmegaConfBaseException) -> CompositionError:
    """An override of a key the schema lacks: the key and the closest known one."""
    full_key = str(cause.full_key or cause.key or "")
    parent, _, name = full_key.rpartition(".")
    known = _known_keys(cause.object_type)
    close = difflib.get_close_matches(name, known, n=1, cutoff=0.6) if name else []
    guess = f"; did you mean {parent + '.' if parent else ''}{close[0]}?" if close else ""
    what = "unknown config key" if parent else "unknown config group or key"
    return CompositionError(f"invalid config: {full_key}: {what}{guess}",
                            hint="gmtiflow --cfg job shows every key (--package GROUP: one group)")


def _known_keys(object_type) -> List[str]:
    """The field names of the schema dataclass the key was looked up in (none otherwise)."""
    if isinstance(object_type, type) and dataclasses.is_dataclass(object_type):
        return [f.name for f in dataclasses.fields(object_type)]
    return []


def _parse_error(exc: OverrideParseException) -> CompositionError:
    """An override Hydra's grammar cannot read: the override and the parser's complaint."""
    lines = [line.strip() for line in str(exc.message).splitlines()]
    what = [line for line in lines if line and not line.startswith("See https://")
            and not line.startswith("Error parsing override")]
    reason = "; ".join(what) or "cannot parse"
    return CompositionError(f"cannot parse the override {exc.override!r}: {reason}",
                            hint=f"write KEY=VALUE or GROUP=OPTION; quote a value holding "
                                 f"spaces, brackets or commas ('key=\"a b\"'); grammar: "
                                 f"{_GRAMMAR}")


def _plain(exc: CompactHydraException) -> CompositionError:
    """Any other composition error: Hydra's first line, its second as the hint, and the
    OmegaConf cause's own first line."""
    lines = [line.strip() for line in str(exc).splitlines()]
    lines = [line for line in lines if line and not line.startswith(("See https://",
                                                                     "Config search path"))]
    first = lines[0] if lines else type(exc).__name__
    cause = exc.__cause__
    if isinstance(cause, OmegaConfBaseException):
        first = f"{first} {_first_line(cause)}"
    hint = lines[1] if len(lines) > 1 and not lines[1].startswith("provider=") else None
    return CompositionError(first, hint=hint)


def _first_line(exc: BaseException) -> str:
    """OmegaConf's message without its ``full_key:``/``object_type=`` lines."""
    text = getattr(exc, "msg", None) or str(exc)
    return str(text).strip().splitlines()[0] if str(text).strip() else type(exc).__name__
