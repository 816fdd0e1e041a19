"""Track-to-truth identity: per-step association, switches, fragmentation, purity, coverage.

**Association** (CLEAR-MOT, Bernardin & Stiefelhagen 2008, §2.1.1; as py-motmetrics does it).
At every grid step, in two passes:

1. *Keep.*  A truth whose last associated track id (from any earlier step) is present at this
   step and closer than the gate ``g`` = ``assoc_gate_m`` stays with that track.  When two truths
   claim one track, the closer pair keeps it.
2. *Assign.*  The truths and tracks left over are paired by one optimal assignment of the
   pairs closer than the gate: as many pairs as can be matched, and among those matchings the
   least total distance Σd (Munkres with the pairs at or beyond the gate forbidden, as
   py-motmetrics solves it; :func:`_pass2`).

Without pass 1 the association is a fresh nearest-pair choice at every step, and two tracks that
both sit within the gate of one vehicle (or one track between two close vehicles, e.g. a convoy
25 m apart with tracks tens of metres off) flip the pairing back and forth: every flip would be
counted as an identity switch although no track changed what it follows.  CLEAR-MOT counts a
mismatch only when the kept correspondence becomes invalid (the track left the gate or ended) and
the truth is then picked up by a different track.

**Counting** (CLEAR-MOT style, Bernardin & Stiefelhagen 2008), per truth, over its grid steps:

* *identity switch*: the truth is associated with a track id different from the last track id
  it was associated with (gaps in between do not reset the memory).  A track replaced by a new
  one counts 1; two tracks swapping two truths count 1 for each truth, 2 in all; a switch is
  counted once, at the step it happens, never again while the new id holds.
* *fragmentation*: an associated run of the truth resumes after at least one unassociated step
  (whatever the id): every associated run but the first.
* *coverage*: fraction of the truth's steps at which it is associated with some track.
* *purity* of a track: fraction of its associated steps spent on its dominant truth.
"""
from __future__ import annotations

from typing import Mapping

import numpy as np
from scipy.optimize import linear_sum_assignment

from gmtiflow.evaluate.order import dense_ids, lexorder
from gmtiflow.tables import Table


def unique_pairs(a: np.ndarray, b: np.ndarray, return_counts: bool = False):
    """Distinct (a, b) integer pairs sorted by a then b (a faster ``np.unique(axis=0)``)."""
    a = np.asarray(a, np.int64)
    b = np.asarray(b, np.int64)
    if len(a) == 0:
        empty = np.zeros((0, 2), np.int64)
        return (empty, np.zeros(0, np.int64)) if return_counts else empty
    a0, b0 = a.min(), b.min()
    span = int(b.max()) - int(b0) + 1
    if (int(a.max()) - int(a0) + 1) * span >= 2 ** 63:    # the key would overflow int64: the
        ua, ia = dense_ids(a)                             # pairs of dense indices, mapped back
        ub, ib = dense_ids(b)
        out = unique_pairs(ia, ib, return_counts)
        pairs = out[0] if return_counts else out
        pairs = np.stack([ua[pairs[:, 0]], ub[pairs[:, 1]]], axis=1)
        return (pairs, out[1]) if return_counts else pairs
    # one sortable key per pair, sorted (a plain sort: which row of equal keys is kept does not
    # matter, the key gives the pair back) and cut into runs
    key = np.sort((a - a0) * span + (b - b0))
    first = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    pairs = np.stack([key[first] // span + a0, key[first] % span + b0], axis=1)
    counts = np.diff(np.r_[first, len(key)])
    return (pairs, counts) if return_counts else pairs


#: Up to this many (truth, track) pairs a step is paired with one dense assignment; above,
#: candidate pairs inside the gate come from a cell grid and are assigned per connected
#: component.  Both give the same association (the threshold only trades fixed cost for scaling).
DENSE_PAIRS = 4096


def associate(truth_at: Mapping[str, np.ndarray], tracks_at: Mapping[str, np.ndarray],
              n_steps: int, gate_m: float) -> np.ndarray:
    """Track id associated with every ``truth_at`` row (-1 when none), CLEAR-MOT style: a truth
    keeps its last track while that track is present and inside the gate; the rest are paired by
    one optimal assignment per step (see the module docstring).  Vectorised over the truths and
    tracks of a step; one Python iteration per step."""
    out = np.full(len(truth_at["step"]), -1, np.int64)
    tb = np.searchsorted(truth_at["step"], np.arange(n_steps + 1))
    kb = np.searchsorted(tracks_at["step"], np.arange(n_steps + 1))
    X = np.stack([truth_at["x_m"], truth_at["y_m"]], axis=1)
    Y = np.stack([tracks_at["x_m"], tracks_at["y_m"]], axis=1)
    tid = np.asarray(tracks_at["track_id"], np.int64)
    vehicles, vpos = dense_ids(truth_at["vehicle_id"])
    g2 = float(gate_m) ** 2
    last = np.full(len(vehicles), -1, np.int64)   # per vehicle: last associated track id
    for s in np.flatnonzero((np.diff(tb) > 0) & (np.diff(kb) > 0)):
        a, b, c, d = tb[s], tb[s + 1], kb[s], kb[s + 1]
        ids = tid[c:d]
        free_r = np.ones(b - a, bool)
        free_k = np.ones(d - c, bool)
        # Pass 1: keep still-valid correspondences, closest first when two truths claim a track
        # (ties: the lower truth row, as sorting (D², row, col) tuples does).
        prev = last[vpos[a:b]]
        order = np.argsort(ids, kind="stable")
        j = np.minimum(np.searchsorted(ids[order], prev), d - c - 1)
        r = np.flatnonzero((prev >= 0) & (ids[order][j] == prev))
        k = order[j[r]]
        d2 = (X[a + r, 0] - Y[c + k, 0]) ** 2 + (X[a + r, 1] - Y[c + k, 1]) ** 2
        inside = d2 < g2
        r, k, d2 = r[inside], k[inside], d2[inside]
        r, k = _closest_claims(r, k, d2, d - c)
        out[a + r] = ids[k]
        free_r[r] = free_k[k] = False
        # Pass 2: optimal assignment of the rest.
        rr, kk = np.flatnonzero(free_r), np.flatnonzero(free_k)
        if len(rr) and len(kk):
            pr, pk = _pass2(X[a + rr], Y[c + kk], g2)
            out[a + rr[pr]] = ids[kk[pk]]
        got = np.flatnonzero(out[a:b] >= 0)
        last[vpos[a + got]] = out[a + got]
    return out


def _closest_claims(r: np.ndarray, k: np.ndarray, d2: np.ndarray, n_tracks: int):
    """The claims ``(truth r[i], track k[i])`` that win their track: the closest claim of each
    track (ties: the lower truth row, as sorting (d2, row, col) tuples does).  Without two
    claims on one track (the usual step) every claim wins, and the sort is skipped."""
    if len(k) < 2 or np.bincount(k, minlength=n_tracks).max() < 2:
        return r, k
    o = np.lexsort((k, r, d2))
    r, k = r[o], k[o]
    _, win = np.unique(k, return_index=True)
    return r[win], k[win]


def _pass2(X: np.ndarray, Y: np.ndarray, g2: float):
    """Pairs (rows of X, rows of Y) inside the gate: as many as can be matched, and of those
    matchings the one of least total distance Σd (CLEAR-MOT's Munkres with the pairs beyond the
    gate forbidden, as py-motmetrics solves it).  Each pair inside costs ``d − big`` with
    ``big`` = g·(min(m, n) + 1), more than any matching's total distance, so one more pair
    always wins; a pair beyond costs 0 (dense) or is not offered (sparse).  Dense for small
    steps, else the candidate pairs (a cell grid) assigned per connected component (the same
    optimum: components share no pair inside the gate).

    Until 2026-11-28 this minimised Σ min(d, g)², which can leave a pair inside the gate
    unmatched for a closer one (A–1 at 14 m alone rather than A–2 and B–1 at 37 m each): a
    miss and a false positive that py-motmetrics does not count."""
    big = np.sqrt(g2) * (min(len(X), len(Y)) + 1)
    if len(X) * len(Y) <= DENSE_PAIRS:
        sub = (X[:, None, 0] - Y[None, :, 0]) ** 2 + (X[:, None, 1] - Y[None, :, 1]) ** 2
        inside = sub < g2
        r, k = linear_sum_assignment(np.where(inside, np.sqrt(sub) - big, 0.0))
        keep = inside[r, k]
        return r[keep], k[keep]
    from gmtiflow.evaluate.assignment import sparse_gated_assignment
    from gmtiflow.evaluate.neighbours import close_pairs
    # candidates a hair beyond the gate (every pair with d2 < g2 among them), sorted by
    # (row, column); the gate test is then made on d2 itself
    r, k, _ = close_pairs(X, Y, np.sqrt(g2) * (1.0 + 1e-9))
    if not len(r):
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    d2 = (X[r, 0] - Y[k, 0]) ** 2 + (X[r, 1] - Y[k, 1]) ** 2
    inside = d2 < g2
    return sparse_gated_assignment(r[inside], k[inside], np.sqrt(d2[inside]) - big, 0.0)


def identity_metrics(truth_at: Mapping[str, np.ndarray], assigned: np.ndarray,
                     grid: np.ndarray) -> dict:
    """Per-truth and per-track identity tables and the totals.

    Returns ``{"truth": table, "tracks": table, "switches": int, "fragmentations": int,
    "switch_times": table}``.
    """
    vid = np.asarray(truth_at["vehicle_id"], np.int64)
    step = np.asarray(truth_at["step"], np.int64)
    order = lexorder(vid, step)
    v, s, a = vid[order], step[order], assigned[order]
    vehicles, vpos = dense_ids(v)
    n = len(v)
    new_vehicle = np.ones(n, bool)
    new_vehicle[1:] = v[1:] != v[:-1]
    has = a >= 0

    # Switches: compare every associated row with the previous associated row of the vehicle.
    ai = np.flatnonzero(has)
    av, aid = v[ai], a[ai]
    sw = np.zeros(len(ai), bool)
    sw[1:] = (av[1:] == av[:-1]) & (aid[1:] != aid[:-1])
    # Fragmentation: starts of associated runs that are not the vehicle's first run.
    run_start = has & (new_vehicle | ~np.roll(has, 1))
    first_run = np.zeros(n, bool)
    starts_idx = np.flatnonzero(run_start)
    if len(starts_idx):
        # first run start per vehicle
        sv = v[starts_idx]
        first = np.ones(len(starts_idx), bool)
        first[1:] = sv[1:] != sv[:-1]
        first_run[starts_idx[first]] = True
    frag = run_start & ~first_run

    n_steps = np.bincount(vpos, minlength=len(vehicles))
    n_assoc = np.bincount(vpos, weights=has, minlength=len(vehicles))
    n_sw = np.bincount(vpos[ai[sw]], minlength=len(vehicles))
    n_fr = np.bincount(vpos[frag], minlength=len(vehicles))
    pairs = unique_pairs(v[has], a[has])
    n_ids = np.bincount(np.searchsorted(vehicles, pairs[:, 0]), minlength=len(vehicles))
    truth_table = {"vehicle_id": vehicles, "n_steps": n_steps.astype(np.int64),
                   "coverage": np.where(n_steps > 0, n_assoc / np.maximum(n_steps, 1), np.nan),
                   "identity_switches": n_sw.astype(np.int64),
                   "fragmentations": n_fr.astype(np.int64), "n_track_ids": n_ids.astype(np.int64)}

    # Purity per track: its associated steps, and the share of its dominant truth.
    if has.any():
        uniq, counts = unique_pairs(a[has], v[has], return_counts=True)
        o = np.lexsort((uniq[:, 1], -counts, uniq[:, 0]))   # track, count desc, vehicle
        u2, c2 = uniq[o], counts[o]
        firsts = np.flatnonzero(np.r_[True, u2[1:, 0] != u2[:-1, 0]])
        tracks, dom, best = u2[firsts, 0], u2[firsts, 1], c2[firsts]
        total = np.add.reduceat(c2, firsts)
        n_truths = np.diff(np.r_[firsts, len(u2)])
    else:
        tracks = total = best = dom = n_truths = np.zeros(0, np.int64)
    track_table = {"track_id": tracks.astype(np.int64), "n_associated": total.astype(np.int64),
                   "purity": np.where(total > 0, best / np.maximum(total, 1), np.nan),
                   "dominant_vehicle_id": dom.astype(np.int64),
                   "n_vehicles": n_truths.astype(np.int64)}
    sw_rows = ai[sw]
    switch_times = {"time_s": np.asarray(grid, float)[s[sw_rows]], "vehicle_id": v[sw_rows],
                    "from_track_id": aid[np.flatnonzero(sw) - 1],
                    "to_track_id": a[sw_rows]}
    return {"truth": truth_table, "tracks": track_table, "switches": int(sw.sum()),
            "fragmentations": int(frag.sum()), "switch_times": switch_times}


def association_table(truth_at: Mapping[str, np.ndarray], assigned: np.ndarray,
                      grid: np.ndarray) -> Table:
    """The per-step association as a table: time_s, vehicle_id, track_id (-1 = none)."""
    return {"time_s": np.asarray(grid, float)[truth_at["step"]],
            "vehicle_id": np.asarray(truth_at["vehicle_id"], np.int64),
            "track_id": np.asarray(assigned, np.int64)}


def convoy_confusions(vehicle_id: np.ndarray, assigned: np.ndarray,
                      convoy_of: Mapping[int, int]) -> Table:
    """Per convoy: members, tracks associated with any member, and *confused* tracks — those
    associated with two or more different members of the convoy over time (split/merge
    confusions: a track that hops from one convoy vehicle to another)."""
    has = assigned >= 0
    pairs = unique_pairs(assigned[has], vehicle_id[has])
    convoys = sorted({c for c in convoy_of.values() if c >= 0})
    out = {"convoy_id": np.asarray(convoys, np.int64),
           "n_members": np.zeros(len(convoys), np.int64),
           "n_tracks": np.zeros(len(convoys), np.int64),
           "n_confused_tracks": np.zeros(len(convoys), np.int64)}
    pair_convoy = np.array([convoy_of.get(int(vv), -1) for vv in pairs[:, 1]], np.int64)
    for i, c in enumerate(convoys):
        out["n_members"][i] = sum(1 for cc in convoy_of.values() if cc == c)
        sel = pairs[pair_convoy == c]
        if len(sel):
            tids, counts = np.unique(sel[:, 0], return_counts=True)
            out["n_tracks"][i] = len(tids)
            out["n_confused_tracks"][i] = int((counts > 1).sum())
    return out
