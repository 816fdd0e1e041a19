"""Plane geometry of clutter regions: circles, rings and polygons in the scene's ENU (x, y) metres.

Pure, vectorised helpers used by :mod:`gmtiflow.sensor.clutter`:

* :func:`polygon_area_m2` — shoelace formula (absolute value, either winding);
* :func:`polygon_self_intersects` — any two non-adjacent edges cross or touch (O(k²) in the
  number of vertices k, which is small for config polygons);
* :func:`points_in_polygon` — even-odd (crossing-number) rule, vectorised over points, and over
  *one polygon per point* (:func:`points_in_polygons`) so that many dwell footprints are tested
  in one call;
* uniform samplers for a disc, a ring and a bounding box, driven by given uniforms (the caller
  owns the randomness, see :mod:`gmtiflow.rng`).

Boundary convention of the point-in-polygon test: the half-open crossing-number rule, so a point
exactly on an edge is inside for some edges and outside for others; the boundary has zero area
and never matters for uniformly drawn points.
"""
from __future__ import annotations

import numpy as np


def as_polygon(vertices_m) -> np.ndarray:
    """Vertices as a float (k, 2) array, without a repeated closing vertex."""
    v = np.asarray(vertices_m, dtype=float)
    if v.ndim != 2 or v.shape[1] != 2:
        raise ValueError(f"polygon vertices must be a (k, 2) array of [x, y] metres, got shape {v.shape}")
    if len(v) > 1 and np.array_equal(v[0], v[-1]):
        v = v[:-1]
    return v


def polygon_area_m2(vertices_m) -> float:
    """Area of a simple polygon (shoelace formula), m², independent of the winding."""
    v = as_polygon(vertices_m)
    if len(v) < 3:
        return 0.0
    x, y = v[:, 0], v[:, 1]
    # Centre first: the shoelace sum of large coordinates loses digits otherwise.
    x = x - x.mean()
    y = y - y.mean()
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


def _orient(ax, ay, bx, by, cx, cy):
    """Sign of the cross product (b - a) x (c - a): +1 left turn, -1 right turn, 0 collinear."""
    return np.sign((bx - ax) * (cy - ay) - (by - ay) * (cx - ax))


def polygon_self_intersects(vertices_m) -> bool:
    """True if any two non-adjacent edges of the closed polygon intersect or touch.

    Adjacent edges share a vertex and are not compared, except that a zero-length edge
    (repeated vertex) or a vertex visited twice also counts as self-intersection.
    """
    v = as_polygon(vertices_m)
    k = len(v)
    if k < 3:
        return False
    a = v
    b = np.roll(v, -1, axis=0)
    if np.any(np.all(a == b, axis=1)):
        return True  # repeated consecutive vertex: a degenerate edge
    if len(np.unique(v, axis=0)) < k:
        return True  # a vertex visited twice: the boundary touches itself
    i, j = np.triu_indices(k, k=2)
    keep = ~((i == 0) & (j == k - 1))  # first and last edges are adjacent (share vertex 0)
    i, j = i[keep], j[keep]
    if len(i) == 0:
        return False
    p1x, p1y, p2x, p2y = a[i, 0], a[i, 1], b[i, 0], b[i, 1]
    q1x, q1y, q2x, q2y = a[j, 0], a[j, 1], b[j, 0], b[j, 1]
    o1 = _orient(p1x, p1y, p2x, p2y, q1x, q1y)
    o2 = _orient(p1x, p1y, p2x, p2y, q2x, q2y)
    o3 = _orient(q1x, q1y, q2x, q2y, p1x, p1y)
    o4 = _orient(q1x, q1y, q2x, q2y, p2x, p2y)
    proper = (o1 * o2 < 0) & (o3 * o4 < 0)

    def on_segment(ax, ay, bx, by, cx, cy):  # c collinear with a-b lies within its box
        return ((np.minimum(ax, bx) <= cx) & (cx <= np.maximum(ax, bx))
                & (np.minimum(ay, by) <= cy) & (cy <= np.maximum(ay, by)))

    touch = (((o1 == 0) & on_segment(p1x, p1y, p2x, p2y, q1x, q1y))
             | ((o2 == 0) & on_segment(p1x, p1y, p2x, p2y, q2x, q2y))
             | ((o3 == 0) & on_segment(q1x, q1y, q2x, q2y, p1x, p1y))
             | ((o4 == 0) & on_segment(q1x, q1y, q2x, q2y, p2x, p2y)))
    return bool(np.any(proper | touch))


def points_in_polygon(x_m, y_m, vertices_m) -> np.ndarray:
    """Boolean mask of points inside one polygon (even-odd rule), vectorised over points."""
    v = as_polygon(vertices_m)
    x = np.asarray(x_m, dtype=float)
    y = np.asarray(y_m, dtype=float)
    inside = np.zeros(np.broadcast(x, y).shape, dtype=bool)
    k = len(v)
    for e in range(k):  # loop over the (few) edges, vectorised over the points
        x1, y1 = v[e]
        x2, y2 = v[(e + 1) % k]
        if y1 == y2:
            continue  # a horizontal edge never crosses a horizontal ray (half-open rule)
        crosses = (y1 > y) != (y2 > y)
        x_cross = x1 + (y - y1) * (x2 - x1) / (y2 - y1)
        inside ^= crosses & (x < x_cross)
    return inside


def points_in_polygons(x_m, y_m, polygons_m: np.ndarray, which: np.ndarray) -> np.ndarray:
    """Point i inside polygon ``polygons_m[which[i]]`` (even-odd rule), for many polygons at once.

    ``polygons_m`` is a (n_poly, k, 2) array; polygons with fewer vertices are padded by repeating
    their last vertex (zero-length edges cross nothing), see :func:`stack_polygons`.
    """
    x = np.asarray(x_m, dtype=float)
    y = np.asarray(y_m, dtype=float)
    polys = np.asarray(polygons_m, dtype=float)
    which = np.asarray(which, dtype=np.int64)
    inside = np.zeros(x.shape, dtype=bool)
    if x.size == 0:
        return inside
    k = polys.shape[1]
    for e in range(k):
        p1 = polys[which, e]
        p2 = polys[which, (e + 1) % k]
        x1, y1, x2, y2 = p1[:, 0], p1[:, 1], p2[:, 0], p2[:, 1]
        crosses = (y1 > y) != (y2 > y)
        dy = np.where(crosses, y2 - y1, 1.0)  # no division by zero where the edge is not crossed
        x_cross = x1 + (y - y1) * (x2 - x1) / dy
        inside ^= crosses & (x < x_cross)
    return inside


def stack_polygons(polygons) -> np.ndarray:
    """A list of (k_i, 2) polygons -> one (n, max k_i, 2) array, short ones padded by their last vertex."""
    if isinstance(polygons, np.ndarray) and polygons.ndim == 3:
        return polygons.astype(float, copy=False)
    polys = [as_polygon(p) for p in polygons]
    if not polys:
        return np.zeros((0, 3, 2))
    k = max(len(p) for p in polys)
    out = np.empty((len(polys), k, 2))
    for n, p in enumerate(polys):  # one iteration per dwell footprint, not per point
        out[n, :len(p)] = p
        out[n, len(p):] = p[-1]
    return out


def bounding_box(vertices_m) -> tuple[float, float, float, float]:
    """(x_min, y_min, x_max, y_max) of a polygon."""
    v = as_polygon(vertices_m)
    return float(v[:, 0].min()), float(v[:, 1].min()), float(v[:, 0].max()), float(v[:, 1].max())


def sample_disc(u1, u2, centre_m, inner_radius_m: float, outer_radius_m: float):
    """Map uniforms (0,1) to points uniform in the ring inner <= r < outer (inner = 0: a disc).

    Uniform in area: r² uniform in [inner², outer²), angle uniform in [0, 2π).
    """
    r = np.sqrt(inner_radius_m ** 2 + np.asarray(u1) * (outer_radius_m ** 2 - inner_radius_m ** 2))
    theta = 2.0 * np.pi * np.asarray(u2)
    return centre_m[0] + r * np.sin(theta), centre_m[1] + r * np.cos(theta)


def ring_area_m2(inner_radius_m: float, outer_radius_m: float) -> float:
    """Area of the ring inner <= r < outer, m² (inner = 0: a disc)."""
    return float(np.pi * (outer_radius_m ** 2 - inner_radius_m ** 2))
