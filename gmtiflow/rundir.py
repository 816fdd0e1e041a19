"""The run directory: one run at a time, and never one run's config beside another's outputs.

docs/reliability.md, "Re-runs into the same directory".  A run into a directory

1. takes an exclusive lock on it (:func:`claim`, ``flock`` on the directory itself); a second
   run into the same directory fails at once with :class:`RunDirBusyError` instead of deleting
   the first one's temporaries;
2. refuses a directory whose Hydra outputs (``.hydra/``, its YAML files, the job's ``.log``)
   are symlinks (:func:`check_hydra_outputs`): they would be written through to wherever they
   point;
3. removes what an earlier run left (:func:`prepare`): ``run.h5``, the files the earlier run's
   manifest ``outputs.json`` lists and writers' temporaries; the new manifest (``complete:
   false``, listing both runs' names until they are gone) is written first, so a kill during
   the removal leaves a manifest that still claims the leftovers;
4. only then writes the run's own ``.hydra/config.yaml``, ``hydra.yaml`` and
   ``overrides.yaml`` (:func:`write_hydra_files`; the packaged config sets
   ``hydra.output_subdir: null`` so that Hydra does not write them before step 3: a kill in
   between used to leave the new config beside the previous run's complete ``run.h5``).

At the end the runner rewrites the manifest with ``complete: true`` (:func:`write_manifest`).
"""
from __future__ import annotations

import errno
import json
import logging
import os
import threading
from contextlib import contextmanager
from pathlib import Path
from typing import Dict, Iterable, Iterator, List, Optional

from gmtiflow.errors import GmtiflowError

log = logging.getLogger(__name__)

RUN_FILE = "run.h5"
MANIFEST = "outputs.json"
"""Written first (``complete: false``, the files the run may write) and last (``complete: true``,
the files it wrote, with sizes)."""
HYDRA_SUBDIR = ".hydra"
HYDRA_FILES = ("config.yaml", "hydra.yaml", "overrides.yaml")


class RunDirError(GmtiflowError):
    """The run directory cannot be used (symlinked Hydra outputs)."""


class RunDirBusyError(RunDirError):
    """Another run holds the run directory's lock."""


# --------------------------------------------------------------------------------------------
# the lock
# --------------------------------------------------------------------------------------------
_held: Dict[str, List[int]] = {}      # real path -> [fd, depth]: claim is re-entrant per process
_held_guard = threading.Lock()


@contextmanager
def claim(out_dir: os.PathLike) -> Iterator[Path]:
    """Hold an exclusive lock on ``out_dir`` (created if needed) for the block.

    ``flock`` on the directory itself (no lock file to leave behind or race on); released when
    the block ends or the process dies.  Re-entrant within a process.  Where ``flock`` is
    unavailable the block runs unlocked.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    key = os.path.realpath(out)
    with _held_guard:
        if key in _held:
            _held[key][1] += 1
            fd = None
        else:
            fd = _lock(out)
            _held[key] = [fd, 1]
    try:
        yield out
    finally:
        with _held_guard:
            _held[key][1] -= 1
            if _held[key][1] == 0:
                fd = _held.pop(key)[0]
                if fd is not None:
                    os.close(fd)        # releases the lock


def _lock(out: Path):
    try:
        import fcntl
    except ImportError:    # pragma: no cover (Windows)
        return None
    fd = os.open(out, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0) | getattr(os, "O_CLOEXEC", 0))
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as exc:
        os.close(fd)
        if exc.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
            raise RunDirBusyError(
                f"{out}: another gmtiflow run is writing to this run directory; wait for it to "
                f"finish or choose another directory (hydra.run.dir=...)") from None
        return None        # flock unsupported here (some network file systems): unlocked
    return fd


# --------------------------------------------------------------------------------------------
# Hydra's files
# --------------------------------------------------------------------------------------------
class NoFollowFileHandler(logging.FileHandler):
    """``logging.FileHandler`` that never writes through a symlink (``O_NOFOLLOW``).

    The job log (``gmtiflow.log``) is opened by Hydra before gmtiflow runs; if it is a symlink
    the handler discards the records and :func:`check_hydra_outputs` refuses the directory.
    """

    def _open(self):
        flags = os.O_WRONLY | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0) | \
            getattr(os, "O_CLOEXEC", 0) | (os.O_APPEND if "a" in self.mode else os.O_TRUNC)
        try:
            fd = os.open(self.baseFilename, flags, 0o666)
        except OSError as exc:
            if exc.errno != errno.ELOOP:
                raise
            return open(os.devnull, "a", encoding=self.encoding)
        return os.fdopen(fd, "a" if "a" in self.mode else "w", encoding=self.encoding,
                         errors=self.errors)


def check_hydra_outputs(out_dir: os.PathLike, log_names: Iterable[str] = ()) -> None:
    """RunDirError if ``.hydra``, its files or a job log in ``out_dir`` is a symlink."""
    out = Path(out_dir)
    sub = out / HYDRA_SUBDIR
    paths = [sub, *(sub / n for n in HYDRA_FILES if not sub.is_symlink()),
             *(out / n for n in log_names)]
    links = [p for p in paths if p.is_symlink()]
    if links:
        raise RunDirError(
            f"{out}: {', '.join(str(p.relative_to(out)) for p in links)} "
            f"{'is a symlink' if len(links) == 1 else 'are symlinks'}; gmtiflow and Hydra would "
            f"write through {'it' if len(links) == 1 else 'them'} to another file. Remove "
            f"{'it' if len(links) == 1 else 'them'} or choose another run directory")


def write_hydra_files(out_dir: os.PathLike, files: Dict[str, str]) -> None:
    """Write ``.hydra/<name>`` for each of ``files`` (name -> YAML text), each atomically (a
    symlink in the way is replaced, never written through; :func:`check_hydra_outputs` refuses
    one before this point)."""
    sub = Path(out_dir) / HYDRA_SUBDIR
    check_hydra_outputs(out_dir)
    sub.mkdir(exist_ok=True)
    from gmtiflow.formats import write_atomic   # the writers: not on every start-up
    for name, text in files.items():
        write_atomic(sub / name, text.encode("utf-8"))


def holds_earlier_run(out_dir: os.PathLike) -> bool:
    """Whether ``out_dir`` holds a run file or a manifest of an earlier run."""
    out = Path(out_dir)
    return (out / RUN_FILE).exists() or (out / MANIFEST).exists()


# --------------------------------------------------------------------------------------------
# outputs of an earlier run
# --------------------------------------------------------------------------------------------
def temporaries(out_dir: Path, name: str, entries: Optional[List[str]] = None) -> List[Path]:
    """Temporaries a killed writer of ``name`` leaves: RunWriter/report, formats' writers
    (``.<name>.*.partial*`` and ``<name>.*.part``, as glob matches them).  ``entries``: the
    directory's names when the caller listed it already (one listing for all its names,
    instead of two glob scans and their patterns compiled per name: ~0.8 ms of a fresh
    process's first run)."""
    if entries is None:
        try:
            entries = os.listdir(out_dir)
        except (FileNotFoundError, NotADirectoryError):
            return []
    hidden, plain = f".{name}.", f"{name}."
    return [out_dir / e for e in sorted(e for e in entries if e.startswith(hidden)
                                        and ".partial" in e[len(hidden):])] + \
        [out_dir / e for e in sorted(e for e in entries if e.startswith(plain)
                                     and e[len(plain):].endswith(".part"))]


def read_manifest(out_dir: Path) -> List[str]:
    """File names an earlier run's manifest claims (plain names inside ``out_dir`` only)."""
    path = out_dir / MANIFEST
    if not path.is_file():
        return []
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
        names = list(doc.get("planned", [])) + [f.get("name") for f in doc.get("files", [])]
    except (ValueError, AttributeError, TypeError, OSError) as exc:
        log.warning("%s: unreadable manifest of an earlier run (%s); ignored", path,
                    type(exc).__name__)
        return []
    return [n for n in names if isinstance(n, str) and n and Path(n).name == n
            and n not in (".", "..", MANIFEST)]


def write_manifest(out_dir: Path, doc: dict) -> None:
    from gmtiflow.formats import write_atomic   # the writers: not on every start-up
    write_atomic(Path(out_dir) / MANIFEST, (json.dumps(doc, indent=1) + "\n").encode())


def prepare(out_dir: os.PathLike, planned: List[str], seed: int) -> List[Path]:
    """Remove what an earlier run left in ``out_dir`` and write the new manifest
    (``complete: false``); returns the removed paths.

    Removed: ``run.h5``, the files the earlier run's manifest lists, and writers' temporaries.
    Files of other names, and files no gmtiflow manifest claims (a first run into a user's
    folder), stay.  The new manifest is written before anything is deleted and claims the
    earlier run's names too, so a kill half-way still leaves them claimed for the next run.
    """
    out = Path(out_dir)
    claimed = read_manifest(out)
    names = list(dict.fromkeys([RUN_FILE, *claimed]))
    claiming = list(dict.fromkeys([*planned, *names]))
    write_manifest(out, {"complete": False, "seed": seed, "planned": claiming, "files": []})
    paths = [out / n for n in names]
    entries = os.listdir(out)
    for name in dict.fromkeys([*planned, *claimed]):
        paths += temporaries(out, name, entries)
    removed = []
    for path in dict.fromkeys(paths):
        if path.is_file() or path.is_symlink():
            path.unlink()
            removed.append(path)
    if claiming != list(planned):     # (a re-run of the same outputs: already written)
        write_manifest(out, {"complete": False, "seed": seed, "planned": list(planned),
                             "files": []})
    if removed:
        log.info("removed %d output(s) of an earlier run in %s: %s", len(removed), out,
                 ", ".join(p.name for p in removed))
    return removed
