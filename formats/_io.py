"""Small I/O helpers shared by the writers and readers (not public API)."""
from __future__ import annotations

import os
import tempfile
from datetime import datetime, timezone
from pathlib import Path
from typing import Mapping

import numpy as np


def write_atomic(dest, data: bytes) -> None:
    """Write ``data`` to a path (via a temporary file renamed into place) or a binary file object.

    A path never holds a partial file that looks complete: the bytes go to a temporary file in
    the same directory, which is renamed over ``dest`` only once everything is written.
    """
    if hasattr(dest, "write"):
        dest.write(data)
        return
    path = Path(dest)
    fd, tmp = tempfile.mkstemp(prefix=path.name + ".", suffix=".part", dir=path.parent or ".")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        # mkstemp creates the file 0600; give it the mode open() would (0666 minus the umask)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def source_name(source) -> str | None:
    """A name for messages: the path, a file object's name, or None for raw bytes."""
    if isinstance(source, (str, os.PathLike)):
        return str(source)
    name = getattr(source, "name", None)
    return str(name) if isinstance(name, (str, os.PathLike)) else None


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
