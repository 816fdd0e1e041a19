"""The braking cap ahead of each road segment (motion._speed_caps): for segment j, the later
segment b of the same route with the smallest T_b² + 2 d s_b (the nearest one on ties)."""
import numpy as np

from gmtiflow.scene.motion import _speed_caps


def _caps_one_by_one(offset, start, target, d_cap):
    cap_t = np.full(len(start), np.inf)
    cap_s = np.full(len(start), np.inf)
    for p in range(len(offset) - 1):
        for j in range(offset[p], offset[p + 1] - 1):
            r = [target[b] ** 2 + 2.0 * d_cap[p] * start[b] for b in range(j + 1, offset[p + 1])]
            b = j + 1 + int(np.argmin(r))           # argmin: the first (nearest) minimum
            cap_t[j], cap_s[j] = target[b], start[b]
    return cap_t, cap_s


def test_caps_are_each_segments_binding_segment_ahead():
    g = np.random.default_rng(3)
    n_seg = g.integers(1, 9, 60)                    # routes of 1 to 8 segments, many alike
    offset = np.concatenate([[0], np.cumsum(n_seg)])
    start = np.concatenate([np.concatenate([[0.0], np.cumsum(g.uniform(5, 400, n - 1))])
                            for n in n_seg])
    # speeds from a few values, so equal bounds (ties) occur: two 0 m segments at the same
    # start, and d = 0 (the bound is then T² alone)
    target = g.choice([8.0, 13.9, 13.9, 25.0], size=len(start))
    start[offset[5] + 2] = start[offset[5] + 1] if n_seg[5] > 2 else start[offset[5] + 2]
    d_cap = g.choice([0.0, 3.6], size=len(n_seg))
    got = _speed_caps(offset, start, target, d_cap)
    want = _caps_one_by_one(offset, start, target, d_cap)
    assert got[0].tobytes() == want[0].tobytes() and got[1].tobytes() == want[1].tobytes()
    last = offset[1:] - 1
    assert np.isinf(got[0][last]).all() and np.isfinite(np.delete(got[0], last)).all()
    # ties were there to break: some segment has two equal bounds ahead
    assert (d_cap == 0).any() and (n_seg > 3).any()
