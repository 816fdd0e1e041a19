"""Path checks shared by the command-line tools (docs/reliability.md, "Outputs")."""
from __future__ import annotations

import os
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
