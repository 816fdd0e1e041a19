"""A user error of one job of a sweep (``gmtiflow -m``), as Hydra reports it.

The basic launcher runs every job, then re-raises the first failed job's exception in the
launching process, where Hydra prints it with a Python traceback; a ``CompactHydraException``
it prints as its message alone.  :class:`JobError` carries a job's
:class:`~gmtiflow.errors.GmtiflowError` (or a disk error) that way; its ``repr`` is the
original's (``ConfigError('invalid config: ...')``), which the sweep callback writes into the
failed job's ``timing.json`` and the sweep report lists.  Kept out of :mod:`gmtiflow.cli`, which
does not import Hydra before it has to (``--help``).
"""
from __future__ import annotations

from hydra.errors import CompactHydraException


class JobError(CompactHydraException):
    """One sweep job's user error: ``str`` its message, ``repr`` the original exception's."""

    def __init__(self, message: str, kind: str = "GmtiflowError"):
        super().__init__(message, kind)         # both in args: picklable (joblib workers)

    def __str__(self) -> str:
        return str(self.args[0])

    def __repr__(self) -> str:
        return f"{self.args[1]}({self.args[0]!r})"
