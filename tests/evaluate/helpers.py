"""Hand-built truth and track tables in the docs/tables.md columns."""
import numpy as np


def truth_table(paths, modes=None):
    """paths: vehicle_id -> (times, x, y); velocities from finite differences (exact for lines)."""
    modes = modes or {}
    parts = []
    for vid, (t, x, y) in paths.items():
        t, x, y = (np.asarray(a, float) for a in (t, x, y))
        vx = np.gradient(x, t) if len(t) > 1 else np.zeros(len(t))
        vy = np.gradient(y, t) if len(t) > 1 else np.zeros(len(t))
        mode = np.asarray(modes.get(vid, np.zeros(len(t))), np.uint8)
        parts.append({"time_s": t, "vehicle_id": np.full(len(t), vid, np.int64),
                      "convoy_id": np.full(len(t), -1, np.int64), "x_m": x, "y_m": y,
                      "z_m": np.zeros(len(t)), "vx_mps": vx, "vy_mps": vy,
                      "vz_mps": np.zeros(len(t)), "speed_mps": np.hypot(vx, vy),
                      "heading_rad": np.mod(np.arctan2(vx, vy), 2 * np.pi), "mode": mode})
    out = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    o = np.lexsort((out["vehicle_id"], out["time_s"]))
    return {k: v[o] for k, v in out.items()}


def track_table(rows):
    """rows: list of (track_id, time_s, x_m, y_m) -> a position-only track table."""
    a = np.asarray(rows, float).reshape(-1, 4)
    return {"track_id": a[:, 0].astype(np.int64), "time_s": a[:, 1], "x_m": a[:, 2],
            "y_m": a[:, 3]}


def line(t, x0, y0, vx, vy):
    t = np.asarray(t, float)
    return t, x0 + vx * t, y0 + vy * t


def check_truth_free_order(seen, ref):
    """Check that ``seen``, detections as a tracker under test receives them (a batch's, a blind
    CSV's), list each dwell's reports by measured slant range with the dwell's own det_id values
    handed out in that order; ``ref`` is run.h5's /detections (with truth_id).  Each seen report
    is found in ``ref`` by (dwell_id, range_m).  Returns how many dwells with two or more
    reports of which at least two differ in truth_id (vehicles, or a vehicle and a false alarm)
    there are, and how many of those still list them in ``ref``'s order (run.h5's: targets by
    vehicle id, then false alarms): the caller asserts that the order gives nothing away."""
    seen_dwell = np.asarray(seen["dwell_id"], np.int64)
    ref_dwell = np.asarray(ref["dwell_id"], np.int64)
    assert sorted(seen_dwell.tolist()) == sorted(ref_dwell.tolist())
    mixed = truth_ordered = 0
    for d in np.unique(ref_dwell):
        mine = np.flatnonzero(seen_dwell == d)
        assert np.all(np.diff(mine) == 1), f"dwell {d}: its reports are not together"
        rng_m = np.asarray(seen["range_m"], float)[mine]
        ids = np.asarray(seen["det_id"], np.int64)[mine]
        assert np.all(np.diff(rng_m) >= 0), f"dwell {d}: not by measured range"
        assert np.all(np.diff(ids) > 0), f"dwell {d}: det_ids not handed out in row order"
        theirs = np.flatnonzero(ref_dwell == d)
        assert sorted(ids.tolist()) == sorted(np.asarray(ref["det_id"])[theirs].tolist()), d
        truth_of = dict(zip(np.asarray(ref["range_m"], float)[theirs].tolist(),
                            np.asarray(ref["truth_id"], np.int64)[theirs].tolist()))
        assert len(truth_of) == len(theirs), f"dwell {d}: two reports at one range"
        truth = np.array([truth_of[r] for r in rng_m.tolist()])
        if len(np.unique(truth)) < 2:
            continue
        mixed += 1
        truth_ordered += np.array_equal(truth, np.asarray(ref["truth_id"])[theirs])
    return mixed, truth_ordered
