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
from typing import Any, Sequence

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
    """CSR weight matrix of the routing graph, (from, to) -> edge_id and the shortest-path
    predecessors per source node (filled on use), cached on the map."""
    cached = roadmap._routing_csr
    if cached is None:
        rows, cols, length, eid = roadmap.arcs()
        n = roadmap.n_nodes
        # Explicit zeros would read as "no arc": a zero-length road gets a negligible weight.
        w = np.maximum(length, 1e-9)
        from scipy.sparse import csr_matrix   # here: scipy.sparse is slow to import
        csr = csr_matrix((w, (rows, cols)), shape=(n, n))
        edge_of = dict(zip(zip(rows.tolist(), cols.tolist()), eid.tolist()))
        cached = (csr, edge_of, {})
        roadmap._routing_csr = cached
    return cached


def shortest_route(roadmap: RoadMap, start: Any, end: Any, stopovers: Sequence[Any] = (),
                   who: str = "vehicle") -> Route:
    """Shortest route start -> stopovers -> end; RoadMapError names ``who`` and the nodes."""
    refs = [start, *stopovers, end]
    try:
        ids = [roadmap.node_index(r) for r in refs]
    except RoadMapError as exc:
        raise RoadMapError(f"{who}: {exc}") from None
    csr, edge_of, preds = _csr(roadmap)
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
    edge_id = np.asarray([edge_of[(a, b)] for a, b in zip(path[:-1], path[1:])],
                         dtype=np.int64)
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
