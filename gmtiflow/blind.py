"""What a tracker under test may see of a run's reports: the columns, and their order.

Every path by which detections reach a tracker under test uses this module: the tracker
protocol's batches (:mod:`gmtiflow.evaluate.protocol`, so the built-in and Stone Soup trackers
too), ``gmtiflow-bench --command``'s ``detections.csv`` (:mod:`gmtiflow.bench.external`) and
``export.blind`` exports and the live stream (:func:`gmtiflow.export.blind_run`).

* **Columns**: :data:`BLIND_DETECTION_COLUMNS`, the radar's report; never the truth columns
  :data:`TRUTH_DETECTION_COLUMNS`.
* **Order**: :func:`truth_free_order`.  run.h5 numbers a dwell's reports target by target in
  vehicle id order, then its false alarms (the sensor stage's order, kept so run.h5 stays what
  it is); that order, and the ``det_id`` values that follow it, would tell a tracker which
  reports are false alarms and which vehicle is which.  A tracker sees each dwell's reports by
  measured slant range (as a processor lists range cells), with the dwell's own ``det_id``
  values handed out in that order.  No track table cites a ``det_id`` (tracks are scored by
  position against /truth), so nothing needs translating back; a report a tracker saw is found
  in run.h5 by its ``dwell_id`` and ``range_m``.
"""
from __future__ import annotations

from typing import Mapping, Optional

import numpy as np

BLIND_DETECTION_COLUMNS = (
    "det_id", "dwell_id", "sensor_id", "time_s", "range_m", "azimuth_rad", "range_rate_mps",
    "snr_db", "sigma_range_m", "sigma_azimuth_rad", "sigma_range_rate_mps", "x_m", "y_m", "z_m",
    "lat_deg", "lon_deg", "height_m", "implausible", "wrap_velocity_mps")
"""What a tracker sees of a detection (docs/tables.md /detections, less every truth column)."""

TRUTH_DETECTION_COLUMNS = ("truth_id", "true_range_m", "true_azimuth_rad", "true_range_rate_mps",
                           "merged", "range_folded", "doppler_wrapped", "rcs_dbsm")
"""/detections columns that carry truth: never in a batch nor in a blind export."""


def truth_free_order(detections: Mapping[str, np.ndarray],
                     group: Optional[np.ndarray] = None) -> dict:
    """The detections by dwell and, within a dwell, by measured slant range (then azimuth),
    with the dwell's ``det_id`` values reassigned in that order (the set of values is kept).

    ``group``: one integer per row naming its dwell, in the order the dwells are wanted (default
    ``dwell_id``, unique over a run; the tracker protocol passes each dwell's position in batch
    order, which also tells apart equal ``dwell_id``s of different sensors in user tables).
    A table without ``det_id`` is only reordered."""
    det = {k: np.asarray(v) for k, v in detections.items()}
    if group is None:
        if "dwell_id" not in det:
            return det
        group = det["dwell_id"]
    group = np.asarray(group, np.int64)
    if len(group) < 2:
        return det
    keys = [np.arange(len(group))]          # ties (same range and azimuth): as they were
    for c in ("azimuth_rad", "range_m"):
        if c in det:
            keys.append(np.nan_to_num(np.asarray(det[c], float), nan=np.inf))
    keys.append(group)
    order = np.lexsort(keys)
    out = {k: v[order] for k, v in det.items()}
    if "det_id" in det:
        # each dwell keeps its own ids, handed out in the new order
        out["det_id"] = det["det_id"][np.lexsort((det["det_id"], group))]
    return out
