"""experiment=two_orbits: what fusing two stand-off orbits 90° apart buys, and what it costs.

Runs the scene three times (stage cache off): each sensor alone (as the only sensor, with the
same name, hence the same draws as in the fused run) and both together, and prints

* wall time of ``pipeline.run`` per case, and the fused run's time over the sum of the two
  single-sensor runs (cost linear in the number of sensors: about 1);
* per sensor and fused, from ``/metrics/sensors`` (``gmtiflow.coverage``): detection coverage,
  detection gaps, Doppler-blind gaps and their total span;
* per run, from ``/metrics`` (the baseline tracker on that run's detections): track coverage
  (``coverage_mean``), Doppler-blind events and OSPA.

    python benchmarks/two_orbits.py [--seeds 1 2 3] [--repeat 1] [extra overrides ...]

Speeds depend on the machine's load, which is printed.
"""
from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path


from gmtiflow import pipeline
from gmtiflow.compose import compose
from gmtiflow.config import sensor_slots
from gmtiflow.evaluate.stage import summary_value
from gmtiflow.store import read_table

BASE = ["experiment=two_orbits", "progress=false", "cache.enabled=false", "export=none",
        "report.enabled=false"]


def alone(cfg, name):
    """The scene with sensor ``name`` as its only sensor (same name: same random streams)."""
    slot = {s.name: s for s in sensor_slots(cfg)}[name]
    cfg.platform, cfg.sensor, cfg.sensor_name, cfg.sensors = slot.platform, slot.sensor, name, {}
    return cfg


def timed_run(cfg, out: Path, repeat: int):
    best = float("inf")
    for _ in range(repeat):
        start = time.perf_counter()
        path = pipeline.run(cfg, out)
        best = min(best, time.perf_counter() - start)
    return path, best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[1])
    ap.add_argument("--repeat", type=int, default=1, help="runs per case; the fastest counts")
    ap.add_argument("overrides", nargs="*")
    args = ap.parse_args()
    print(f"load average at start: {os.getloadavg()[0]:.1f} ({os.cpu_count()} cores)")
    with tempfile.TemporaryDirectory() as tmp:
        for seed in args.seeds:
            overrides = BASE + [f"seed={seed}", *args.overrides]
            names = [s.name for s in sensor_slots(compose(overrides))]
            cases = {f"{n} alone": alone(compose(overrides), n) for n in names}
            cases["fused"] = compose(overrides)
            seconds, rows, tracked = {}, {}, {}
            for case, cfg in cases.items():
                path, seconds[case] = timed_run(cfg, Path(tmp) / case.replace(" ", "_"),
                                                args.repeat)
                table = read_table(path, "metrics/sensors")
                metrics = {"metrics": read_table(path, "metrics")}
                tracked[case] = [summary_value(metrics, k) for k in
                                 ("coverage_mean", "doppler_blind_events", "ospa_mean_m")]
                if case == "fused":
                    rows = {str(n): i for i, n in enumerate(table["name"])}
                    sensors = table
            print(f"\nseed {seed}: {' + '.join(names)}, scene "
                  f"{cases['fused'].scene.duration_s:g} s, "
                  f"{len(read_table(path, 'vehicles')['vehicle_id'])} vehicles")
            print(f"{'':14s}{'det. coverage':>14s}{'det. gaps':>10s}{'Doppler gaps':>13s}"
                  f"{'gap span s':>11s}")
            for name, i in rows.items():
                print(f"{name:14s}{sensors['detection_coverage'][i]:14.3f}"
                      f"{sensors['detection_gaps'][i]:10d}{sensors['doppler_blind_gaps'][i]:13d}"
                      f"{sensors['doppler_blind_gap_s'][i]:11.1f}")
            print(f"{'run':14s}{'wall s':>8s}{'track coverage':>16s}{'Doppler events':>16s}"
                  f"{'OSPA m':>8s}")
            for case in cases:
                cov, blind, ospa = tracked[case]
                print(f"{case:14s}{seconds[case]:8.2f}{cov:16.3f}{blind:16.0f}{ospa:8.1f}")
            single = sum(v for k, v in seconds.items() if k != "fused")
            print(f"fused / (sum of the single-sensor runs) = {seconds['fused'] / single:.2f}")
    print(f"\nload average at end: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
