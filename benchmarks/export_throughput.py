"""Export throughput: target reports (detections) per second written and read, per format.

    PYTHONPATH=. python benchmarks/export_throughput.py [--dwells 2000] [--detections 200000]

Synthetic tables (formats.synthetic) of N detections in M dwells; each figure is the best of
--repeat runs (wall clock, in memory: encode_* / read_* on bytes, no disk I/O).
Targets for STANAG 4607 on a 2-core machine: >= 1,000,000 reports/s written, >= 500,000/s read.
"""
from __future__ import annotations

import argparse
import platform
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from gmtiflow.formats import csvtable, geojson, stanag4607, synthetic, xmldoc  # noqa: E402


def best(fn, repeat):
    times = []
    out = None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--dwells", type=int, default=2000)
    ap.add_argument("--detections", type=int, default=200_000)
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args(argv)
    dwells, dets = synthetic.tables(a.dwells, a.detections, seed=1)
    meta = {"epoch_utc": synthetic.EPOCH_UTC}
    n = a.detections
    small_dw, small_det = synthetic.tables(20, 200)
    stanag4607.read_4607(stanag4607.encode_4607(small_dw, small_det, meta))   # warm-up
    print(f"# {n} detections in {a.dwells} dwells; python {platform.python_version()}, "
          f"{platform.machine()}; best of {a.repeat}")
    print(f"{'format':<10} {'bytes':>12} {'write/s':>12} {'read/s':>12}")
    cases = [
        ("4607", lambda: stanag4607.encode_4607(dwells, dets, meta), stanag4607.read_4607),
        ("4607-41", lambda: stanag4607.encode_4607(dwells, dets, meta, edition="41"), stanag4607.read_4607),
        ("xml", lambda: xmldoc.encode_xml(dwells, dets, meta), xmldoc.read_xml),
        ("csv", lambda: csvtable.encode_csv(dets, "detections", epoch_utc=meta["epoch_utc"]),
         lambda b: csvtable.read_csv(b, "detections")),
        ("geojson", lambda: geojson.encode_geojson(detections=dets, epoch_utc=meta["epoch_utc"]),
         geojson.read_geojson),
    ]
    for name, write, read in cases:
        repeat = a.repeat if name.startswith("4607") else 1
        tw, data = best(write, repeat)
        tr, _ = best(lambda: read(data), repeat)
        print(f"{name:<10} {len(data):>12,d} {n / tw:>12,.0f} {n / tr:>12,.0f}")


if __name__ == "__main__":
    main()
