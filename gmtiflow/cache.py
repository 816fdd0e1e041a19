"""Stage cache: reuse an expensive stage's output when nothing it depends on has changed.

A stage's cache **key** is a SHA-256 over

* the stage name and :data:`CACHE_FORMAT`,
* the resolved YAML of every config subtree the stage reads (``to_key_text``), with a
  fingerprint (size, modification time) of every input file a string in it names,
* the keys of the stages it consumes (so a changed upstream setting invalidates exactly the
  stages downstream of it, and nothing upstream),
* the root seed,
* the package version and a digest of the package's own source files (so editing the code
  never serves a stale entry, even without a version bump).

Entries are files ``<dir>/<stage>/<key>.pkl`` written under a temporary name in the same
directory and renamed into place (``os.replace`` is atomic on POSIX), so concurrent runs of a
sweep never see a half-written entry.  A run that misses takes an advisory lock
(``<key>.lock``, ``fcntl.flock``) before computing and looks again once it holds it, so the
parallel jobs of a sweep (joblib, submitit) that need the same truth compute it once: the
others wait and then hit.  Where ``flock`` is missing (Windows, some network file systems)
both compute and the last rename wins, with identical content.  An entry that cannot be read (truncated by a full disk,
written by another Python) counts as a miss and is rewritten.

Serialisation is :mod:`pickle` (protocol 5) of numpy-backed objects, exact to the bit, so
runs with the cache on are bit-identical to runs with it off.  **Trust model:** unpickling runs
code, so the cache directory must be local and written only by you, like a virtualenv.  Never
point ``cache.dir`` at a directory others can write to.  Delete it at any time to reclaim space
(``rm -rf outputs/.cache``); there is no eviction.

Streams (the sensor stage's chunks) are stored as consecutive pickles in one file so that a
replay holds only one chunk in memory at a time (:meth:`StageCache.stream`).
"""
from __future__ import annotations

import dataclasses
import hashlib
import logging
import os
import pickle
from contextlib import contextmanager
from dataclasses import dataclass
from enum import Enum
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator, List, Optional

from omegaconf import OmegaConf

from gmtiflow.formats import atomic_path
from gmtiflow import __version__
from gmtiflow.errors import StoreError

log = logging.getLogger(__name__)

CACHE_FORMAT = 1
"""Bumped whenever what an entry holds changes meaning."""

_MISSING = object()


@dataclass
class CacheConfig:
    """Where and whether stage outputs are cached (``cache.enabled``, ``cache.dir``)."""

    enabled: bool = True
    dir: str = "outputs/.cache"
    """Cache directory (relative paths are taken from the current directory, which Hydra
    does not change).  Local and trusted only: entries are pickles."""

    def problems(self) -> list:
        from gmtiflow.schema import Problem
        if self.enabled and not str(self.dir).strip():
            return [Problem("dir", "must name a directory when the cache is enabled")]
        return []


_SOURCE_DIGEST: Optional[str] = None


def source_digest() -> str:
    """SHA-256 of the package's .py files and packaged conf/ files, computed once per process."""
    global _SOURCE_DIGEST
    if _SOURCE_DIGEST is None:
        h = hashlib.sha256()
        for root in (Path(__file__).resolve().parent,):
            for path in sorted(root.rglob("*.py")):
                h.update(str(path.relative_to(root)).encode())
                h.update(path.read_bytes())
        # Packaged data the stages read by name (RCS tables under conf/sensor/rcs ...).
        try:
            import gmtiflow.conf as conf_pkg
            cdir = Path(next(iter(conf_pkg.__path__))).resolve()
            for path in sorted(p for p in cdir.rglob("*") if p.is_file()
                               and p.suffix not in (".pyc",)):
                h.update(str(path.relative_to(cdir)).encode())
                h.update(path.read_bytes())
        except (ImportError, StopIteration):  # pragma: no cover
            pass
        _SOURCE_DIGEST = h.hexdigest()
    return _SOURCE_DIGEST


def _plain(obj: Any) -> Any:
    """A config subtree as plain YAML-able data (dataclasses, enums, lists, dicts)."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return OmegaConf.to_container(OmegaConf.structured(obj), enum_to_str=True)
    if isinstance(obj, Enum):
        return obj.value
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    return obj


def _file_prints(data: Any, out: List[str]) -> None:
    """Size and mtime of every existing file a string in ``data`` names (input files)."""
    if isinstance(data, dict):
        for v in data.values():
            _file_prints(v, out)
    elif isinstance(data, list):
        for v in data:
            _file_prints(v, out)
    elif isinstance(data, str) and data and len(data) < 4096:
        try:
            st = os.stat(data)
        except (OSError, ValueError):
            return
        if os.path.isfile(data):
            out.append(f"{os.path.abspath(data)}:{st.st_size}:{st.st_mtime_ns}")


def to_key_text(**parts: Any) -> str:
    """Canonical text of named config subtrees and values (what a key hashes)."""
    plain = {name: _plain(value) for name, value in sorted(parts.items())}
    prints: List[str] = []
    _file_prints(plain, prints)
    return OmegaConf.to_yaml(OmegaConf.create({"parts": plain, "files": prints}), sort_keys=True)


def stage_key(stage: str, *, seed: Optional[int], upstream: Iterable[str] = (), **parts: Any) -> str:
    """The cache key of ``stage`` (hex, 32 chars) for these config parts and upstream keys."""
    h = hashlib.sha256()
    h.update(f"gmtiflow-cache {CACHE_FORMAT} {stage} {__version__} {source_digest()}\n".encode())
    h.update(f"seed {'-' if seed is None else int(seed)}\n".encode())
    for up in upstream:
        h.update(f"upstream {up}\n".encode())
    h.update(to_key_text(**parts).encode())
    return h.hexdigest()[:32]


class StageCache:
    """Get-or-compute stage outputs in a directory (or do nothing when disabled)."""

    def __init__(self, directory: Optional[os.PathLike], enabled: bool = True):
        self.enabled = bool(enabled) and directory is not None
        self.dir = Path(directory) if directory is not None else None
        self.hits: List[str] = []
        self.misses: List[str] = []

    @classmethod
    def from_config(cls, cfg: Optional[CacheConfig]) -> "StageCache":
        if cfg is None:
            return cls(None, False)
        return cls(Path(cfg.dir), cfg.enabled)

    def _path(self, stage: str, key: str) -> Path:
        return self.dir / stage / f"{key}.pkl"

    def _load(self, path: Path) -> Any:
        try:
            with open(path, "rb") as f:
                return pickle.load(f)
        except FileNotFoundError:
            return _MISSING
        except Exception as exc:  # truncated / unreadable entry: recompute it
            log.warning("cache entry %s unreadable (%s): recomputing", path, exc)
            return _MISSING

    def _atomic_write(self, path: Path, write: Callable[[Any], None]) -> None:
        with atomic_path(path) as tmp, open(tmp, "wb") as f:
            write(f)

    @contextmanager
    def _lock(self, path: Path):
        """Exclusive advisory lock next to an entry (no-op where flock is unavailable)."""
        try:
            import fcntl
            path.parent.mkdir(parents=True, exist_ok=True)
            fd = os.open(path.with_suffix(".lock"), os.O_RDWR | os.O_CREAT, 0o644)
        except (ImportError, OSError):
            yield
            return
        try:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX)
            except OSError:
                pass
            yield
        finally:
            os.close(fd)   # releases the lock

    def get_or_compute(self, stage: str, key: str, compute: Callable[[], Any]) -> Any:
        """The cached value of ``stage``/``key``, or ``compute()`` stored under it."""
        if not self.enabled:
            return compute()
        path = self._path(stage, key)
        value = self._load(path)
        if value is _MISSING:
            with self._lock(path):
                value = self._load(path)    # another job may have written it meanwhile
                if value is _MISSING:
                    log.info("cache miss %s %s", stage, key)
                    self.misses.append(stage)
                    value = compute()
                    try:
                        self._atomic_write(path, lambda f: pickle.dump(value, f, protocol=5))
                    except OSError as exc:  # a full or read-only disk must not fail the run
                        log.warning("could not write cache entry %s: %s", path, exc)
                    return value
        log.info("cache hit %s %s", stage, key)
        self.hits.append(stage)
        return value

    def stream(self, stage: str, key: str, produce: Callable[[], Iterable[Any]]
               ) -> Iterator[Any]:
        """Items of a cached stream, or of ``produce()`` (stored as they pass).

        The items are consecutive pickles ended by an end marker holding their count; the
        entry is renamed into place only after the producer is exhausted (a consumer that
        stops early leaves none), so an entry on disk is complete by construction.
        """
        if not self.enabled:
            yield from produce()
            return
        path = self._path(stage, key)
        try:
            f = open(path, "rb")
        except FileNotFoundError:
            f = None
        if f is not None:
            log.info("cache hit %s %s", stage, key)
            self.hits.append(stage)
            with f:
                while True:
                    try:
                        item = pickle.load(f)
                    except Exception as exc:
                        raise StoreError(f"cache entry {path} is damaged ({exc}); delete it "
                                         f"and run again") from None
                    if isinstance(item, _End):
                        return
                    yield item
        log.info("cache miss %s %s", stage, key)
        self.misses.append(stage)
        n = 0
        with atomic_path(path) as tmp, open(tmp, "wb") as out:
            for item in produce():
                pickle.dump(item, out, protocol=5)
                n += 1
                yield item
            pickle.dump(_End(n), out, protocol=5)


@dataclass(frozen=True)
class _End:
    """End marker of a cached stream."""

    n_items: int
