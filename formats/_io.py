"""Small I/O helpers shared by the writers and readers; ``atomic_path`` and ``write_atomic``
are public (``formats.atomic_path``) and used by gmtiflow's own writers too."""
from __future__ import annotations

import errno
import itertools
import os
from contextlib import contextmanager
from datetime import datetime, timezone
from pathlib import Path
from typing import Iterator, Mapping

import numpy as np

from .errors import FormatError, where


_TEMPORARY_NUMBERS = itertools.count()
_CREATE_NEW = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0) | \
    getattr(os, "O_CLOEXEC", 0) | getattr(os, "O_BINARY", 0)


def _new_temporary(path: Path, suffix: str) -> tuple:
    """``(fd, tmp)``: a new file ``.<name>.<pid>.<n><suffix>`` beside ``path``, open for
    writing.  Made with ``O_EXCL`` (never another's file, never through a symlink) and mode
    0666 minus the umask, as ``open()`` gives (not ``mkstemp``'s 0600, and no chmod after)."""
    for _ in range(1000):
        tmp = path.with_name(f".{path.name}.{os.getpid()}.{next(_TEMPORARY_NUMBERS)}{suffix}")
        try:
            return os.open(tmp, _CREATE_NEW, 0o666), tmp
        except FileExistsError:       # a temporary a killed process of this pid left
            continue
    raise FileExistsError(errno.EEXIST, "no free temporary name beside", str(path))


@contextmanager
def _replacing(dest, suffix: str) -> Iterator[tuple]:
    """``(fd, tmp)``: a new temporary beside ``dest`` (:func:`_new_temporary`, its descriptor
    open for writing: the caller closes it), renamed over ``dest`` when the block ends
    normally and deleted when it raises."""
    path = Path(dest)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = _new_temporary(path, suffix)
    try:
        yield fd, tmp
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


@contextmanager
def atomic_path(dest, suffix: str = ".partial") -> Iterator[Path]:
    """A temporary path beside ``dest`` that becomes ``dest`` only if the block completes.

    ``with atomic_path("out.pdf") as tmp: write(tmp)``: the temporary (``.out.pdf.<pid>.<n>.partial``
    in the same directory, so the final rename is atomic on POSIX; :func:`_new_temporary`) is
    renamed over ``dest`` when the block ends normally and deleted when it raises, so a path
    never holds a partial file that looks complete.  ``suffix`` ends the temporary's name, for
    writers that pick the format from the extension (``".partial.gif"``).
    """
    with _replacing(dest, suffix) as (fd, tmp):
        os.close(fd)
        yield tmp


def write_atomic(dest, data: bytes) -> None:
    """Write ``data`` to a path (never partly, as :func:`atomic_path` does, written through
    the temporary's own descriptor: one open) or to a binary file object."""
    if hasattr(dest, "write"):
        dest.write(data)
        return
    with _replacing(dest, ".partial") as (fd, _), open(fd, "wb") as f:
        f.write(data)


def write_chunks(dest, chunks) -> None:
    """Write an iterable of byte strings to a path (through :func:`atomic_path`, so a failure
    half-way leaves nothing) or to a binary file object, one chunk at a time."""
    if hasattr(dest, "write"):
        for chunk in chunks:
            dest.write(chunk)
        return
    with atomic_path(dest) as tmp, open(tmp, "wb") as f:
        for chunk in chunks:
            f.write(chunk)


def source_name(source) -> str | None:
    """A name for messages: the path, a file object's name, or None for raw bytes."""
    if isinstance(source, (str, os.PathLike)):
        return str(source)
    name = getattr(source, "name", None)
    return str(name) if isinstance(name, (str, os.PathLike)) else None


def read_source(source):
    """The content of a path, bytes or a file object (``str`` if a text-mode file gave one);
    an unreadable path is a FormatError naming it."""
    if isinstance(source, (bytes, bytearray)):
        return bytes(source)
    if isinstance(source, (str, os.PathLike)):
        try:
            with open(source, "rb") as f:
                return f.read()
        except OSError as exc:
            raise FormatError(f"{where(source_name(source))}cannot read: {exc}") from None
    return source.read()


def parse_epoch(text: str) -> datetime:
    """ISO-8601 UTC instant (``Z`` or an offset accepted; naive means UTC) -> aware datetime."""
    if isinstance(text, datetime):
        dt = text
    else:
        s = str(text).strip()
        if s.endswith(("Z", "z")):
            s = s[:-1] + "+00:00"
        dt = datetime.fromisoformat(s)
    if dt.tzinfo is None:
        dt = dt.replace(tzinfo=timezone.utc)
    return dt.astimezone(timezone.utc)


def iso_utc(epoch: datetime, time_s: np.ndarray) -> np.ndarray:
    """ISO-8601 UTC strings (microseconds, 'Z') of ``epoch + time_s``; vectorised via datetime64."""
    base = np.datetime64(epoch.replace(tzinfo=None), "us")
    t = np.asarray(time_s, dtype=np.float64)
    us = np.rint(np.where(np.isfinite(t), t, 0.0) * 1e6).astype(np.int64)
    out = np.datetime_as_string(base + us.astype("timedelta64[us]"), unit="us").astype(object)
    out = np.char.add(out.astype(str), "Z")
    return np.where(np.isfinite(t), out, "")


def n_rows(table: Mapping[str, np.ndarray], what: str = "table") -> int:
    """Common length of a table's columns; ValueError naming the table when they disagree."""
    lengths = {k: len(v) for k, v in table.items()}
    if not lengths:
        return 0
    if len(set(lengths.values())) != 1:
        raise ValueError(f"{what}: columns have different lengths: {lengths}")
    return next(iter(lengths.values()))
