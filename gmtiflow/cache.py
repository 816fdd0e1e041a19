"""Stage cache: reuse an expensive stage's output when nothing it depends on has changed.

A stage's cache **key** is a SHA-256 over

* the stage name and :data:`CACHE_FORMAT`,
* the resolved YAML of every config subtree the stage reads (``to_key_text``), with a
  fingerprint of every input file a string in it names, taken of the file the loaders read
  (``~`` expanded, symlinks resolved): its SHA-256 up to :data:`HASH_LIMIT_BYTES`, else its
  size, modification and change times and inode,
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
both compute and the last rename wins, with identical content.

Every entry ends with a trailer holding the SHA-256 of what precedes it.  It is verified
before anything is unpickled: an entry that fails (flipped bytes, cut short by a full disk or a
kill) or cannot be read counts as a miss, is logged and rewritten.  A cache directory that
cannot be written (full, read-only) is logged and skipped: the cache never fails a run.

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
import stat
import tempfile
from contextlib import contextmanager
from dataclasses import dataclass
from enum import Enum
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator, List, Optional

from omegaconf import OmegaConf

from gmtiflow.errors import StoreError

log = logging.getLogger(__name__)

CACHE_FORMAT = 2
"""Bumped whenever what an entry holds changes meaning."""

_MISSING = object()

HASH_LIMIT_BYTES = 64 * 2**20
"""Input files up to this size are fingerprinted by content, bigger ones by their metadata."""

_TRAILER_MAGIC = b"GMTIFLOW-CACHE-SHA256\n"
_TRAILER_BYTES = len(_TRAILER_MAGIC) + 32


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


def _file_print(path: str) -> Optional[str]:
    """Fingerprint of the regular file a config string names, as a loader opens it (``~``
    expanded, symlinks resolved), or None if it names none."""
    try:
        real = os.path.realpath(os.path.expanduser(path))
        st = os.stat(real)
    except (OSError, ValueError):
        return None
    if not stat.S_ISREG(st.st_mode):
        return None
    if st.st_size <= HASH_LIMIT_BYTES:
        h = hashlib.sha256()
        try:
            with open(real, "rb") as f:
                for block in iter(lambda: f.read(1 << 20), b""):
                    h.update(block)
        except OSError:
            return None
        return f"{real}:sha256:{h.hexdigest()}"
    return f"{real}:{st.st_size}:{st.st_mtime_ns}:{st.st_ctime_ns}:{st.st_ino}"


def _file_prints(data: Any, out: List[str]) -> None:
    """Fingerprints of every existing file a string in ``data`` names (input files)."""
    if isinstance(data, dict):
        for v in data.values():
            _file_prints(v, out)
    elif isinstance(data, list):
        for v in data:
            _file_prints(v, out)
    elif isinstance(data, str) and data and len(data) < 4096:
        fp = _file_print(data)
        if fp is not None:
            out.append(fp)


def to_key_text(**parts: Any) -> str:
    """Canonical text of named config subtrees and values (what a key hashes): the sorted
    YAML of ``{"parts": ..., "files": ...}`` as ``OmegaConf.to_yaml(..., sort_keys=True)``
    writes it.  Plain data is written by :mod:`gmtiflow.config_yaml` (the same text,
    ``tests/test_config_yaml.py``; OmegaConf's structured copy and Python emitter took ~12 s
    for a scene listing 1,000 vehicles); anything that module does not reproduce goes through
    OmegaConf as before."""
    text = _fast_key_text(parts)
    return text if text is not None else _omegaconf_key_text(parts)


def _omegaconf_key_text(parts: dict) -> str:
    """:func:`to_key_text` through OmegaConf (structured copies, its YAML dumper)."""
    plain = {name: _plain(value) for name, value in sorted(parts.items())}
    prints: List[str] = []
    _file_prints(plain, prints)
    return OmegaConf.to_yaml(OmegaConf.create({"parts": plain, "files": prints}), sort_keys=True)


def _fast_key_text(parts: dict) -> Optional[str]:
    """:func:`to_key_text` without OmegaConf, or None where :mod:`gmtiflow.config_yaml` cannot
    write it."""
    from gmtiflow import config, config_yaml
    tree = {name: value.value if isinstance(value, Enum) else config._plain(value)
            for name, value in sorted(parts.items())}
    prints: List[str] = []
    _file_prints(tree, prints)
    return config_yaml.dump({"parts": tree, "files": prints}, config._resolves_as_str,
                            sort_keys=True, max_key=config_yaml.PYTHON_MAX_KEY)


def stage_key(stage: str, *, seed: Optional[int], upstream: Iterable[str] = (), **parts: Any) -> str:
    """The cache key of ``stage`` (hex, 32 chars) for these config parts and upstream keys."""
    h = hashlib.sha256()
    from gmtiflow import __version__   # not at import: reading the package metadata is slow
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

    def _open_verified(self, path: Path):
        """The entry opened at its start if its checksum holds, else None (a miss, logged)."""
        try:
            f = open(path, "rb")
        except FileNotFoundError:
            return None
        except OSError as exc:
            log.warning("cache entry %s unreadable (%s): recomputing", path, exc)
            return None
        try:
            size = os.fstat(f.fileno()).st_size
            if size < _TRAILER_BYTES:
                raise ValueError(f"{size} B, shorter than its checksum trailer")
            h = hashlib.sha256()
            left = size - _TRAILER_BYTES
            while left:
                block = f.read(min(left, 1 << 20))
                if not block:
                    raise ValueError("cut short while reading")
                h.update(block)
                left -= len(block)
            trailer = f.read(_TRAILER_BYTES)
            if trailer[:len(_TRAILER_MAGIC)] != _TRAILER_MAGIC:
                raise ValueError("no checksum trailer (cut short, or not a cache entry)")
            if trailer[len(_TRAILER_MAGIC):] != h.digest():
                raise ValueError("checksum mismatch (the entry was altered or damaged)")
            f.seek(0)
            return f
        except (OSError, ValueError) as exc:
            f.close()
            log.warning("cache entry %s is damaged (%s): recomputing", path, exc)
            return None

    def _load(self, path: Path) -> Any:
        f = self._open_verified(path)
        if f is None:
            return _MISSING
        with f:
            try:
                return pickle.load(f)
            except Exception as exc:  # verified but unreadable (another Python): recompute
                log.warning("cache entry %s unreadable (%s): recomputing", path, exc)
                return _MISSING

    def _writer(self, path: Path) -> Optional["_EntryWriter"]:
        """A checksumming writer of a new entry, or None (logged) if the directory refuses."""
        try:
            return _EntryWriter(path)
        except OSError as exc:
            log.warning("could not write cache entry %s: %s", path, exc)
            return None

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
                    w = self._writer(path)
                    if w is not None:
                        w.write_items([value])
                        w.commit()
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
        f = self._open_verified(path)
        if f is not None:
            log.info("cache hit %s %s", stage, key)
            self.hits.append(stage)
            with f:    # verified: the items and their end marker are all there
                try:
                    while True:
                        item = pickle.load(f)
                        if isinstance(item, _End):
                            return
                        yield item
                except Exception as exc:
                    raise StoreError(f"cache entry {path} passed its checksum but cannot be "
                                     f"unpickled ({type(exc).__name__}); delete it and run "
                                     f"again") from None
        log.info("cache miss %s %s", stage, key)
        self.misses.append(stage)
        n = 0
        w = self._writer(path)
        try:
            for item in produce():
                if w is not None:
                    w.write_items([item])
                    if w.failed:
                        w = None
                n += 1
                yield item
            if w is not None:
                w.write_items([_End(n)])
                w.commit()
                w = None
        finally:
            if w is not None:      # the consumer stopped early or the producer raised
                w.discard()


class _EntryWriter:
    """Writes one entry (pickles + SHA-256 trailer) to a temporary file, renamed on commit.

    An OSError while writing (full disk) is logged once and the entry dropped: the run goes on.
    """

    def __init__(self, path: Path):
        self.path = path
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".partial", dir=path.parent)
        self.tmp = Path(name)
        self._f = os.fdopen(fd, "wb")
        self._hash = hashlib.sha256()
        self.failed = False

    def write(self, data) -> None:          # pickle's file protocol
        self._hash.update(data)
        self._f.write(data)

    def write_items(self, items) -> None:
        if self.failed:
            return
        try:
            for item in items:
                pickle.dump(item, self, protocol=5)
        except OSError as exc:
            self._fail(exc)

    def _fail(self, exc: OSError) -> None:
        log.warning("could not write cache entry %s (%s); the run goes on without it",
                    self.path, exc)
        self.failed = True
        self.discard()

    def commit(self) -> None:
        if self.failed:
            return
        try:
            self._f.write(_TRAILER_MAGIC + self._hash.digest())
            self._f.close()
            umask = os.umask(0)
            os.umask(umask)
            os.chmod(self.tmp, 0o666 & ~umask)
            os.replace(self.tmp, self.path)
        except OSError as exc:
            self._fail(exc)

    def discard(self) -> None:
        try:
            self._f.close()
        except OSError:
            pass
        self.tmp.unlink(missing_ok=True)


@dataclass(frozen=True)
class _End:
    """End marker of a cached stream."""

    n_items: int
