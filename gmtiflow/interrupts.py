"""Ctrl-C that always stops a run, even when an extension swallows the KeyboardInterrupt.

Python turns SIGINT into a ``KeyboardInterrupt`` raised at the next bytecode; when that happens
inside C code that clears pending exceptions (some numpy/h5py paths do), the interrupt is lost
and the run would finish and claim to be complete (seen about once in ten runs at load 10).
:func:`install` (called by the ``gmtiflow`` command) keeps Python's behaviour and also records
the request; :func:`check`, called by the runner between stages, raises it again, so an
interrupted run stops at the latest at the next stage boundary — before ``run.h5`` is committed
if the interrupt came earlier.  Where Python itself swallows it (in a weakref or finaliser
callback, which it reports as "Exception ignored in ..." with a traceback) that report is not
printed: the interrupt is not lost, :func:`check` raises it.  Some extensions turn the
``KeyboardInterrupt`` into an error of their own instead (h5py's type conversion code raises
``TypeError`` when Ctrl-C lands inside it); :func:`errors_as_interrupt` gives the command that
error back as the interrupt it was.  A SIGINT the parent process ignores (``nohup``, a
background job of a script) stays ignored.
"""
from __future__ import annotations

import contextlib
import signal
import sys
import threading

_requested = threading.Event()


def _on_sigint(signum, frame):
    _requested.set()
    raise KeyboardInterrupt


def install() -> None:
    """Record Ctrl-C as well as raising it (only where SIGINT has Python's default handler),
    and keep the interrupts Python swallows in callbacks off the console."""
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        signal.signal(signal.SIGINT, _on_sigint)
        sys.unraisablehook = _quiet_swallowed_interrupt(sys.unraisablehook)


def _quiet_swallowed_interrupt(report):
    """An unraisable-exception hook that stays silent about a recorded Ctrl-C (:func:`check`
    raises it again) and hands everything else to ``report``."""
    def hook(unraisable):
        if isinstance(unraisable.exc_value, KeyboardInterrupt) and _requested.is_set():
            return
        report(unraisable)
    return hook


def requested() -> bool:
    return _requested.is_set()


def check() -> None:
    """Raise ``KeyboardInterrupt`` if Ctrl-C was pressed (and perhaps swallowed) earlier."""
    if _requested.is_set():
        raise KeyboardInterrupt


@contextlib.contextmanager
def errors_as_interrupt():
    """Raise ``KeyboardInterrupt`` (chained to the error) for any error raised in the block
    after Ctrl-C was pressed: the error is then the interrupt's doing, not the input's."""
    try:
        yield
    except Exception as exc:
        if _requested.is_set():
            raise KeyboardInterrupt from exc
        raise
