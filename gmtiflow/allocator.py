"""Keep numpy's large temporaries out of fresh pages: glibc malloc settings for a run.

A run's array code makes many temporaries of one to a few MB (a sensor chunk of 300,000 pairs
is 2.4 MB per float column).  With glibc's defaults such a block is served by ``mmap`` (or from
the top of a heap that is trimmed back to the OS as soon as it is freed), so every new
temporary is fresh memory and the kernel zero-fills it page by page: on this project's
virtual machine an element-wise product of 100,000 float64 into fresh memory took ~20x as long
as into reused memory, and the sensor's arithmetic spent more time faulting than computing.  :func:`tune`
asks glibc to serve blocks up to 32 MB from the heap (``M_MMAP_THRESHOLD``), to keep up to
256 MB of freed heap instead of trimming it (``M_TRIM_THRESHOLD``) and to grow it 16 MB at a
time (``M_TOP_PAD``): freed temporaries are then reused.  The sensor stage runs ~1.4x faster
(docs/scale.md); the cost is that up to 256 MB freed late in a run stay mapped until the process ends (its peak
memory is not raised: the peak is what the run holds at once).

Results do not depend on it (memory contents never do).  :func:`tune` changes nothing when the
C library is not glibc, when the user set any ``MALLOC_*`` variable or ``GLIBC_TUNABLES``
(their choice wins), or with ``GMTIFLOW_MALLOC=default``.  The ``gmtiflow`` command calls it at
start-up, and so do the benchmarks that time runs in process (``fidelity_tradeoff.py``,
``sensor_throughput.py``, ``stonesoup_peer.py``'s gmtiflow child), so that they time the run as
the command makes it; a program that imports gmtiflow as a library keeps its own allocator
settings unless it calls :func:`tune`.
"""
from __future__ import annotations

import ctypes
import os
import sys

M_TRIM_THRESHOLD = -1
M_TOP_PAD = -2
M_MMAP_THRESHOLD = -3

SETTINGS = ((M_MMAP_THRESHOLD, 32 * 2**20), (M_TRIM_THRESHOLD, 256 * 2**20),
            (M_TOP_PAD, 16 * 2**20))
"""(mallopt parameter, value) pairs :func:`tune` sets, in order."""

_TUNED = False


def _user_chose() -> bool:
    env = os.environ
    return (env.get("GMTIFLOW_MALLOC", "").lower() == "default" or "GLIBC_TUNABLES" in env
            or any(k.startswith("MALLOC_") for k in env))


def tune() -> bool:
    """Apply :data:`SETTINGS` to this process's glibc malloc (once); True when they are in
    force.  A no-op returning False off glibc or when the user chose (module doc)."""
    global _TUNED
    if _TUNED:
        return True
    if not sys.platform.startswith("linux") or _user_chose():
        return False
    try:
        libc = ctypes.CDLL(None)
        if not hasattr(libc, "gnu_get_libc_version"):     # musl and others: leave them
            return False
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    mallopt.restype = ctypes.c_int
    _TUNED = all(mallopt(param, value) == 1 for param, value in SETTINGS)
    return _TUNED
