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
