"""The one error type of the converter toolset.

Every reader raises :class:`FormatError` for malformed input, and only it: no ``struct.error``,
``IndexError``, ``UnicodeDecodeError`` or ``KeyError`` escapes.  Messages name where the problem
is (file and byte offset for binary formats, line and column for text formats) and what was
expected, so a user can act on them.
"""
from __future__ import annotations


class FormatError(ValueError):
    """An input file is truncated, malformed or not of the format it claims to be."""


def where(source_name: str | None) -> str:
    """Prefix naming the input in messages ('' for anonymous byte strings)."""
    return f"{source_name}: " if source_name else ""
