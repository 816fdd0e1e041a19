"""Routes: shortest paths on the road graph, as polylines with arc length (paper §3, DESIGN §3).

Dijkstra with the Euclidean 3-D road length as weight, from the start through the stopovers to
the end. The search runs on a CSR matrix of the road graph's arcs (``RoadMap.arcs``) with ``scipy.sparse.csgraph.dijkstra``
(compiled; networkx's pure-Python Dijkstra took 10 ms a route on Monaco, 10 s for 1,000
vehicles); the tests check it against networkx and brute force. A :class:`Route` is a
polyline: node positions, cumulative arc length, and per segment the road's edge id, invisible
flag and speed limit. Off-road vehicles get a route from their waypoints (edge id -1, visible,
no limit).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from itertools import chain
from typing import Any, List, Optional, Sequence

import numpy as np

from gmtiflow.errors import RoadMapError
from gmtiflow.scene.roadmap import RoadMap


@dataclass(frozen=True)
class Route:
    """A polyline route.

    Attributes:
        node_ids: road node ids along the route (n,), -1 for off-road waypoints.
        xyz_m: vertex positions (n, 3), ENU metres.
        s_m: cumulative arc length at each vertex (n,), s_m[0] = 0.
        edge_id: road edge of each segment (n-1,), -1 off-road.
        invisible: per segment (n-1,).
        speed_limit_mps: per segment (n-1,), NaN = none.
    """

    node_ids: np.ndarray
    xyz_m: np.ndarray
    s_m: np.ndarray
    edge_id: np.ndarray
    invisible: np.ndarray
    speed_limit_mps: np.ndarray

    @property
    def length_m(self) -> float:
        return float(self.s_m[-1])

    def position_at(self, s_m) -> np.ndarray:
        """Points (…, 3) on the polyline at arc lengths ``s_m`` (clipped to the route)."""
        s = np.clip(np.asarray(s_m, float), 0.0, self.length_m)
        j = np.clip(np.searchsorted(self.s_m, s, side="right") - 1, 0, len(self.s_m) - 2)
        seg = self.s_m[j + 1] - self.s_m[j]
        f = np.where(seg > 0, (s - self.s_m[j]) / np.where(seg > 0, seg, 1.0), 0.0)
        return self.xyz_m[j] + f[..., None] * (self.xyz_m[j + 1] - self.xyz_m[j])


def _seg_lengths(xyz: np.ndarray) -> np.ndarray:
    """Euclidean length of each segment of a polyline (n, 3) (np.linalg.norm's sum of
    squares, without its overhead)."""
    d = xyz[1:] - xyz[:-1]
    return np.sqrt(np.add.reduce(d * d, axis=1))


def _polyline(xyz: np.ndarray):
    return np.concatenate([[0.0], np.cumsum(_seg_lengths(xyz))])


def _csr(roadmap: RoadMap):
    """CSR weight matrix of the routing graph, its arcs' keys ``from * n + to`` (ascending)
    with the edge id of each, and the shortest-path predecessors per source node (filled on
    use), cached on the map."""
    cached = roadmap._routing_csr
    if cached is None:
        rows, cols, length, eid = roadmap.arcs()
        n = roadmap.n_nodes
        # Explicit zeros would read as "no arc": a zero-length road gets a negligible weight.
        w = np.maximum(length, 1e-9)
        from scipy.sparse import csr_matrix   # here: scipy.sparse is slow to import
        csr = csr_matrix((w, (rows, cols)), shape=(n, n))
        key = rows * n + cols                 # one arc per (from, to): unique keys
        order = np.argsort(key)
        cached = (csr, (key[order], eid[order]), {})
        roadmap._routing_csr = cached
    return cached


def _edge_ids(arcs, n_nodes: int, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The edge id of each arc ``a[i] -> b[i]`` of the routing graph (each one an arc of it):
    a binary search in the arcs' sorted keys."""
    key, eid = arcs
    return eid[np.searchsorted(key, a * n_nodes + b)]


def shortest_route(roadmap: RoadMap, start: Any, end: Any, stopovers: Sequence[Any] = (),
                   who: str = "vehicle") -> Route:
    """Shortest route start -> stopovers -> end; RoadMapError names ``who`` and the nodes."""
    refs = [start, *stopovers, end]
    try:
        ids = [roadmap.node_index(r) for r in refs]
    except RoadMapError as exc:
        raise RoadMapError(f"{who}: {exc}") from None
    csr, arcs, preds = _csr(roadmap)
    path = [ids[0]]
    for a, b in zip(ids[:-1], ids[1:]):
        if a == b:
            continue
        pred = preds.get(a)
        if pred is None:    # one search per source node, shared by the vehicles leaving it
            from scipy.sparse.csgraph import dijkstra
            pred = preds[a] = dijkstra(csr, directed=True, indices=a,
                                       return_predecessors=True)[1]
        if pred[b] < 0:
            names = roadmap.nodes["name"]
            raise RoadMapError(f"{who}: no route from node {str(names[a])!r} to node "
                               f"{str(names[b])!r} on {roadmap.source} (unreachable: oneway "
                               f"roads or disconnected parts)")
        leg = [b]
        while leg[-1] != a:
            leg.append(int(pred[leg[-1]]))
        path.extend(leg[-2::-1])
    if len(path) < 2:
        names = roadmap.nodes["name"]
        raise RoadMapError(f"{who}: start {str(names[ids[0]])!r} and end "
                           f"{str(names[ids[-1]])!r} are the same node; the route would be empty")
    node_ids = np.asarray(path, dtype=np.int64)
    edge_id = _edge_ids(arcs, roadmap.n_nodes, node_ids[:-1], node_ids[1:])
    xyz = roadmap.node_xyz(node_ids)
    return Route(node_ids=node_ids, xyz_m=xyz, s_m=_polyline(xyz), edge_id=edge_id,
                 invisible=roadmap.edges["invisible"][edge_id].copy(),
                 speed_limit_mps=roadmap.edges["speed_limit_mps"][edge_id].copy())


def off_road_route(waypoints_m: Sequence[Sequence[float]], who: str = "vehicle") -> Route:
    """A route through off-road waypoints [x, y] or [x, y, z] (ENU m, z default 0)."""
    pts = []
    for p in waypoints_m:
        vals = [float(c) for c in p]
        if len(vals) == 2:
            vals.append(0.0)
        if len(vals) != 3 or not all(map(math.isfinite, vals)):
            raise RoadMapError(f"{who}: off_road waypoint {list(p)!r} must be [x, y] or "
                               f"[x, y, z] in finite metres")
        pts.append(vals)
    xyz = np.asarray(pts, dtype=float).reshape(-1, 3)
    if len(xyz) < 2:
        raise RoadMapError(f"{who}: off_road needs at least two waypoints")
    seg = _seg_lengths(xyz)
    if not seg.all():           # coinciding waypoints: dropped
        xyz = xyz[np.concatenate([[True], seg > 0])]
        if len(xyz) < 2:
            raise RoadMapError(f"{who}: off_road waypoints all coincide; the route would be "
                               f"empty")
        seg = _seg_lengths(xyz)
    n = len(xyz)
    return Route(node_ids=np.full(n, -1, dtype=np.int64), xyz_m=xyz,
                 s_m=np.concatenate([[0.0], np.cumsum(seg)]),
                 edge_id=np.full(n - 1, -1, dtype=np.int64),
                 invisible=np.zeros(n - 1, dtype=bool),
                 speed_limit_mps=np.full(n - 1, np.nan))


def _routes_from_flat(xyz: np.ndarray, offset: np.ndarray, node_ids: np.ndarray,
                      edge_id: np.ndarray, invisible: np.ndarray,
                      speed_limit_mps: np.ndarray) -> List[Route]:
    """Routes whose vertices are the rows ``offset[i]:offset[i + 1]`` of flat vertex arrays
    and whose segments are the rows ``offset[i] - i:offset[i + 1] - i - 1`` of flat segment
    arrays: the arc lengths of each route by its own cumulative sum (as :func:`_polyline`;
    the routes with the same number of vertices at once, one row each)."""
    offset = np.asarray(offset, np.int64)
    n_v = np.diff(offset)
    seg = _seg_lengths(xyz)          # vertex i to i + 1 (across routes at their last vertex)
    s = np.empty(len(xyz))
    s[offset[:-1]] = 0.0
    for n_b in np.unique(n_v).tolist():
        first = offset[:-1][n_v == n_b]
        cells = first[:, None] + np.arange(n_b - 1)
        s[cells + 1] = np.cumsum(seg[cells], axis=1)
    out = []
    for i, (a, b) in enumerate(zip(offset[:-1].tolist(), offset[1:].tolist())):
        out.append(Route(node_ids=node_ids[a:b], xyz_m=xyz[a:b], s_m=s[a:b],
                         edge_id=edge_id[a - i:b - i - 1], invisible=invisible[a - i:b - i - 1],
                         speed_limit_mps=speed_limit_mps[a - i:b - i - 1]))
    return out


def shortest_routes(roadmap: RoadMap, starts: Sequence[Any], ends: Sequence[Any]
                    ) -> List[Optional[Route]]:
    """``shortest_route(roadmap, start, end)`` of many vehicles at once, the same routes: each
    node reference resolved once, one Dijkstra call for all new source nodes, the vertices of
    all routes gathered at once.  None where :func:`shortest_route` raises (unknown or equal
    nodes, no route): the caller asks it for that vehicle's error."""
    names: dict = {}
    ids = []
    for ref in list(starts) + list(ends):
        key = (type(ref), ref) if isinstance(ref, (str, int)) else None
        if key is not None and key in names:
            ids.append(names[key])
            continue
        try:
            i = roadmap.node_index(ref)
        except Exception:       # noqa: BLE001 - shortest_route raises it for that vehicle
            i = None
        if key is not None:
            names[key] = i
        ids.append(i)
    n = len(starts)
    src, dst = ids[:n], ids[n:]
    csr, arcs, preds = _csr(roadmap)
    new = sorted({a for a, b in zip(src, dst)
                  if a is not None and b is not None and a != b and a not in preds})
    if new:
        from scipy.sparse.csgraph import dijkstra
        # sources in groups: the call's distance matrix (freed after it) stays <= 32 MB
        step = max(1, 4_000_000 // max(roadmap.n_nodes, 1))
        for c in range(0, len(new), step):
            part = new[c:c + step]
            rows = dijkstra(csr, directed=True, indices=np.asarray(part, np.int64),
                            return_predecessors=True)[1]
            preds.update(zip(part, rows))
    good = [a is not None and b is not None and a != b and preds[a][b] >= 0
            for a, b in zip(src, dst)]
    if not any(good):
        return [None] * n
    a_ok = np.asarray([a for a, g in zip(src, good) if g], np.int64)
    b_ok = np.asarray([b for b, g in zip(dst, good) if g], np.int64)
    node_ids, offset = _walk_paths(preds, a_ok, b_ok, roadmap.n_nodes)
    inner = np.ones(len(node_ids) - 1, bool)     # the steps within a route, not between two
    inner[offset[1:-1] - 1] = False
    edge_id = _edge_ids(arcs, roadmap.n_nodes, node_ids[:-1][inner], node_ids[1:][inner])
    routes = iter(_routes_from_flat(roadmap.node_xyz(node_ids), offset, node_ids, edge_id,
                                    roadmap.edges["invisible"][edge_id],
                                    roadmap.edges["speed_limit_mps"][edge_id]))
    return [next(routes) if g else None for g in good]


#: Predecessor entries (sources x nodes) walked at once by :func:`_walk_paths`: its stacked
#: copy of their rows stays <= 16 MB (int32) on a large map; the default scene's 59 nodes
#: take every source at once.
_WALK_ENTRIES = 4_000_000


def _walk_paths(preds: dict, src: np.ndarray, dst: np.ndarray, n_nodes: int):
    """The node paths ``src[i] -> dst[i]`` (each reachable, src != dst) from the predecessor
    rows ``preds[src]`` (of ``n_nodes`` each), end to end in one array, and each path's first
    index (``offset``, one more): the paths of a group of sources walked back from their ends
    at once, one gather a step (the longest path's number of steps), not node by node
    (1,000 random vehicles on the default scene: routing 5.0 -> 3.6 ms)."""
    uniq, row = np.unique(src, return_inverse=True)
    per = max(1, _WALK_ENTRIES // max(n_nodes, 1))
    walks = []
    for c in range(0, len(uniq), per):
        pred = np.stack([preds[a] for a in uniq[c:c + per].tolist()])
        idx = np.flatnonzero((row >= c) & (row < c + per))
        r, a, cur = row[idx] - c, src[idx], dst[idx]
        back = [cur]            # back[t][i]: node t steps before the end of path idx[i]
        while True:
            on = cur != a
            if not on.any():
                break
            cur = np.where(on, pred[r, cur], cur)
            back.append(cur)
        walks.append((idx, np.stack(back)))
    count = np.empty(len(src), np.int64)         # nodes per path (its start counted once)
    for idx, back in walks:
        count[idx] = (back != src[idx]).sum(axis=0) + 1
    offset = np.concatenate([[0], np.cumsum(count)]).astype(np.int64)
    nodes = np.empty(offset[-1], np.int64)
    for idx, back in walks:
        n_i = count[idx]
        path = np.repeat(np.arange(len(idx)), n_i)
        pos = np.arange(len(path)) - np.repeat(np.cumsum(n_i) - n_i, n_i)  # along its path
        nodes[offset[idx][path] + pos] = back[n_i[path] - 1 - pos, path]
    return nodes, offset


def off_road_routes(waypoints: Sequence[Sequence[Sequence[float]]]) -> List[Optional[Route]]:
    """``off_road_route(w)`` of many waypoint lists at once, the same routes; None where it
    would raise or drop coinciding waypoints (the caller asks it for that vehicle)."""
    stacked = _stacked_waypoints(waypoints)
    if stacked is not None:
        xyz, counts = stacked
        ok = [True] * len(counts)
    else:
        xyz, counts, ok = _converted_waypoints(waypoints)
    if not counts:
        return [None] * len(ok)
    offset = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    seg = _seg_lengths(xyz)
    zero = seg == 0
    zero[offset[1:-1] - 1] = False           # the steps from one route to the next
    n = len(xyz)
    n_r = len(counts)
    routes = _routes_from_flat(xyz, offset, np.full(n, -1, dtype=np.int64),
                               np.full(n - n_r, -1, dtype=np.int64), np.zeros(n - n_r, bool),
                               np.full(n - n_r, np.nan))
    if zero.any():                           # coinciding waypoints: those routes one by one
        bad = set((np.searchsorted(offset, np.flatnonzero(zero), side="right") - 1).tolist())
        routes = [None if i in bad else r for i, r in enumerate(routes)]
    it = iter(routes)
    return [next(it) if g else None for g in ok]


def _stacked_waypoints(waypoints) -> Optional[tuple]:
    """``(xyz, counts)``: the vertices (n, 3) of every waypoint list, end to end, and the
    length of each, read in bulk (a few C calls for thousands of vehicles), when :func:`
    off_road_route` accepts every list as it is: at least two waypoints each, every waypoint
    a list (or tuple) of finite ints and floats, all [x, y] (z = 0) or all [x, y, z].  None
    otherwise (:func:`_converted_waypoints` then reads them one by one)."""
    counts = list(map(len, waypoints))
    if not counts or min(counts) < 2:
        return None
    points = list(chain.from_iterable(waypoints))
    widths = set(map(len, points)) if set(map(type, points)) <= {list, tuple} else None
    if widths not in ({2}, {3}):
        return None
    coordinates = list(chain.from_iterable(points))
    if not set(map(type, coordinates)) <= {int, float}:
        return None
    try:
        values = np.fromiter(coordinates, float, len(coordinates))
    except OverflowError:                    # an int too large for a float
        return None
    width = widths.pop()
    if not np.isfinite(values).all():
        return None
    if width == 3:
        return values.reshape(-1, 3), counts
    xyz = np.zeros((len(points), 3))
    xyz[:, :2] = values.reshape(-1, 2)
    return xyz, counts


def _converted_waypoints(waypoints) -> tuple:
    """``(xyz, counts, ok)``: as :func:`_stacked_waypoints`, each waypoint converted as
    :func:`off_road_route` converts it, for the lists it accepts (``ok``), the others left
    out."""
    pts, counts, ok = [], [], []
    for w in waypoints:
        vals = []
        good = len(w) >= 2
        try:
            for p in w if good else ():
                v = [float(c) for c in p]
                if len(v) == 2:
                    v.append(0.0)
                if len(v) != 3:
                    good = False
                    break
                vals.extend(v)
        except (TypeError, ValueError):
            good = False
        good = good and all(map(math.isfinite, vals))
        ok.append(good)
        if good:
            pts.extend(vals)
            counts.append(len(vals) // 3)
    return np.asarray(pts, dtype=float).reshape(-1, 3), counts, ok
