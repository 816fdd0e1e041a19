"""Path checks shared by the command-line tools (docs/reliability.md, "Outputs")."""
from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Iterable

from gmtiflow.errors import InputFileError


def refuse_same_file(out: os.PathLike, inputs: Iterable[os.PathLike]) -> None:
    """Raise InputFileError if ``out`` resolves to one of ``inputs``.

    Same file means the same path once symlinks are resolved, or the same inode (a hard
    link, or a symlink whose target is another path to the input), so a tool never
    overwrites what it reads.
    """
    for src in inputs:
        same = Path(os.path.realpath(out)) == Path(os.path.realpath(src))
        if not same:
            try:
                same = os.path.samefile(out, src)
            except OSError:        # out does not exist yet (or src vanished): not the same
                same = False
        if same:
            raise InputFileError(f"{out}: output would overwrite the input {src}; choose "
                                 f"another output path")


def check_input_file(path: os.PathLike, what: str, max_bytes: int,
                     memory_factor: float = 0.0) -> int:
    """Size in bytes of the regular file ``path``, or InputFileError naming ``what``.

    Refused: a path that is not a regular file (a device such as ``/dev/zero``, a FIFO, a
    directory), a file over ``max_bytes``, and (``memory_factor`` > 0) a file whose parse
    would need ``memory_factor`` times its size, more than this machine's available memory.
    """
    from gmtiflow.resources import available_memory_bytes, human_bytes
    p = Path(path)
    try:
        st = p.stat()
    except OSError as exc:
        raise InputFileError(f"{what} {p}: cannot read ({exc.strerror or exc})") from None
    import stat as stat_mod
    if not stat_mod.S_ISREG(st.st_mode):
        raise InputFileError(f"{what} {p}: not a regular file (a device, pipe or directory); "
                             f"give a file")
    if st.st_size > max_bytes:
        raise InputFileError(f"{what} {p}: {human_bytes(st.st_size)}, over the "
                             f"{human_bytes(max_bytes)} this input may have")
    need = memory_factor * st.st_size
    memory = available_memory_bytes()
    if need > memory:
        raise InputFileError(f"{what} {p}: reading {human_bytes(st.st_size)} needs about "
                             f"{human_bytes(need)} of memory, more than the "
                             f"{human_bytes(memory)} available (GMTIFLOW_MEMORY_BYTES)")
    return st.st_size


_SAFE_TOKEN = re.compile(r"^[A-Za-z0-9_.,+\- ]{1,24}$")


def excerpt(text: str) -> str:
    """A short quoted excerpt of file content for an error message, or ``(not shown)``.

    Only a short token of letters, digits, spaces and ``_.,+-`` (plausibly the user's own header key
    or number) is echoed; anything else (a line of ``/etc/shadow``, control characters,
    long lines) is not, so an error never leaks a file's content into a log.
    """
    text = str(text).strip()
    return repr(text) if _SAFE_TOKEN.match(text) else "(not shown)"
