"""CLEAR-MOT MOTA/MOTP and the identity measure IDF1, on the per-step association.

Counts over all grid steps (Bernardin & Stiefelhagen 2008; Ristani et al. 2016), with the
association of :func:`gmtiflow.evaluate.identity.associate` (gate g = ``assoc_gate_m``, Euclidean
ground distance) — the same conventions as py-motmetrics' ``MOTAccumulator`` with Euclidean
distances and ``max_d`` = g, against which ``tests/evaluate/test_clearmot.py`` checks them:

* GT = truth-steps, FN = truth-steps without a track, FP = track-steps without a truth,
  IDSW = identity switches; **MOTA** = 1 − (FN + FP + IDSW) / GT (can be negative);
  **MOTP** = mean distance (m) of the associated pairs (lower is better; py-motmetrics' MOTP
  with Euclidean distances).
* **IDF1** = 2·IDTP / (GT + track-steps): IDTP is the number of steps at which a truth and the
  track it is matched with *for the whole run* are closer than g, with the one-to-one
  truth↔track matching that maximises it (an optimal assignment on the co-occurrence counts,
  per connected component of the co-occurring pairs); IDP = IDTP / track-steps, IDR = IDTP / GT.

Pairs closer than g are found for all steps at once (:func:`gmtiflow.evaluate.neighbours.
close_pairs`, a grid of g-sized cells per step), so the cost is linear in rows (no per-step
Python loop).
"""
from __future__ import annotations

from typing import Dict, Mapping

import numpy as np
from gmtiflow.evaluate.assignment import sparse_gated_assignment
from gmtiflow.evaluate.identity import unique_pairs
from gmtiflow.evaluate.neighbours import step_pairs
from gmtiflow.evaluate.order import dense_ids


def _matched_distance(truth_at, tracks_at, assigned: np.ndarray) -> np.ndarray:
    """Distance of each associated truth row to its track at that step."""
    rows = np.flatnonzero(assigned >= 0)
    if not len(rows):
        return np.zeros(0)
    steps_k = np.asarray(tracks_at["step"], np.int64)
    # (step, track) as one integer key from the tracks' dense index: the ids themselves may be
    # anywhere in 0 .. 2^63 - 1, where step * span + id overflowed
    uniq, dense = dense_ids(tracks_at["track_id"])
    key_k = steps_k * len(uniq) + dense
    order = np.argsort(key_k, kind="stable")
    want = (np.asarray(truth_at["step"], np.int64)[rows] * len(uniq)
            + np.searchsorted(uniq, assigned[rows]))
    j = order[np.searchsorted(key_k[order], want)]
    return np.hypot(np.asarray(truth_at["x_m"], float)[rows] - tracks_at["x_m"][j],
                    np.asarray(truth_at["y_m"], float)[rows] - tracks_at["y_m"][j])


def idtp(truth_at: Mapping[str, np.ndarray], tracks_at: Mapping[str, np.ndarray],
         gate_m: float, pairs=None) -> int:
    """IDTP: co-occurrences within the gate under the best one-to-one truth↔track matching.

    ``pairs``: :func:`~gmtiflow.evaluate.neighbours.step_pairs` at ``gate_m`` when the caller
    has them already (the search is then not repeated)."""
    n_t, n_k = len(truth_at["step"]), len(tracks_at["step"])
    if not n_t or not n_k:
        return 0
    # the pairs of one step closer than g (the distances a k-d tree over (x, y, step·4g) gives)
    r, c, _ = step_pairs(truth_at, tracks_at, float(gate_m)) if pairs is None else pairs
    if not len(r):
        return 0
    vid = np.asarray(truth_at["vehicle_id"], np.int64)[r]
    tid = np.asarray(tracks_at["track_id"], np.int64)[c]
    pairs, counts = unique_pairs(vid, tid, return_counts=True)
    # maximise the matched co-occurrences: minimise −count, every pair "inside" a gate of 0;
    # solved per connected component of the (vehicle, track) pairs (sparse, linear in them)
    rr, cc = sparse_gated_assignment(pairs[:, 0], pairs[:, 1], -counts.astype(float), 0.0)
    lo = pairs[:, 0].min()
    tracks = np.unique(pairs[:, 1])      # dense track index: ids may span all of 64 bits

    def key(v, t):      # the pairs' order (vehicle, then track) as one sortable integer
        return (v - lo) * len(tracks) + np.searchsorted(tracks, t)
    return int(counts[np.searchsorted(key(pairs[:, 0], pairs[:, 1]), key(rr, cc))].sum())


def clear_mot(truth_at: Mapping[str, np.ndarray], tracks_at: Mapping[str, np.ndarray],
              assigned: np.ndarray, switches: int, gate_m: float,
              pairs=None) -> Dict[str, float]:
    """MOTA, MOTP (m), IDF1, IDP, IDR and the counts they come from (see the module docstring).
    ``pairs``: as :func:`idtp` takes them."""
    gt = len(truth_at["step"])
    n_hyp = len(tracks_at["step"])
    assigned = np.asarray(assigned, np.int64)
    matches = int(np.sum(assigned >= 0))
    fn, fp = gt - matches, n_hyp - matches
    d = _matched_distance(truth_at, tracks_at, assigned)
    tp_id = idtp(truth_at, tracks_at, gate_m, pairs)
    nan = float("nan")
    return {
        "mota": 1.0 - (fn + fp + switches) / gt if gt else nan,
        "motp_m": float(d.mean()) if len(d) else nan,
        "idf1": 2.0 * tp_id / (gt + n_hyp) if gt + n_hyp else nan,
        "idp": tp_id / n_hyp if n_hyp else nan,
        "idr": tp_id / gt if gt else nan,
        "false_negatives": float(fn), "false_positives": float(fp),
    }
