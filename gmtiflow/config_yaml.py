"""The /config text of a run file, written straight from the config tree.

:func:`gmtiflow.config.to_yaml` must give exactly the text PyYAML gives for the tree as plain
data (``yaml.dump(..., default_flow_style=False, allow_unicode=True, sort_keys=False)`` with
OmegaConf's dumper on libyaml): run files are compared and hashed by that text.  PyYAML's
representer costs a Python call per node, ~0.5 s for a scene that lists 1,000 off-road vehicles;
:func:`dump` writes the same block-style text itself for the values whose YAML form is simple and
certain (dicts, lists, ints, floats, bools, None and plain-looking strings), and returns None for
anything else (unusual characters, strings long enough to be wrapped, keys that are not
strings, types other than those) so that the caller lets PyYAML write the whole document.

The rules followed are PyYAML's and libyaml's for block style with the default 80-column width:

* a mapping is ``key: value`` lines; a nested mapping is indented by 2 under its ``key:``; a
  list inside a mapping is not indented (``key:`` then ``- item`` at the key's column); a list
  or mapping inside a list starts on the item's line (``- - 1.0``, ``- name: a``);
* empty lists and mappings are written ``[]`` and ``{}``;
* floats are ``repr`` with ``.0`` put before a bare exponent (``1.0e+16``), ``.nan``, ``.inf``,
  ``-.inf``; ints ``str``; ``true``/``false``; ``null``;
* a one-line printable ASCII string is written bare unless a YAML reader would take it for
  something else (a number, a bool, null, a timestamp: the dumper's implicit resolvers, and
  OmegaConf's own quoting of strings that read as bools or numbers) or it holds an indicator
  a bare scalar cannot (libyaml's ``yaml_emitter_analyze_scalar``: a leading ``#``, ``- ``,
  ``: `` anywhere, a leading or trailing space ...); then it is single-quoted, ``'`` doubled.
"""
from __future__ import annotations

import dataclasses
import re
from enum import Enum
from itertools import chain
from typing import Callable, Dict, List, Optional, Tuple

import numpy as np

from gmtiflow.config_tree import field_names, field_values

WIDTH = 80
"""PyYAML's default line width: a bare or quoted string is folded at a space past this column."""

MAX_KEY = 128
"""libyaml writes longer keys as complex keys (``? key``)."""

PYTHON_MAX_KEY = 122
"""PyYAML's pure-Python emitter (``yaml.Dumper``, what ``OmegaConf.to_yaml`` uses) counts the
key's ``!!str`` tag too and needs the total below 128: longer keys are complex keys there."""

_ONE_LINE_ASCII = re.compile(r"[\x20-\x7e]*")
"""Strings of printable ASCII on one line: bare or single-quoted, never escaped (libyaml's
``yaml_emitter_analyze_scalar`` finds no special characters or breaks in them)."""

_LEADING_INDICATORS = frozenset("#,[]{}&*!|>'\"%@`")
"""Characters that cannot start a bare scalar."""


class Unsupported(Exception):
    """A value whose YAML text this module does not reproduce (PyYAML writes the document)."""


def dump(tree, resolves_as_str: Callable[[str], bool], *, sort_keys: bool = False,
         max_key: int = MAX_KEY) -> Optional[str]:
    """The block-style YAML of a config tree (dataclasses, Enums, dicts, lists, scalars), or
    None where PyYAML must write it.  ``resolves_as_str(s)``: a bare ``s`` reads back as the
    string ``s`` (the dumper's implicit resolvers and OmegaConf's quoting say so).

    ``sort_keys`` and ``max_key=PYTHON_MAX_KEY`` give the text of ``OmegaConf.to_yaml(
    OmegaConf.create(tree), sort_keys=True)`` instead (the stage cache's key text, for plain
    data: ``tests/test_config_yaml.py`` compares them)."""
    lines: List[str] = []
    writer = _Writer(lines, resolves_as_str, sort_keys, max_key)
    try:
        mapping = writer.mapping_of(tree)
        if mapping is None:
            return None
        if not mapping[0]:
            return "{}\n"
        writer.mapping(*mapping, 0, "")
    except Unsupported:
        return None
    lines.append("")
    return "\n".join(lines)


def float_text(value: float) -> str:
    """PyYAML's text of a float (``SafeRepresenter.represent_float``)."""
    text = repr(value)
    if "e" in text or "n" in text:          # an exponent, inf or nan
        if value != value:
            return ".nan"
        if value in (float("inf"), float("-inf")):
            return ".inf" if value > 0 else "-.inf"
        if "." not in text:
            text = text.replace("e", ".0e", 1)
    return text


def number_texts(numbers: list, kinds: set) -> List[str]:
    """PyYAML's text of each int and float of ``numbers`` (``kinds``: their types).

    Lists of waypoints repeat their values (a lapped route, a convoy's shared corners), and a
    field's values across a vehicle list often are one value: each distinct float is written
    once when there are few of them.  Floats only (ints equal to floats would share one text),
    and zeros only when all have one sign (``0.0 == -0.0`` would share one text too)."""
    if kinds == {float} and len(numbers) > 64:
        values = np.fromiter(numbers, float, len(numbers))
        distinct, index = np.unique(values, return_inverse=True)    # NaNs as one: all .nan
        if len(distinct) * 2 <= len(numbers) and _zeros_of_one_sign(values):
            distinct = distinct.tolist()
            texts = list(map(repr, distinct))
            if "e" in "".join(texts) or "n" in "".join(texts):
                texts = list(map(float_text, distinct))
            return np.array(texts, dtype=object)[index.reshape(-1)].tolist()
    texts = list(map(repr, numbers))                   # repr is str for an int
    joined = "".join(texts)
    if "e" in joined or "n" in joined:
        texts = [float_text(v) if type(v) is float else repr(v) for v in numbers]
    return texts


def _zeros_of_one_sign(values: np.ndarray) -> bool:
    """The zeros among ``values`` are all +0.0 or all -0.0."""
    negative = np.signbit(values[values == 0.0])
    return bool(negative.all() or not negative.any())


_SCALARS: Dict[type, Callable[[object], str]] = {
    float: float_text,
    int: str,
    bool: lambda v: "true" if v else "false",
    type(None): lambda v: "null",
}
"""Text of the non-string scalars (exact types: subclasses such as numpy floats go to PyYAML)."""

class _Writer:
    """Appends the lines of one document; raises :class:`Unsupported` on what it cannot write."""

    def __init__(self, lines: List[str], resolves_as_str: Callable[[str], bool],
                 sort_keys: bool = False, max_key: int = MAX_KEY):
        self.lines = lines
        self.resolves_as_str = resolves_as_str
        self.sort_keys = sort_keys
        self.max_key = max_key
        self.strings: Dict[str, str] = {}
        self.heads: Dict[Tuple[tuple, int], List[str]] = {}

    def mapping_of(self, node) -> Optional[Tuple[tuple, tuple]]:
        """(keys, values) of a mapping node (a dataclass or a dict; Enum keys by name), sorted
        by key if asked; None if ``node`` is not a mapping."""
        cls = type(node)
        if cls is dict:
            keys = tuple(node)
            if any(isinstance(k, Enum) for k in keys):      # by name, as config._plain does
                node = {(k.name if isinstance(k, Enum) else k): v for k, v in node.items()}
                keys = tuple(node)
            values = tuple(node.values())
        elif dataclasses.is_dataclass(cls) and not isinstance(node, type):
            keys, values = field_names(node), field_values(node)
        elif isinstance(node, dict):
            raise Unsupported(cls)
        else:
            return None
        if self.sort_keys and keys:
            if set(map(type, keys)) != {str}:
                raise Unsupported("keys PyYAML may not sort")
            order = sorted(range(len(keys)), key=keys.__getitem__)
            keys, values = tuple(keys[i] for i in order), tuple(values[i] for i in order)
        return keys, values

    def mapping(self, keys: tuple, values: tuple, indent: int, lead: str) -> None:
        """``key: value`` lines at ``indent``; the first line starts with ``lead``."""
        for i, (head, value) in enumerate(zip(self.key_heads(keys, indent), values)):
            self.entry(lead + head[indent:] if not i else head, value, indent)

    def entry(self, head: str, value, indent: int) -> None:
        """One ``key: value`` of a mapping at ``indent`` (``head`` is ``key:``)."""
        cls = type(value)
        if cls is float:                               # the common cases, inline
            text = repr(value)
            self.lines.append(head + " " + (float_text(value) if "e" in text or "n" in text
                                            else text))
        elif cls is str:
            self.lines.append(head + " " + self.string(value, len(head) + 1))
        elif cls in _SCALARS:
            self.lines.append(head + " " + _SCALARS[cls](value))
        elif cls is list and not value:
            self.lines.append(head + " []")
        else:
            self.value(head, value, indent, in_mapping=True)

    def sequence(self, items, indent: int, lead: str) -> None:
        """``- item`` lines at ``indent``; the first line starts with ``lead``."""
        if self.rows(items, indent, lead) or self.records(items, indent, lead):
            return
        pad = " " * indent
        scalar = _SCALARS.get
        for i, item in enumerate(items):
            head = (pad if i else lead) + "- "
            text = scalar(type(item))
            if text is not None:                       # the common case, inline
                self.lines.append(head + text(item))
            else:
                self.value(head, item, indent + 2, in_mapping=False)

    def rows(self, items, indent: int, lead: str) -> bool:
        """Write a list of equally long, non-empty lists of ints and floats (waypoints ...)
        in bulk (:meth:`list_column` of the one list), ``- - x`` then ``  - y`` per row; False
        (nothing written) for other lists."""
        if not items or set(map(type, items)) != {list}:
            return False
        texts = self.list_column((items,), indent)
        if texts is None:
            return False
        self.lines.append(lead + texts[0][indent:])
        return True

    def records(self, items, indent: int, lead: str) -> bool:
        """Write a list of mappings with the same keys (dataclasses of one class, dicts with
        the same keys: listed vehicles ...) field by field across the list, ``- key: value``
        then ``  key: value`` per item; False (nothing written) for other lists."""
        table = self.table(items)
        if table is None:
            return False
        blocks = self.blocks(*table, indent + 2, item=True)
        self.lines.append(lead + blocks[0][indent:])
        self.lines.extend(blocks[1:])
        return True

    def table(self, items) -> Optional[Tuple[tuple, list]]:
        """(keys, rows of values) of two or more mappings with the same keys in the same
        order (after sorting if asked), or None: then each is written on its own."""
        if len(items) < 2:
            return None
        cls = type(items[0])
        if set(map(type, items)) != {cls}:
            return None
        if cls is dict:
            keys = tuple(items[0])
            if any(tuple(item) != keys for item in items) or any(isinstance(k, Enum)
                                                                  for k in keys):
                return None
            rows = [tuple(item.values()) for item in items]
        elif dataclasses.is_dataclass(cls):
            keys = field_names(cls)
            rows = list(map(field_values, items))
        else:
            return None
        if not keys:
            return None
        if self.sort_keys:
            if set(map(type, keys)) != {str}:
                return None
            order = sorted(range(len(keys)), key=keys.__getitem__)
            keys = tuple(keys[i] for i in order)
            rows = [tuple(row[i] for i in order) for row in rows]
        return keys, rows

    def blocks(self, keys: tuple, rows: list, indent: int, item: bool = False) -> List[str]:
        """The ``key: value`` lines of each row at ``indent``, one string per row (lines
        joined), each written as :meth:`mapping` writes it, column by column; with ``item``,
        each row's first line as a list item's (``- `` in its last two columns of indent)."""
        heads = self.key_heads(keys, indent)
        if item:
            heads = [heads[0][:indent - 2] + "- " + heads[0][indent:], *heads[1:]]
        columns = [self.column(head, values, indent)
                   for head, values in zip(heads, zip(*rows))]
        return list(map("\n".join, zip(*columns)))

    def column(self, head: str, values: tuple, indent: int) -> List[str]:
        """The text of ``head`` + each value, as :meth:`entry` writes it."""
        kinds = set(map(type, values))
        text = self.shared_text(values, kinds, len(head) + 1)
        if text is not None:                           # a value every row holds: one text
            return [head + " " + text] * len(values)
        if kinds == {float}:
            head += " "
            return [head + text for text in number_texts(list(values), kinds)]
        if kinds == {str}:
            column = len(head) + 1
            return [head + " " + self.string(value, column) for value in values]
        if kinds <= _SCALARS.keys():
            return [head + " " + _SCALARS[type(value)](value) for value in values]
        if kinds == {list}:
            texts = self.list_column(values, indent)
            if texts is not None:
                return [head + " []" if text is None else head + "\n" + text
                        for text in texts]
        elif len(kinds) == 1:
            table = self.table(values)
            if table is not None:
                return [head + "\n" + block for block in self.blocks(*table, indent + 2)]
        lines, out = self.lines, []
        try:
            for value in values:                       # anything else: value by value
                self.lines = []
                self.entry(head, value, indent)
                out.append("\n".join(self.lines))
        finally:
            self.lines = lines
        return out

    def shared_text(self, values: tuple, kinds: set, column: int) -> Optional[str]:
        """The text, after ``column`` characters, of the one value all ``values`` hold (equal,
        of one type: a scalar, a string or an empty list), as :meth:`entry` writes it; None for
        anything else, and for zero floats (``0.0 == -0.0``: their texts differ)."""
        first = values[0]
        cls = type(first)
        if len(kinds) != 1 or not (cls in _SCALARS or cls is str or (cls is list and not first)):
            return None
        if values.count(first) != len(values):
            return None
        if cls is str:
            return self.string(first, column)
        if cls is list:
            return "[]"
        if cls is float and first == 0.0:
            return None
        return _SCALARS[cls](first)

    def list_column(self, values: tuple, indent: int) -> Optional[List[Optional[str]]]:
        """The ``- item`` lines at ``indent`` of each list (None for an empty one), for lists of
        ints and floats, of number rows all of one length (:meth:`rows`) or all empty; else
        None."""
        flat = list(chain.from_iterable(values))
        if not flat:
            return [None] * len(values)                # every list empty: ``key: []``
        kinds = set(map(type, flat))
        width, nested = 1, kinds == {list}
        if nested:
            widths = set(map(len, flat))
            if len(widths) != 1 or not flat[0]:
                return None
            width = len(flat[0])
            flat = list(chain.from_iterable(flat))
            kinds = set(map(type, flat))
        if not kinds or not kinds <= {float, int}:
            return None
        texts = number_texts(flat, kinds)
        pad = " " * indent
        row = (pad + "- - %s" + ("\n" + pad + "  - %s") * (width - 1)) if nested else (
            pad + "- %s")
        templates: Dict[int, str] = {}
        out: List[Optional[str]] = []
        start = 0
        for value in values:                           # one % per list
            count = len(value)
            if not count:
                out.append(None)
                continue
            template = templates.get(count)
            if template is None:
                template = templates[count] = "\n".join([row] * count)
            stop = start + count * width
            out.append(template % tuple(texts[start:stop]))
            start = stop
        return out

    def value(self, head: str, value, indent: int, in_mapping: bool) -> None:
        """``value`` after ``head`` (``key:`` or ``- ``): inline if a scalar or empty, else
        on the following lines."""
        sep = " " if in_mapping else ""
        cls = type(value)
        text = _SCALARS.get(cls)
        if text is not None:
            self.lines.append(head + sep + text(value))
        elif cls is str or isinstance(value, Enum):
            string = value.name if isinstance(value, Enum) else value
            self.lines.append(head + sep + self.string(string, len(head) + len(sep)))
        elif cls is list or cls is tuple:
            if not value:
                self.lines.append(head + sep + "[]")
            elif in_mapping:                            # not indented under its key
                self.lines.append(head)
                self.sequence(value, indent, " " * indent)
            else:
                self.sequence(value, indent, head)
        else:
            mapping = self.mapping_of(value)
            if mapping is None:
                raise Unsupported(cls)
            if not mapping[0]:
                self.lines.append(head + sep + "{}")
            elif in_mapping:
                self.lines.append(head)
                self.mapping(*mapping, indent + 2, " " * (indent + 2))
            else:
                self.mapping(*mapping, indent, head)

    def key_heads(self, keys: tuple, indent: int) -> List[str]:
        """``key:`` of each key at ``indent`` (cached: a dataclass's are the same every time).
        Keys are strings, never folded (libyaml's simple keys)."""
        heads = self.heads.get((keys, indent))
        if heads is None:
            pad = " " * indent
            heads = [pad + self.key(key) + ":" for key in keys]
            self.heads[(keys, indent)] = heads
        return heads

    def key(self, key) -> str:
        """The text of one mapping key."""
        if type(key) is not str or not 0 < len(key) <= self.max_key:
            raise Unsupported(key)
        return _str_text(key, self.resolves_as_str)

    def string(self, value: str, column: int) -> str:
        """The text of a string value starting at ``column``."""
        cached = self.strings.get(value)
        if cached is None:
            cached = self.strings[value] = _str_text(value, self.resolves_as_str)
        if " " in value and column + len(cached) > WIDTH:
            raise Unsupported("a string PyYAML may fold")
        return cached


_WORD = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
"""Words (nearly every key and name of a config): one-line printable ASCII with no space,
indicator or colon, which libyaml writes bare (:func:`_bare_allowed`) unless a reader would
take it for something else (``resolves_as_str``)."""


def _str_text(value: str, resolves_as_str: Callable[[str], bool]) -> str:
    """A string bare, or single-quoted where a bare one would not read back as itself."""
    if _WORD.fullmatch(value):
        return value if resolves_as_str(value) else "'" + value + "'"
    if not _ONE_LINE_ASCII.fullmatch(value):
        raise Unsupported("a string with breaks, tabs or non-ASCII characters")
    if _bare_allowed(value) and resolves_as_str(value):
        return value
    return "'" + value.replace("'", "''") + "'"


def _bare_allowed(value: str) -> bool:
    """libyaml's ``block_plain_allowed`` for a one-line printable ASCII string: no leading or
    trailing space, no document marker, no indicator where a reader would take it as one."""
    if not value:
        return True          # (the empty string resolves as null: it is quoted all the same)
    first, second = value[0], value[1:2]
    return not (first == " " or value[-1] == " " or value.startswith(("---", "..."))
                or first in _LEADING_INDICATORS
                or (first in "?-" and second in ("", " "))
                or ": " in value or value.endswith(":") or " #" in value)
