"""Progress bars of the simulation stages (config ``progress``): tqdm, only when asked for and
only on a terminal.

tqdm's own ``disable=None`` rule (no bar unless its stream is a terminal) is applied here
*before* tqdm is imported or a bar is made: making one, even a disabled one, creates tqdm's
process-wide lock, which imports :mod:`multiprocessing` and makes a semaphore (~5 ms of a small
run, ~60 ms on a cold file cache).  A run writing to a pipe or a log pays nothing for bars it
does not show.  A leaf module (imports nothing of gmtiflow): the truth kernel and the sensor
use it.  The bars after the simulation (export, report) are :func:`gmtiflow.console.progress`.
"""
from __future__ import annotations

import sys


def on_terminal(file=None) -> bool:
    """Whether ``file`` (default stderr) is a terminal (tqdm's ``disable=None`` rule)."""
    try:
        return (sys.stderr if file is None else file).isatty()
    except (AttributeError, ValueError):            # replaced or closed stream
        return False


class _NoBar:
    """Stands in for a counted bar that is not shown."""

    def update(self, n: int = 1) -> None:
        pass

    def close(self) -> None:
        pass


def stage_progress(items, enabled: bool, **tqdm_kwargs):
    """The simulation stages' bars (config ``progress``): ``items`` wrapped in a tqdm bar when
    ``enabled`` and stderr is a terminal, else ``items`` itself."""
    if not (enabled and on_terminal()):
        return items
    from tqdm import tqdm
    return tqdm(items, **tqdm_kwargs)


def stage_counter(total: int, enabled: bool, **tqdm_kwargs):
    """A bar counted with ``update``/``close`` (the truth kernel's steps) when ``enabled`` and
    stderr is a terminal, else a silent stand-in."""
    if not (enabled and on_terminal()):
        return _NoBar()
    from tqdm import tqdm
    return tqdm(total=total, **tqdm_kwargs)
