"""Line of sight by vectorised ray marching over a terrain (:meth:`Terrain.line_of_sight`).

Line of sight (``line_of_sight``) samples every ray at ``step_m`` from the target end, all rays
at once and in chunks of ``chunk_samples`` samples; a ray is blocked if at some sample the ground
is more than ``clearance_m`` above the ray. Samples within ``end_skip_m`` (default: one grid
cell) of either end are not tested, so a target's own ground cell never shadows it. Two exact
shortcuts: the part of a ray above the highest ground is not sampled, and of the ~1 km segments
left only those that the highest ground within reach (a cached running-maximum grid) comes up to
are sampled. Geodetic DEMs compare heights above the ellipsoid along the local normal: the
segment ends are converted with pymap3d and the samples interpolated linearly in between
(error < 2 cm in height, < 1 mm horizontally). Rays are straight on an earth of the radius the
caller gives (``earth_radius_m``: the sensor passes k·R, its 4/3-earth refraction model), by
raising the ground by the earth's bulge (:func:`march`); without a radius, on a flat earth.

The march reads the terrain only through its hooks (``_coords``, ``_ground``,
``_ground_bound``) and attributes (``end_skip_m``, ``z_ceiling_m``, ``chunk_samples``,
``clearance_m``, ``ray_sag_m``), see :class:`gmtiflow.scene.terrain.Terrain`.
"""
from __future__ import annotations

import numpy as np

#: segment length along a ray (metres): the screen against the ground's maximum, and the
#: spacing of the ENU -> geodetic conversions for geodetic DEMs
KNOT_M = 1000.0


def max_filter(terrain, half: tuple, values: np.ndarray) -> np.ndarray:
    """Running maximum of ``values`` over (2*half + 1) windows, NaN (unknown) as -inf; cached."""
    cache = terrain.__dict__.setdefault("_max_cache", {})
    if half not in cache:
        import scipy.ndimage
        v = np.where(np.isnan(values), -np.inf, values)
        cache[half] = scipy.ndimage.maximum_filter(v, size=(2 * half[0] + 1, 2 * half[1] + 1),
                                                   mode="nearest")
    return cache[half]


def march(terrain, p_from: np.ndarray, p_to: np.ndarray, step_m: float,
          earth_radius_m=None) -> np.ndarray:
    """Blocked flag per ray by vectorised ray sampling (see the module docstring).

    Samples sit at distances ``s = s_lo + k*step_m`` from the target end ``p_to``, where
    [s_lo, s_hi] is the part of [end_skip, length - end_skip] on which the ray is not above the
    highest ground. They are grouped in segments of ``C`` samples (about ``KNOT_M``): each
    segment's ends are converted to terrain coordinates (pymap3d for geodetic DEMs), and a
    segment is sampled only if the highest ground within reach of it (a max-filtered grid) comes
    up to the ray; the samples inside are interpolated between the ends. Skipping a segment is
    exact: no ground under it can block. Rays are grouped into chunks of at most
    ``chunk_samples`` samples (a single longer ray is its own chunk).

    ``earth_radius_m`` (a): the ray is straight on a round earth, so it sits t(1 − t)·d²/(2a)
    below the map-straight line at fraction t of a ray of ground length d: the ground there is
    raised by that bulge before the comparison (equivalently the ray lowered); the screens add
    the bulge's maximum d²/(8a), so they stay exact.
    """
    n = len(p_from)
    blocked = np.zeros(n, dtype=bool)
    d = p_from - p_to
    length = np.sqrt(np.einsum("ij,ij->i", d, d))
    finite = np.isfinite(length)
    good = finite & (length > 0)
    u = np.zeros_like(d)
    u[good] = d[good] / length[good, None]
    skip = terrain.end_skip_m
    s_lo = np.full(n, skip)
    s_hi = np.where(finite, length - skip, -np.inf)
    uz = u[:, 2]
    z_to = np.where(finite, p_to[:, 2], 0.0)
    if earth_radius_m is None:
        bulge = np.zeros(n)
    else:
        bulge = np.where(finite, (d[:, 0] ** 2 + d[:, 1] ** 2) / (2.0 * earth_radius_m), 0.0)
    top = 0.25 * bulge   # the bulge's maximum, at the ray's middle
    room = terrain.z_ceiling_m + top - z_to  # the ray can be blocked only where its z rise <= room
    lim = np.divide(room, uz, out=np.zeros(n), where=uz != 0)
    s_hi = np.where(uz > 0, np.minimum(s_hi, lim), s_hi)
    s_lo = np.where(uz < 0, np.maximum(s_lo, lim), s_lo)
    s_hi = np.where((uz == 0) & (room < 0), -np.inf, s_hi)
    s_hi = np.where(good, s_hi, -np.inf)
    count = np.zeros(n, dtype=np.int64)
    ok = s_hi >= s_lo
    count[ok] = np.floor((s_hi[ok] - s_lo[ok]) / step_m).astype(np.int64) + 1
    per_seg = max(1, int(round(KNOT_M / step_m)))
    seg_m = per_seg * step_m
    n_seg = (count + per_seg - 1) // per_seg
    cum = np.cumsum(count)
    budget = terrain.chunk_samples
    clr = terrain.clearance_m
    sag = terrain.ray_sag_m  # h below its chord over a segment
    start = 0
    while start < n:
        base = cum[start - 1] if start else 0
        end = max(int(np.searchsorted(cum, base + budget, side="right")), start + 1)
        ns = n_seg[start:end]
        total_seg = int(ns.sum())
        if total_seg:
            # segment ends: ray r has ns[r] segments and ns[r] + 1 ends
            n_end = np.where(ns > 0, ns + 1, 0)
            first_end = np.cumsum(n_end) - n_end
            e_ray = np.repeat(np.arange(start, end), n_end)
            e_idx = np.arange(int(n_end.sum())) - np.repeat(first_end, n_end)
            e_s = np.minimum(s_lo[e_ray] + e_idx * seg_m, s_hi[e_ray])
            ea, eb, ec = terrain._coords(p_to[e_ray] + u[e_ray] * e_s[:, None])
            # segments: ends k and k + 1
            g_ray = np.repeat(np.arange(start, end), ns)
            g_idx = np.arange(total_seg) - np.repeat(np.cumsum(ns) - ns, ns)
            ka = first_end[g_ray - start] + g_idx
            kb = ka + 1
            reach = 0.5 * seg_m + step_m
            bound = terrain._ground_bound(0.5 * (ea[ka] + ea[kb]), 0.5 * (eb[ka] + eb[kb]), reach)
            may = bound + top[g_ray] > np.minimum(ec[ka], ec[kb]) - sag + clr
            g_ray, g_idx, ka, kb = g_ray[may], g_idx[may], ka[may], kb[may]
            if len(g_ray):
                # fine samples of the kept segments
                first_k = g_idx * per_seg
                n_in = np.minimum(per_seg, count[g_ray] - first_k)
                f_seg = np.repeat(np.arange(len(g_ray)), n_in)
                k = (np.arange(int(n_in.sum())) - np.repeat(np.cumsum(n_in) - n_in, n_in)
                     + first_k[f_seg])
                rid = g_ray[f_seg]
                s = s_lo[rid] + k * step_m
                sa = e_s[ka[f_seg]]
                sb = e_s[kb[f_seg]]
                f = np.divide(s - sa, sb - sa, out=np.zeros(len(s)), where=sb > sa)
                a0, b0 = ka[f_seg], kb[f_seg]
                a = ea[a0] + (ea[b0] - ea[a0]) * f
                b = eb[a0] + (eb[b0] - eb[a0]) * f
                c = ec[a0] + (ec[b0] - ec[a0]) * f
                t = s / length[rid]
                lift = t * (1.0 - t) * bulge[rid]
                hit = terrain._ground(a, b) + lift > c + clr  # NaN (unknown ground) -> False
                blocked[start:end] = np.bincount(rid[hit] - start, minlength=end - start) > 0
        start = end
    blocked[~finite] = True
    return blocked
