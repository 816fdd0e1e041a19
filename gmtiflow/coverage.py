"""Per-sensor and fused detection coverage: what each sensor sees, and what they see together.

``/metrics/sensors`` has one row per sensor (``sensor_id`` 0..S-1) and one ``fused`` row
(``sensor_id`` = -1, all sensors' detections and looks together).  For a set of sensors:

* ``detection_coverage``: the fraction of /truth samples (vehicle, time) at which the vehicle
  had a report of its own (a look with outcome ``detected``) from the set within the last
  ``window_s`` seconds, ``t - window_s < t_det <= t``.  The window is the same for every row
  (twice the longest revisit of the scene's sensors), so the rows compare.
* ``detection_gaps``: the set's looks of a vehicle merged in time order, a gap is a run of
  looks without a detection whose span from the previous detection (or the vehicle's first
  look) to the next one (or the end of the scene) is longer than ``window_s``.  For the fused
  row a detection by *any* sensor ends a gap, so a vehicle lost in one sensor's Doppler notch
  but seen by another has no fused gap.
* ``doppler_blind_gaps``: the gaps whose most frequent blind outcome (doppler_blind,
  terrain, invisible_road; ties: the lowest code, as :mod:`gmtiflow.evaluate.events`) is
  ``doppler_blind``; ``doppler_blind_gap_s`` their total span (vehicle-seconds).

A tracker fed the fused detections can only hold what the fused row covers; these numbers are
the sensors' share of the comparison, independent of any tracker.
"""
from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from gmtiflow.sensor.outcome import Outcome
from gmtiflow.tables import Table

SENSORS_METRICS = ("sensor_id", "name", "n_dwells", "n_detections", "n_false_alarms",
                   "detection_coverage", "detection_gaps", "doppler_blind_gaps",
                   "doppler_blind_gap_s")
FUSED_ID = -1


def detection_coverage(truth: Mapping[str, np.ndarray], looks: Mapping[str, np.ndarray],
                       window_s: float) -> float:
    """Fraction of truth samples whose vehicle was detected within the last ``window_s``."""
    tv = np.asarray(truth["vehicle_id"], np.int64)
    tt = np.asarray(truth["time_s"], float)
    if tv.size == 0:
        return float("nan")
    hit = np.asarray(looks["outcome"]) == Outcome.DETECTED
    dv = np.asarray(looks["vehicle_id"], np.int64)[hit]
    dt = np.asarray(looks["time_s"], float)[hit]
    # One sorted axis for all vehicles: vehicle v's times live in [v*span, (v+1)*span).
    span = float(max(tt.max(initial=0.0), dt.max(initial=0.0))) + 2.0 * window_s + 1.0
    det_key = np.sort(dv * span + dt)
    truth_key = tv * span + tt
    last = np.searchsorted(det_key, truth_key, side="right") - 1
    prev = det_key[np.maximum(last, 0)] if det_key.size else np.zeros(0)
    covered = (last >= 0) & (truth_key - prev < window_s) if det_key.size else \
        np.zeros(tv.size, bool)
    return float(np.mean(covered))


def detection_gaps(looks: Mapping[str, np.ndarray], window_s: float, end_s: float):
    """(number of gaps, number of Doppler-blind gaps, their total span in s) of these looks."""
    v = np.asarray(looks["vehicle_id"], np.int64)
    t = np.asarray(looks["time_s"], float)
    order = np.lexsort((t, v))
    v, t = v[order], t[order]
    code = np.asarray(looks["outcome"]).astype(np.int64)[order]
    if v.size == 0:
        return 0, 0, 0.0
    det = code == Outcome.DETECTED
    new = np.r_[True, v[1:] != v[:-1]]          # first look of a vehicle
    last = np.r_[v[1:] != v[:-1], True]         # last look of a vehicle
    starts = np.flatnonzero(~det & (new | np.r_[True, det[:-1]]))
    ends = np.flatnonzero(~det & (last | np.r_[det[1:], True]))
    before = np.where(new[starts], t[starts], t[np.maximum(starts - 1, 0)])
    after = np.where(last[ends], end_s, t[np.minimum(ends + 1, v.size - 1)])
    gap = after - before > window_s
    counts = {}
    for outcome in (Outcome.INVISIBLE_ROAD, Outcome.TERRAIN, Outcome.DOPPLER_BLIND):
        cum = np.r_[0, np.cumsum(code == outcome)]
        counts[int(outcome)] = cum[ends + 1] - cum[starts]
    doppler = gap & (counts[int(Outcome.DOPPLER_BLIND)] > 0) & \
        (counts[int(Outcome.DOPPLER_BLIND)] > counts[int(Outcome.TERRAIN)]) & \
        (counts[int(Outcome.DOPPLER_BLIND)] > counts[int(Outcome.INVISIBLE_ROAD)])
    return int(gap.sum()), int(doppler.sum()), float(np.sum((after - before)[doppler]))


def sensors_table(names: Sequence[str], truth: Mapping[str, np.ndarray],
                  dwells: Mapping[str, np.ndarray], detections: Mapping[str, np.ndarray],
                  looks: Mapping[str, np.ndarray], window_s: float, end_s: float) -> Table:
    """``/metrics/sensors``: one row per sensor (``names[i]`` is sensor i), then the fused row."""
    rows = {c: [] for c in SENSORS_METRICS}
    ids = list(range(len(names))) + [FUSED_ID]
    for sid in ids:
        def part(table):
            if sid == FUSED_ID:
                return table
            sel = np.asarray(table["sensor_id"]) == sid
            return {c: np.asarray(v)[sel] for c, v in table.items()}
        lk, det = part(looks), part(detections)
        n_gaps, n_doppler, doppler_s = detection_gaps(lk, window_s, end_s)
        rows["sensor_id"].append(sid)
        rows["name"].append("fused" if sid == FUSED_ID else names[sid])
        rows["n_dwells"].append(len(part(dwells)["dwell_id"]))
        rows["n_detections"].append(len(det["det_id"]))
        rows["n_false_alarms"].append(int(np.sum(np.asarray(det["truth_id"]) < 0)))
        rows["detection_coverage"].append(detection_coverage(truth, lk, window_s))
        rows["detection_gaps"].append(n_gaps)
        rows["doppler_blind_gaps"].append(n_doppler)
        rows["doppler_blind_gap_s"].append(doppler_s)
    out = {c: np.asarray(v) for c, v in rows.items()}
    out["name"] = np.asarray(rows["name"], dtype=str)
    for c in ("sensor_id", "n_dwells", "n_detections", "n_false_alarms", "detection_gaps",
              "doppler_blind_gaps"):
        out[c] = out[c].astype(np.int64)
    for c in ("detection_coverage", "doppler_blind_gap_s"):
        out[c] = out[c].astype(np.float64)
    return out
