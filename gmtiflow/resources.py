"""How much memory this machine has, and refusing work that cannot fit (issue 17, item 9).

The figures come from ``/proc/meminfo`` (``MemAvailable``, else ``MemTotal``) or
``os.sysconf`` and can be overridden with the environment variable ``GMTIFLOW_MEMORY_BYTES``
(for a shared machine, or for tests).
"""
from __future__ import annotations

import os
from typing import Optional

_FALLBACK_BYTES = 4 * 2**30


def available_memory_bytes() -> int:
    """Bytes of memory a run may use: ``GMTIFLOW_MEMORY_BYTES``, else what the OS says is
    available, else 4 GiB."""
    env = os.environ.get("GMTIFLOW_MEMORY_BYTES")
    if env:
        try:
            value = int(float(env))
            if value > 0:
                return value
        except ValueError:
            pass
    info = _meminfo()
    for key in ("MemAvailable", "MemTotal"):
        if key in info:
            return info[key]
    try:
        return int(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_AVPHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        return _FALLBACK_BYTES


def _meminfo() -> dict:
    """``/proc/meminfo``'s figures in bytes (empty where it cannot be read).  Read as UTF-8
    (it is ASCII): that codec is loaded at start-up, where ``ascii`` would be imported by a
    run's first call (~0.4 ms)."""
    out = {}
    try:
        with open("/proc/meminfo", encoding="utf-8") as f:
            for line in f:
                parts = line.split()
                if len(parts) >= 2 and parts[1].isdigit():
                    out[parts[0].rstrip(":")] = int(parts[1]) * (1024 if parts[2:3] == ["kB"]
                                                                else 1)
    except (OSError, UnicodeDecodeError):
        pass
    return out


def human_bytes(n: float) -> str:
    """1536 -> '1.5 KiB' (binary units)."""
    n = float(n)
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if abs(n) < 1024 or unit == "PiB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.3g} {unit}"
        n /= 1024
    return f"{n:.3g} EiB"   # pragma: no cover


def fits_in_memory(n_bytes: float, available: Optional[int] = None) -> bool:
    """Whether ``n_bytes`` fits in the memory a run may use."""
    return n_bytes <= (available_memory_bytes() if available is None else available)
