"""STANAG 4607 reader throughput on many small packets (issue 17: it must stay linear).

    PYTHONPATH=. python benchmarks/read_4607_throughput.py [--packets 1000000] [--repeat 3]

A file of N empty 32-byte packets (header only, no segment: the worst case per byte) and one
of N/10 Mission packets, read with ``formats.read_4607`` from bytes.  Prints the packets per
second of wall-clock and of CPU time (the CPU figure is the one to compare on a shared,
loaded machine), best of --repeat, and the ratio of the per-packet time at N and N/10, which
is about 1 for a linear reader.
"""
from __future__ import annotations

import argparse
import os
import platform
import struct
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from gmtiflow.formats import stanag4607  # noqa: E402


def empty_packets(n: int) -> bytes:
    return struct.pack(">2sI2sB2sHB10sII", b"30", 32, b"XN", 5, b"XN", 0, 129,
                       b"GMTIFLOW  ", 1, 0) * n


def mission_packets(n: int) -> bytes:
    body = struct.pack(">BI12s12sB10sHBB", 1, 44, b"PLAN".ljust(12), b"".ljust(12), 255,
                       b"".ljust(10), 2026, 11, 23)
    head = struct.pack(">2sI2sB2sHB10sII", b"30", 32 + len(body), b"XN", 5, b"XN", 0, 129,
                       b"GMTIFLOW  ", 1, 0)
    return (head + body) * n


def best(fn, repeat):
    wall, cpu = [], []
    for _ in range(repeat):
        w, c = time.perf_counter(), time.process_time()
        fn()
        wall.append(time.perf_counter() - w)
        cpu.append(time.process_time() - c)
    return min(wall), min(cpu)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--packets", type=int, default=1_000_000)
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args(argv)
    print(f"# python {platform.python_version()}, {platform.machine()}, load "
          f"{os.getloadavg()[0]:.1f}; best of {a.repeat}")
    print(f"{'file':<28} {'packets':>10} {'MB':>7} {'wall/s':>12} {'cpu/s':>12}")
    per_packet = {}
    for name, make, n in (("empty packets", empty_packets, a.packets // 10),
                          ("empty packets", empty_packets, a.packets),
                          ("mission packets", mission_packets, a.packets // 10)):
        data = make(n)
        wall, cpu = best(lambda: stanag4607.decode_4607(data), a.repeat)
        per_packet[(name, n)] = cpu / n
        print(f"{name:<28} {n:>10,d} {len(data) / 1e6:>7.1f} {n / wall:>12,.0f} {n / cpu:>12,.0f}")
    ratio = per_packet[("empty packets", a.packets)] / per_packet[("empty packets", a.packets // 10)]
    print(f"cpu time per packet at {a.packets:,d} / at {a.packets // 10:,d}: {ratio:.2f} "
          "(1 = linear)")


if __name__ == "__main__":
    main()
