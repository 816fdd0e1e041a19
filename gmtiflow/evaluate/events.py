"""GMTI events: does a track keep its identity through a stop or a blind gap, and how fast is a
vehicle re-acquired?  (The paper's outlook, §7: "the loss of track identities after stop events
is a great problem for GMTI trackers, and a quantification for this quality must be developed".)

Events, per vehicle:

* **stop**: a run of truth samples with ``mode == 2`` (stopped).  ``start_s`` = first stopped
  sample, ``end_s`` = first sample after the run (the vehicle moves again); NaN when it never does.
* **blind gap**: a run of consecutive /looks of the vehicle that are not detections, holding at
  least ``min_gap_looks`` looks whose outcome is doppler_blind (4), terrain (3) or
  invisible_road (2).  ``kind`` = the most frequent of those outcomes in the run (ties: the
  lowest code).  ``start_s`` = first look of the run, ``end_s`` = the next detected look of the
  vehicle (the first moment it could be re-acquired); NaN when none follows.  A stopped vehicle
  is usually also Doppler blind, so a stop normally shows up as a stop *and* as a
  doppler_blind gap; they are scored separately.

Several sensors (/looks with more than one ``sensor_id``): blind gaps are found in every
sensor's own looks (``sensor_id`` = that sensor: what that radar alone lost) and in all looks
together in time order (``sensor_id`` = -1, *fused*: a detection by any sensor ends the gap, so
it is what a tracker fusing all sensors went without).  Fused gaps are fewer *long* gaps but can
be more numerous than one sensor's: a sensor's blind stretch that another sensor keeps seeing
splits into one short fused gap per blind look, each ended by the other sensor's next
detection.  Stop events and the summary's event metrics use the fused rows; with one sensor every
row is fused (-1).

Scoring, from the per-step association (:mod:`gmtiflow.evaluate.identity`) on the evaluation grid:

* ``track_before``: the last track id associated with the vehicle at a grid time in
  ``[start_s − event_lookback_s, start_s]`` (-1: the vehicle was not held before the event; such
  events are reported but not scored for identity);
* ``track_after``: the first track id associated at a grid time ≥ ``end_s``;
* ``id_kept``: ``track_after == track_before`` (and ``track_before`` ≥ 0);
* ``reacq_delay_s``: (that first grid time) − ``end_s``; NaN when never re-acquired.  It is
  quantised by the evaluation grid.
"""
from __future__ import annotations

from typing import Mapping

import numpy as np

from gmtiflow.evaluate.order import lexorder, searchsorted_within
from gmtiflow.tables import Table

OUTCOME_DETECTED = 0
BLIND_OUTCOMES = {2: "invisible_road", 3: "terrain", 4: "doppler_blind"}
STOPPED = 2

EVENT_COLUMNS = ("vehicle_id", "kind", "start_s", "end_s", "duration_s", "track_before",
                 "track_after", "id_kept", "reacquired", "reacq_delay_s")
"""The columns every /metrics/events table has (the store requires them when reading)."""
OPTIONAL_COLUMNS = ("sensor_id",)
"""Written since several sensors are scored per sensor; run files from before lack it (one
sensor, every row fused)."""
FUSED = -1
"""``sensor_id`` of stop events and of blind gaps in all sensors' looks together (fused)."""


def _runs(flag: np.ndarray, group: np.ndarray):
    """(start, end) index pairs (inclusive) of runs of True in ``flag`` within equal ``group``."""
    n = len(flag)
    if n == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    new = np.ones(n, bool)
    new[1:] = group[1:] != group[:-1]
    prev = np.zeros(n, bool)
    prev[1:] = flag[:-1]
    nxt = np.zeros(n, bool)
    nxt[:-1] = flag[1:]
    last = np.ones(n, bool)
    last[:-1] = group[1:] != group[:-1]
    starts = np.flatnonzero(flag & (new | ~prev))
    ends = np.flatnonzero(flag & (last | ~nxt))
    return starts, ends


def stop_events(truth: Mapping[str, np.ndarray]) -> Table:
    """Stop events (vehicle_id, kind, start_s, end_s) from the truth ``mode`` column."""
    v = np.asarray(truth["vehicle_id"], np.int64)
    t = np.asarray(truth["time_s"], float)
    o = lexorder(v, t)
    v, t = v[o], t[o]
    stopped = np.asarray(truth["mode"])[o] == STOPPED
    s, e = _runs(stopped, v)
    after = e + 1
    has_after = (after < len(v)) & (v[np.minimum(after, len(v) - 1)] == v[e])
    end = np.where(has_after, t[np.minimum(after, len(v) - 1)], np.nan)
    return {"vehicle_id": v[s], "kind": np.array(["stop"] * len(s), dtype=object).astype(str),
            "start_s": t[s], "end_s": end}


def blind_gap_events(looks: Mapping[str, np.ndarray], min_gap_looks: int = 1) -> Table:
    """Blind-gap events (vehicle_id, kind, start_s, end_s) from the /looks outcomes."""
    v = np.asarray(looks["vehicle_id"], np.int64)
    t = np.asarray(looks["time_s"], float)
    o = lexorder(v, t)
    v, t = v[o], t[o]
    outcome = np.asarray(looks["outcome"]).astype(np.int64)[o]
    s, e = _runs(outcome != OUTCOME_DETECTED, v)
    # Per run, the looks of each blind outcome (cumulative counts: no loop over runs).
    codes = sorted(BLIND_OUTCOMES)
    counts = np.zeros((len(codes), len(s)), np.int64)
    for i, code in enumerate(codes):
        cum = np.concatenate([[0], np.cumsum(outcome == code)])
        counts[i] = cum[e + 1] - cum[s]
    n_blind = counts.sum(axis=0)
    ok = n_blind >= max(min_gap_looks, 1)
    s, e, counts = s[ok], e[ok], counts[:, ok]
    names = np.array([BLIND_OUTCOMES[c] for c in codes], dtype=object)
    kinds = names[np.argmax(counts, axis=0)].tolist()      # ties: the lowest code
    nxt = np.minimum(e + 1, max(len(v) - 1, 0))
    follows = (e + 1 < len(v)) & (v[nxt] == v[e])
    ends = np.where(follows, t[nxt], np.nan)
    return {"vehicle_id": v[s], "kind": np.asarray(kinds, dtype=str).reshape(-1),
            "start_s": t[s], "end_s": np.asarray(ends, float)}


def score_events(events: Mapping[str, np.ndarray], assoc_vehicle: np.ndarray,
                 assoc_time: np.ndarray, assoc_track: np.ndarray, lookback_s: float) -> Table:
    """Add track_before/after, id_kept, reacquired and reacq_delay_s to an event table.

    ``assoc_*``: the per-step association (vehicle_id, time_s, track_id; -1 = none).
    """
    o = lexorder(assoc_vehicle, assoc_time)
    av, at, ak = assoc_vehicle[o], assoc_time[o], assoc_track[o]
    has = ak >= 0
    av, at, ak = av[has], at[has], ak[has]
    vid = np.asarray(events["vehicle_id"])
    t0 = np.asarray(events["start_s"], np.float64)
    t1 = np.asarray(events["end_s"], np.float64)
    n = len(vid)
    eps = 1e-9
    before = np.full(n, -1, np.int64)
    after = np.full(n, -1, np.int64)
    delay = np.full(n, np.nan)
    if n and len(av):
        # Each event's two searches in its vehicle's associations (a segment of the sorted
        # rows), for all events at once, with the comparisons a search per event made.
        lo, hi = np.searchsorted(av, vid), np.searchsorted(av, vid + 1)
        # before: the last association at or before start_s (+eps), within the lookback
        j = searchsorted_within(at, lo, hi, t0 + eps, side="right") - 1
        hit = j >= lo
        hit[hit] = at[j[hit]] >= t0[hit] - lookback_s - eps
        before[hit] = ak[j[hit]]
        # after: the first association at or after end_s (-eps); none for an open event
        j = searchsorted_within(at, lo, hi, t1 - eps, side="left")
        hit = np.isfinite(t1) & (j < hi)
        after[hit] = ak[j[hit]]
        delay[hit] = np.maximum(at[j[hit]] - t1[hit], 0.0)
    out = {k: np.asarray(events[k]) for k in ("vehicle_id", "kind", "start_s", "end_s")}
    out["sensor_id"] = (np.asarray(events["sensor_id"], np.int64) if "sensor_id" in events
                        else np.full(n, FUSED, np.int64))
    out = {k: out[k] for k in ("vehicle_id", "kind", "sensor_id", "start_s", "end_s")}
    out["duration_s"] = out["end_s"] - out["start_s"]
    out["track_before"] = before
    out["track_after"] = after
    out["id_kept"] = (before >= 0) & (after == before)
    out["reacquired"] = after >= 0
    out["reacq_delay_s"] = delay
    return out


def gap_events(looks: Mapping[str, np.ndarray], min_gap_looks: int = 1) -> Table:
    """Blind-gap events of the fused looks (``sensor_id`` -1) and, with several sensors, of each
    sensor's looks (``sensor_id`` = that sensor); see the module docstring."""
    fused = blind_gap_events(looks, min_gap_looks)
    parts = [{**fused, "sensor_id": np.full(len(fused["vehicle_id"]), FUSED, np.int64)}]
    sensors = np.asarray(looks["sensor_id"], np.int64) if "sensor_id" in looks else None
    ids = np.unique(sensors) if sensors is not None else ()
    if len(ids) > 1:
        for sid in ids:
            own = sensors == sid
            found = blind_gap_events({k: np.asarray(v)[own] for k, v in looks.items()},
                                     min_gap_looks)
            parts.append({**found, "sensor_id": np.full(len(found["vehicle_id"]), sid, np.int64)})
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
