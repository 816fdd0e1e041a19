"""Throughput of the evaluation stage.

1. OSPA/GOSPA over 100 truths x 100 tracks x 1,000 steps (target < 2 s on a 2-core machine):
   one ``linear_sum_assignment`` per step on a broadcast cost matrix.
2. The whole ``evaluate`` stage on the same sizes (OSPA/GOSPA + identity association + errors).
3. The baseline tracker on 100 vehicles x 100 revisits (one dwell per revisit, light clutter).
4. ``--scaling``: issue 18's targets.  The tracker on straight-road scenes of 10, 1k, 3k and
   10k vehicles (60 revisits of 14 beams, 840 dwells; vehicles 300 m apart, so the plots per
   dwell grow with the vehicles) and ``evaluate()`` on 300, 1k, 3k and 10k truths x as many
   tracks x 60 steps at a fixed density (1 per km², the box grows with them): CPU seconds
   (best of 2), the per-dwell cost at 10 vehicles (the fixed cost) and the log-log slopes
   (target <= 1.1 from 1k to 10k, fixed cost <= 0.2 ms per dwell).  CPU time, not wall
   time: the development machine is shared.
5. ``--run RUN.h5``: the tracker stage (``track()``) and the metrics (``evaluate()``) as the
   pipeline runs them, on the /detections, /dwells, /truth, /looks ... of a stored run (e.g. the
   issue-18 1,000-vehicle scene made with ``report=none export=none``): CPU and wall seconds,
   median of ``--repeats``, the load printed with each.

Run:  PYTHONPATH=. python benchmarks/metrics_throughput.py [--scaling | --run RUN.h5]
"""
from __future__ import annotations

import argparse
import math
import os
import platform
import time

import numpy as np

from gmtiflow.evaluate import align, ospa
from gmtiflow.evaluate.config import MetricsConfig, TrackerConfig
from gmtiflow.evaluate.stage import evaluate, summary_value
from gmtiflow.evaluate.synthetic import straight_scene
from gmtiflow.evaluate.tracker import track


def best_of(fn, repeats=3, clock=time.perf_counter):
    times = []
    for _ in range(repeats):
        t0 = clock()
        result = fn()
        times.append(clock() - t0)
    return min(times), result


def slope(sizes, seconds) -> float:
    """The log-log slope between the first and the last size."""
    return math.log(seconds[-1] / seconds[0]) / math.log(sizes[-1] / sizes[0])


def scaling() -> None:
    cpu = time.process_time
    sizes, secs = (10, 1000, 3000, 10000), []
    for n in sizes:
        scene = straight_scene(n_vehicles=n, n_revisits=60, revisit_s=5.0, spacing_m=300.0,
                               n_beams=14, seed=1)
        n_dw, n_det = len(scene["dwells"]["dwell_id"]), len(scene["detections"]["dwell_id"])
        sec, _ = best_of(lambda: track(TrackerConfig(), scene["detections"], scene["dwells"]),
                         repeats=2, clock=cpu)
        secs.append(sec)
        print(f"tracker {n:6d} vehicles: {n_dw} dwells, {n_det:7d} detections: {sec:7.3f} s CPU "
              f"({1e3 * sec / n_dw:.3f} ms per dwell)")
    print(f"tracker log-log slope 1k -> 10k vehicles: {slope(sizes[1:], secs[1:]):.2f} "
          f"(target <= 1.1); per-dwell cost at 10 vehicles {1e3 * secs[0] / n_dw:.3f} ms "
          f"(target <= 0.2 ms)")
    sizes, secs = (300, 1000, 3000, 10000), []
    for n in sizes:
        # a fixed density: 1 vehicle per km², as in the 100-truth case above
        _, truth, tracks = random_tables(n, n, 60, extent_m=10000.0 * math.sqrt(n / 100))
        sec, _ = best_of(lambda: evaluate(MetricsConfig(), truth, tracks), repeats=2, clock=cpu)
        secs.append(sec)
        print(f"evaluate() {n:5d} truths x {n} tracks x 60 steps: {sec:7.3f} s CPU")
    print(f"evaluate() log-log slope 1k -> 10k truths: {slope(sizes[1:], secs[1:]):.2f} "
          f"(target <= 1.1)")


def run_file(path: str, repeats: int) -> None:
    """track() and evaluate() on a stored run, as gmtiflow.stages runs them."""
    from gmtiflow import frames
    from gmtiflow.store import open_run, read_table
    with open_run(path) as f:
        attrs = dict(f.attrs)
        tables = {n: dict(read_table(f, n)) for n in ("detections", "dwells", "truth", "looks",
                                                      "vehicles", "platform")}
    origin = frames.Origin(float(attrs["origin_lat_deg"]), float(attrs["origin_lon_deg"]),
                           float(attrs.get("origin_height_m", 0.0)))
    first = np.asarray(tables["platform"]["sensor_id"]) == 0
    plat = {c: np.asarray(v)[first] for c, v in tables["platform"].items()}
    last_dwell_s = float(np.max(tables["dwells"]["time_s"]))
    print(f"{path}: {len(tables['dwells']['dwell_id'])} dwells, "
          f"{len(tables['detections']['dwell_id'])} detections, "
          f"{len(tables['truth']['time_s'])} truth samples")
    times = {"track": [], "evaluate": []}
    for _ in range(repeats):
        load = os.getloadavg()[0]
        c0, w0 = time.process_time(), time.perf_counter()
        tracks = track(TrackerConfig(), tables["detections"], tables["dwells"],
                       int(attrs.get("seed", 0)), origin=origin,
                       epoch_utc=str(attrs.get("scene_epoch_utc")),
                       duration_s=float(attrs.get("scene_duration_s", 0.0)))
        c1, w1 = time.process_time(), time.perf_counter()
        evaluate(MetricsConfig(), tables["truth"], tracks, tables["looks"], tables["vehicles"],
                 plat, origin=origin, until_s=last_dwell_s)
        c2, w2 = time.process_time(), time.perf_counter()
        times["track"].append((c1 - c0, w1 - w0))
        times["evaluate"].append((c2 - c1, w2 - w1))
        print(f"  track {c1 - c0:6.3f} s CPU ({w1 - w0:6.3f} s wall, "
              f"{1e3 * (c1 - c0) / len(tables['dwells']['dwell_id']):.3f} ms per dwell), "
              f"evaluate {c2 - c1:6.3f} s CPU ({w2 - w1:6.3f} s wall); load {load:.1f}")
    for name, got in times.items():
        print(f"{name}: median {np.median([c for c, _ in got]):.3f} s CPU, "
              f"{np.median([w for _, w in got]):.3f} s wall over {repeats} runs")


def random_tables(n_truth=100, n_tracks=100, n_steps=1000, seed=0, extent_m=10000.0):
    rng = np.random.default_rng(seed)
    grid = np.arange(float(n_steps))
    pos0 = rng.uniform(0, extent_m, (n_truth, 2))
    vel = rng.normal(0, 10, (n_truth, 2))
    tt = np.repeat(grid, n_truth)
    vid = np.tile(np.arange(n_truth), n_steps)
    truth = {"time_s": tt, "vehicle_id": vid, "x_m": pos0[vid, 0] + vel[vid, 0] * tt,
             "y_m": pos0[vid, 1] + vel[vid, 1] * tt, "vx_mps": vel[vid, 0],
             "vy_mps": vel[vid, 1], "mode": np.zeros(len(tt), np.uint8)}
    # tracks: noisy copies of the truths, ids that change now and then
    tid = vid + 1000 * (tt // 250).astype(np.int64)
    tracks = {"track_id": tid, "time_s": tt, "x_m": truth["x_m"] + rng.normal(0, 20, len(tt)),
              "y_m": truth["y_m"] + rng.normal(0, 20, len(tt)), "vx_mps": truth["vx_mps"],
              "vy_mps": truth["vy_mps"]}
    return grid, truth, tracks


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scaling", action="store_true", help="the issue-18 scaling figures")
    ap.add_argument("--run", metavar="RUN.h5", help="time track() and evaluate() on a run file")
    ap.add_argument("--repeats", type=int, default=3, help="with --run (median)")
    args = ap.parse_args()
    print(f"python {platform.python_version()}, numpy {np.__version__}, "
          f"{platform.processor() or platform.machine()}, load average "
          f"{' / '.join(f'{x:.1f}' for x in os.getloadavg())}")
    if args.scaling:
        scaling()
        return
    if args.run:
        run_file(args.run, args.repeats)
        return
    grid, truth, tracks = random_tables()
    cfg = MetricsConfig()
    truth_at = align.truth_at_grid(truth, grid)
    tracks_at = align.tracks_at_grid(tracks, grid, cfg.max_extrapolation_s, cfg.track_end_hold_s)
    secs, _ = best_of(lambda: ospa.series(truth_at, tracks_at, grid, cfg.cutoff_m, cfg.order_p))
    print(f"OSPA+GOSPA 100 truths x 100 tracks x 1000 steps: {secs:.3f} s "
          f"({1000 / secs:.0f} steps/s)")
    secs, out = best_of(lambda: evaluate(cfg, truth, tracks), repeats=2)
    print(f"evaluate() whole stage, same sizes:               {secs:.3f} s "
          f"(identity switches: {summary_value(out, 'identity_switches'):.0f}; the tables plant "
          f"300 id changes)")

    scene = straight_scene(n_vehicles=100, n_revisits=100, revisit_s=2.0, spacing_m=300.0,
                           clutter_per_dwell=20.0, clutter_half_width_m=20000.0, seed=1)
    n_det = len(scene["detections"]["dwell_id"])
    secs, tr = best_of(lambda: track(TrackerConfig(), scene["detections"], scene["dwells"]),
                       repeats=2)
    print(f"baseline tracker 100 vehicles x 100 revisits ({n_det} detections incl. clutter): "
          f"{secs:.3f} s ({n_det / secs:.0f} detections/s, {100 / secs:.0f} dwells/s), "
          f"{len(np.unique(tr['track_id'][tr['confirmed']]))} confirmed tracks")


if __name__ == "__main__":
    main()
