"""An "external" tracker for the benchmark tests: a separate process that reads only the blind
inputs ``gmtiflow-bench --command`` gives it and writes a track CSV.  Inside it runs the
baseline NN-Kalman tracker, so its scores must equal the in-process ``tracker=nn_kalman`` job's.

    python command_tracker.py DETECTIONS.csv DWELLS.csv SCENE.json TRACKS.csv
"""
import csv
import json
import sys

import numpy as np

from gmtiflow import formats, frames
from gmtiflow.evaluate import track
from gmtiflow.evaluate.config import TrackerConfig


def read_plain_csv(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    head, body = rows[0], rows[1:]
    out = {}
    for i, name in enumerate(head):
        col = [r[i] for r in body]
        if col and col[0] in ("True", "False"):
            out[name] = np.array([c == "True" for c in col])
        else:
            out[name] = np.array(col, dtype=float)
    for name in ("dwell_id", "revisit_id", "dwell_index"):
        if name in out:
            out[name] = out[name].astype(np.int64)
    return out


def main(det_path, dwell_path, scene_path, tracks_path):
    det = formats.read_detections_csv(det_path)
    forbidden = [c for c in det if c == "truth_id" or c.startswith("true_") or c == "merged"]
    if forbidden:
        sys.exit(f"the blind detections carry truth: {forbidden}")
    dwells = read_plain_csv(dwell_path)
    scene = json.loads(open(scene_path).read())
    origin = frames.Origin(scene["origin_lat_deg"], scene["origin_lon_deg"],
                           scene["origin_height_m"])
    tracks = track(TrackerConfig(), det, dwells, 0, origin=origin)
    formats.write_tracks_csv(tracks_path, {k: v for k, v in tracks.items()
                                           if k in formats.csvtable.COLUMNS["tracks"]},
                             epoch_utc=scene["scene_epoch_utc"])


if __name__ == "__main__":
    main(*sys.argv[1:5])
