"""Export throughput: target reports (detections) per second written and read, per format.

    PYTHONPATH=. python benchmarks/export_throughput.py [--dwells 2000] [--detections 200000]
    PYTHONPATH=. python benchmarks/export_throughput.py --against bf41938   # 4607 writer A/B
    PYTHONPATH=. python benchmarks/export_throughput.py --text-against fb27d3a --ab-runs 3

Synthetic tables (formats.synthetic) of N detections in M dwells; each figure is the best of
--repeat runs, in memory (encode_* / read_* on bytes, no disk I/O), timed in CPU time of this
process (``time.process_time``: on a shared machine the wall clock measures the other jobs too;
the code is single-threaded, so on an idle core the two agree).  For the text
formats it also prints *values* per second written (and, for ``truth-csv`` and ``truth-geo``,
a /truth table of as many samples as detections: rows/s instead of reports/s): the table cells formatted (rows x columns
of the detections, plus the dwells' cells for XML), the unit of issue 18's "text exports
>= 1 M values/s".  Targets on a 2-core machine: STANAG 4607 >= 1,000,000 reports/s written,
>= 500,000/s read; XML, CSV and GeoJSON >= 1,000,000 values/s written.

``--against REV`` compares the 4607 writer with the one of git revision REV (its ``formats``
package is extracted to a temporary directory): A and B alternate, --ab-runs times each, and
the medians of their CPU times give the ratio.  The machine's load average is printed first.

``--run RUN.h5 --against REV`` times the export stage's own files of a real run instead
(``gmtiflow.export.write_format`` of every file ``export=all`` writes, truth.csv included,
tracks.geojson left out: older writers have none), today's writers against REV's, alternating::

    python benchmarks/export_throughput.py --run outputs/x/run.h5 --against 011254f --ab-runs 3

``--run RUN.h5 --stage`` times the export stage itself as the pipeline runs it
(``gmtiflow.export.export_run`` with the default export config: 4607, XML, detections/dwells/
tracks CSV, scene/truth/tracks GeoJSON), each time in a fresh process (module imports before
the clock, lazy imports of the writers inside it, as in a run); with ``--against REV`` it
alternates with REV's code (``git archive``) and checks that both wrote the same bytes::

    python benchmarks/export_throughput.py --run outputs/x/run.h5 --stage --against main --ab-runs 3
"""
from __future__ import annotations

import argparse
import importlib
import os
import platform
import subprocess
import sys
import tarfile
import tempfile
import time
from io import BytesIO
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from gmtiflow.formats import csvtable, geojson, stanag4607, synthetic, xmldoc  # noqa: E402


def best(fn, repeat):
    times = []
    out = None
    for _ in range(repeat):
        t0 = time.process_time()
        out = fn()
        times.append(time.process_time() - t0)
    return min(times), out


def load_reference(rev: str, tmp: Path, module: str = "stanag4607"):
    """A module of the ``formats`` package of git revision ``rev``, importable beside today's."""
    data = subprocess.run(["git", "-C", str(ROOT), "archive", rev, "formats"],
                          capture_output=True, check=True).stdout
    with tarfile.open(fileobj=BytesIO(data)) as tar:
        tar.extractall(tmp, filter="data")
    (tmp / "formats").rename(tmp / "formats_reference")
    sys.path.insert(0, str(tmp))
    return importlib.import_module("formats_reference" + (f".{module}" if module else ""))


def run_file_ab(run_path: Path, rev: str, runs: int) -> None:
    """The export stage's files of ``run_path``: today's writers against ``rev``'s."""
    from gmtiflow import export, formats as today
    cfg = export.ExportConfig(csv_tables=list(export.CSV_TABLES), geojson_tracks=False)
    run = export.load_run(run_path)
    names = ("write_4607", "write_xml", "write_csv", "write_geojson")
    mine = {k: getattr(today, k) for k in names}
    print(f"# {run_path}: {len(run.tables['detections']['det_id']):,} detections, "
          f"{len(run.tables['truth']['time_s']):,} truth samples; {runs} alternating runs, "
          f"median CPU time")
    print(f"{'file':<16} {'bytes':>12} {'reference s':>12} {'today s':>10} {'speed-up':>9}")
    with tempfile.TemporaryDirectory() as tmp:
        ref = load_reference(rev, Path(tmp), module="")
        theirs = {k: getattr(ref, k) for k in names}
        for fmt, name in export.planned_files(cfg):
            cpu = {"ref": [], "today": []}
            for _ in range(runs):
                for label, writers in (("ref", theirs), ("today", mine)):
                    for k, f in writers.items():
                        setattr(today, k, f)
                    try:
                        t0 = time.process_time()
                        export.write_format(fmt, run, cfg, Path(tmp) / name)
                        cpu[label].append(time.process_time() - t0)
                    finally:
                        for k, f in mine.items():
                            setattr(today, k, f)
            a, b = np.median(cpu["ref"]), np.median(cpu["today"])
            size = (Path(tmp) / name).stat().st_size
            print(f"{name:<16} {size:>12,d} {a:>12.2f} {b:>10.2f} {a / b:>8.1f}x")


_STAGE = """
import json, os, resource, sys, time
from pathlib import Path
if sys.argv[1]:
    sys.path.insert(0, sys.argv[1])
from gmtiflow import export
t0, c0 = time.perf_counter(), time.process_time()
export.export_run(export.ExportConfig(), sys.argv[2], sys.argv[3])
print(json.dumps({"wall": time.perf_counter() - t0, "cpu": time.process_time() - c0,
                  "maxrss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                  "module": export.__file__}))
"""


def reference_tree(rev: str, tmp: Path) -> Path:
    """gmtiflow (with its formats and conf packages) of git revision ``rev``, importable."""
    data = subprocess.run(["git", "-C", str(ROOT), "archive", rev, "gmtiflow", "formats", "conf"],
                          capture_output=True, check=True).stdout
    with tarfile.open(fileobj=BytesIO(data)) as tar:
        tar.extractall(tmp, filter="data")
    (tmp / "gmtiflow" / "formats").symlink_to(tmp / "formats")
    (tmp / "gmtiflow" / "conf").symlink_to(tmp / "conf")
    return tmp


def stage_ab(run_path: Path, rev, runs: int) -> None:
    """The export stage of ``run_path`` in fresh processes: today's code (and REV's)."""
    import json
    import filecmp
    with tempfile.TemporaryDirectory() as tmp:
        trees = {"today": ""}
        if rev:
            trees[f"reference {rev}"] = str(reference_tree(rev, Path(tmp) / "ref"))
        got = {k: [] for k in trees}
        for _ in range(runs):
            for label, tree in trees.items():
                out = Path(tmp) / label.replace(" ", "_")
                res = subprocess.run([sys.executable, "-c", _STAGE, tree, str(run_path), str(out)],
                                     capture_output=True, text=True, check=True)
                r = json.loads(res.stdout.strip().splitlines()[-1])
                assert (tree or str(ROOT)) in r["module"], r["module"]
                got[label].append(r)
                print(f"  {label:<20} wall {r['wall']:5.2f} s  CPU {r['cpu']:5.2f} s  "
                      f"max RSS {r['maxrss_mb']:6.0f} MB  load {os.getloadavg()[0]:.2f}")
        for label, rs in got.items():
            print(f"{label:<22} median wall {np.median([r['wall'] for r in rs]):.2f} s, "
                  f"CPU {np.median([r['cpu'] for r in rs]):.2f} s")
        if rev:
            a, b = (Path(tmp) / k.replace(" ", "_") for k in trees)
            names = sorted(p.name for p in a.iterdir())
            same = all(filecmp.cmp(a / nm, b / nm, shallow=False) for nm in names)
            print(f"files {'identical' if same else 'DIFFER'}: {', '.join(names)}")
            c = [np.median([r["cpu"] for r in rs]) for rs in got.values()]
            print(f"CPU speed-up today vs {rev}: {c[1] / c[0]:.2f}x")


def ab_text(rev: str, cases, runs: int) -> None:
    """The text writers' values/s, today's against REV's (same tables, alternating runs)."""
    names = {"xml": "xmldoc", "csv": "csvtable", "geojson": "geojson", "truth-csv": "csvtable",
             "truth-geo": "geojson"}
    today = {"xmldoc": xmldoc, "csvtable": csvtable, "geojson": geojson}
    with tempfile.TemporaryDirectory() as tmp:
        ref = load_reference(rev, Path(tmp), module="")
        print(f"\ntext writers A/B against {rev}, {runs} alternating runs (median CPU time):")
        print(f"{'format':<10} {'reference values/s':>19} {'today values/s':>15} {'speed-up':>9}")
        for name, _, _, cells in cases:
            if name not in names:
                continue
            mod = names[name]
            ref_mod = importlib.import_module(f"{ref.__name__}.{mod}")
            cpu = {"ref": [], "today": []}
            for _ in range(runs):
                for label, m in (("ref", ref_mod), ("today", today[mod])):
                    write = _TEXT_WRITES[name](m)
                    t0 = time.process_time()
                    write()
                    cpu[label].append(time.process_time() - t0)
            a, b = np.median(cpu["ref"]), np.median(cpu["today"])
            print(f"{name:<10} {cells / a:>19,.0f} {cells / b:>15,.0f} {a / b:>8.2f}x")


_TEXT_WRITES: dict = {}


def ab_4607(rev: str, dwells, dets, meta, runs: int) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        ref = load_reference(rev, Path(tmp))
        # before D32.7 had its own column, the writer put range_rate_mps into D32.7
        ref_dets = {k: v for k, v in dets.items() if k != "los_velocity_mps"}
        ref_dets["range_rate_mps"] = dets["los_velocity_mps"]
        cases = (("reference " + rev, ref, ref_dets), ("today", stanag4607, dets))
        for _, mod, d in cases:
            mod.encode_4607(dwells, d, meta)                          # warm-up
        cpu = {name: [] for name, _, _ in cases}
        for _ in range(runs):
            for name, mod, d in cases:
                t0 = time.process_time()
                mod.encode_4607(dwells, d, meta)
                cpu[name].append(time.process_time() - t0)
    n = len(dets["det_id"])
    print(f"\n4607 writer A/B, {runs} alternating runs each (median CPU time):")
    for name, t in cpu.items():
        print(f"  {name:<20} {np.median(t) * 1e3:8.1f} ms  {n / np.median(t) / 1e6:6.2f} M reports/s")
    a, b = (np.median(t) for t in cpu.values())
    print(f"  today / reference speed: {a / b:.2f}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--dwells", type=int, default=2000)
    ap.add_argument("--detections", type=int, default=200_000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--against", metavar="REV", help="A/B the 4607 writer with git revision REV")
    ap.add_argument("--ab-runs", type=int, default=9)
    ap.add_argument("--run", type=Path, metavar="RUN.h5",
                    help="with --against: time the export stage's files of this run file")
    ap.add_argument("--text-against", metavar="REV",
                    help="A/B the XML, CSV and GeoJSON writers with those of git revision REV")
    ap.add_argument("--stage", action="store_true",
                    help="with --run: time the whole export stage in fresh processes")
    a = ap.parse_args(argv)
    if a.run is not None and a.stage:
        print(f"# load average {os.getloadavg()[0]:.2f} ({os.cpu_count()} CPUs); export stage "
              f"of {a.run}, {a.ab_runs} alternating runs")
        stage_ab(a.run, a.against, a.ab_runs)
        return
    if a.run is not None:
        if not a.against:
            ap.error("--run needs --against REV")
        print(f"# load average {os.getloadavg()[0]:.2f} ({os.cpu_count()} CPUs)")
        run_file_ab(a.run, a.against, a.ab_runs)
        return
    dwells, dets = synthetic.tables(a.dwells, a.detections, seed=1)
    meta = {"epoch_utc": synthetic.EPOCH_UTC}
    n = a.detections
    # Warm-up at full size: the first encode of tables this big runs at about half the speed
    # of the next ones (fresh buffers' page faults), whichever edition comes first.
    stanag4607.read_4607(stanag4607.encode_4607(dwells, dets, meta))
    print(f"# load average {os.getloadavg()[0]:.2f} ({os.cpu_count()} CPUs); {n} detections in "
          f"{a.dwells} dwells; python {platform.python_version()}, {platform.machine()}; "
          f"best of {a.repeat}")
    csv_cols = [c for c in dets if c in csvtable.COLUMNS["detections"]]
    det_cells = n * (len(csv_cols) + 1)                     # + time_utc
    xml_cells = (n * len([c for c in dets if c in xmldoc.DETECTION_COLUMNS and c != "dwell_id"])
                 + a.dwells * (len([c for c in dwells if c in xmldoc.DWELL_COLUMNS]) + 1))
    geo_cells = n * (len(dets) + 1)
    print(f"{'format':<10} {'bytes':>12} {'write/s':>12} {'values/s':>12} {'read/s':>12}")
    cases = [
        ("4607", lambda: stanag4607.encode_4607(dwells, dets, meta), stanag4607.read_4607, None),
        ("4607-41", lambda: stanag4607.encode_4607(dwells, dets, meta, edition="41"),
         stanag4607.read_4607, None),
        ("xml", lambda: xmldoc.encode_xml(dwells, dets, meta), xmldoc.read_xml, xml_cells),
        ("csv", lambda: csvtable.encode_csv({c: dets[c] for c in csv_cols}, "detections",
                                            epoch_utc=meta["epoch_utc"]),
         lambda b: csvtable.read_csv(b, "detections"), det_cells),
        ("geojson", lambda: geojson.encode_geojson(detections=dets, epoch_utc=meta["epoch_utc"]),
         geojson.read_geojson, geo_cells),
    ]
    truth = synthetic.truth(max(n // 200, 1), 200, seed=1)          # n samples, 1 per vehicle-time
    n_truth = len(truth["time_s"])
    truth_cells = n_truth * len(truth)
    cases += [
        ("truth-csv", lambda: csvtable.encode_csv({c: v for c, v in truth.items()
                                                   if c in csvtable.COLUMNS["truth"]}, "truth",
                                                  epoch_utc=meta["epoch_utc"]),
         lambda b: csvtable.read_csv(b, "truth"), truth_cells),
        ("truth-geo", lambda: geojson.encode_geojson(truth=truth, epoch_utc=meta["epoch_utc"]),
         geojson.read_geojson, truth_cells),
    ]
    _TEXT_WRITES.update({
        "xml": lambda m: lambda: m.encode_xml(dwells, dets, meta),
        "csv": lambda m: lambda: m.encode_csv({c: dets[c] for c in csv_cols}, "detections",
                                              epoch_utc=meta["epoch_utc"]),
        "geojson": lambda m: lambda: m.encode_geojson(detections=dets,
                                                      epoch_utc=meta["epoch_utc"]),
        "truth-csv": lambda m: lambda: m.encode_csv(
            {c: v for c, v in truth.items() if c in csvtable.COLUMNS["truth"]}, "truth",
            epoch_utc=meta["epoch_utc"]),
        "truth-geo": lambda m: lambda: m.encode_geojson(truth=truth, epoch_utc=meta["epoch_utc"]),
    })
    for name, write, read, cells in cases:
        tw, data = best(write, a.repeat)
        tr, _ = best(lambda: read(data), 1 if cells else a.repeat)
        vals = f"{cells / tw:>12,.0f}" if cells else f"{'':>12}"
        rows = n_truth if name.startswith("truth") else n
        print(f"{name:<10} {len(data):>12,d} {rows / tw:>12,.0f} {vals} {rows / tr:>12,.0f}")
    if a.against:
        ab_4607(a.against, dwells, dets, meta, a.ab_runs)
    if a.text_against:
        ab_text(a.text_against, cases, a.ab_runs)


if __name__ == "__main__":
    main()
