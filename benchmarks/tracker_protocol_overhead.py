"""Per-dwell overhead of the tracker protocol (issue 13), on a 1,000-vehicle simulated scene.

The baseline tracker runs through the protocol exactly as the pipeline runs it
(:func:`gmtiflow.evaluate.tracker.track`: blind batches, one per dwell, reports collected and
validated).  A proxy around the tracker times what happens *inside* its ``reset/update/finish``
(the tracker's own time); the rest of ``track()`` is the protocol's overhead: sorting the tables
into batches once, slicing one batch per dwell, concatenating and checking the reports.
Target: overhead < 10 % of the tracker's own time.

Run:  PYTHONPATH=. python benchmarks/tracker_protocol_overhead.py [--vehicles 1000]
      [--duration-s 600]
The scene is simulated once (tracker, metrics, exports and report off); prints the load.
"""
from __future__ import annotations

import argparse
import os
import tempfile
import time

import numpy as np

from gmtiflow import frames, pipeline, store
from gmtiflow.compose import compose
from gmtiflow.evaluate.config import TrackerConfig
from gmtiflow.evaluate import tracker as tracker_mod
from gmtiflow.evaluate.protocol import _Prepared


class Timed:
    """Wraps a tracker and adds up the time spent inside its three methods."""

    def __init__(self, inner):
        self.inner, self.inside_s, self.calls = inner, 0.0, 0

    def _timed(self, name, *args):
        t0 = time.perf_counter()
        out = getattr(self.inner, name)(*args)
        self.inside_s += time.perf_counter() - t0
        self.calls += 1
        return out

    def reset(self, scene):
        return self._timed("reset", scene)

    def update(self, batch):
        return self._timed("update", batch)

    def finish(self):
        return self._timed("finish")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vehicles", type=int, default=1000)
    ap.add_argument("--duration-s", type=float, default=600.0)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    print(f"load average {os.getloadavg()[0]:.1f} {os.getloadavg()[1]:.1f} (1, 5 min)")
    with tempfile.TemporaryDirectory() as tmp:
        cfg = compose(["vehicles=random", f"vehicles.random.count={args.vehicles}",
                       f"scene.duration_s={args.duration_s}", "tracker=none",
                       "metrics.enabled=false", "export=none", "report=none",
                       "progress=false", "cache.enabled=false"])
        run = pipeline.run(cfg, tmp)
        det, dw = store.read_table(run, "detections"), store.read_table(run, "dwells")
        with store.open_run(run) as f:
            origin = frames.Origin(float(f.attrs["origin_lat_deg"]),
                                   float(f.attrs["origin_lon_deg"]),
                                   float(f.attrs["origin_height_m"]))
    print(f"scene: {args.vehicles} vehicles, {args.duration_s:g} s, {len(dw['dwell_id'])} dwells, "
          f"{len(det['det_id'])} detections")
    made = []
    real_make = tracker_mod.make_tracker

    def make(cfg):
        t = Timed(real_make(cfg))
        made.append(t)
        return t

    tracker_mod.make_tracker = make
    rows = []
    try:
        for _ in range(args.repeats):
            made.clear()
            t0 = time.perf_counter()
            tracks = tracker_mod.track(TrackerConfig(), det, dw, origin=origin)
            total = time.perf_counter() - t0
            rows.append((total, made[0].inside_s))
    finally:
        tracker_mod.make_tracker = real_make
    t0 = time.perf_counter()
    prep = _Prepared(det, dw, origin, "dwell")
    n = sum(1 for _ in prep)
    batching = time.perf_counter() - t0
    total, inside = min(rows, key=lambda r: r[0])
    over = total - inside
    print(f"tracks: {len(np.unique(tracks['track_id']))} ids, {len(tracks['track_id'])} rows")
    print(f"track() total {total:.3f} s; inside the tracker {inside:.3f} s; protocol overhead "
          f"{over:.3f} s = {100 * over / inside:.1f} % of the tracker's own time "
          f"({1e6 * over / max(n, 1):.1f} us per dwell; batching alone {batching:.3f} s for "
          f"{n} batches)  [best of {args.repeats}]")


if __name__ == "__main__":
    main()
