"""Trackers a user might write, loaded by import path in tests (``tracker.target=...``)."""
import json

from gmtiflow.evaluate.protocol import TRUTH_DETECTION_COLUMNS
from gmtiflow.evaluate.tracker import NNKalmanTracker


class RecordingTracker:
    """The baseline behind a user's class: logs what it was fed to ``log_path`` (JSON)."""

    def __init__(self, log_path, confirm_m=3):
        self.log_path = log_path
        self.inner = NNKalmanTracker(confirm_m=confirm_m)
        self.seen = None

    def reset(self, scene):
        self.inner.reset(scene)
        self.seen = {"reset": 1, "origin": scene.origin is not None, "n_dwells": scene.n_dwells,
                     "times": [], "n_det": [], "dwell_ids": [], "columns": set(),
                     "truth_columns": set(), "finished": 0}

    def update(self, batch):
        s = self.seen
        s["times"] += batch.dwells["time_s"].tolist()
        s["dwell_ids"] += batch.dwells["dwell_id"].tolist()
        s["n_det"].append(batch.n_detections)
        s["columns"] |= set(batch.detections)
        s["truth_columns"] |= set(batch.detections) & set(TRUTH_DETECTION_COLUMNS)
        return self.inner.update(batch)

    def finish(self):
        self.seen["finished"] += 1
        with open(self.log_path, "w") as f:
            json.dump({k: sorted(v) if isinstance(v, set) else v
                       for k, v in self.seen.items()}, f)
        return self.inner.finish()


class FailsAtDwell:
    """Raises inside ``update`` at its ``n``-th batch (a bug in the user's code)."""

    def __init__(self, n=3):
        self.n, self.k = n, 0

    def reset(self, scene):
        self.k = 0

    def update(self, batch):
        self.k += 1
        if self.k == self.n:
            return {"track_id": [0]}["x_m"]      # KeyError: the user's bug
        return None

    def finish(self):
        return None


class PlotTracker:
    """Each detection becomes a one-row confirmed track (position only), ids by det_id."""

    def reset(self, scene):
        pass

    def update(self, batch):
        d = batch.detections
        return {"track_id": d["det_id"], "x_m": d["x_m"], "y_m": d["y_m"]}

    def finish(self):
        return None


class NoUpdate:
    def reset(self, scene):
        pass

    def finish(self):
        return None
