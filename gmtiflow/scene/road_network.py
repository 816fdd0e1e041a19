"""The road network a road map loads into: :class:`RoadMap` (tables, routing graph, origin).

Its columns are those of ``/roads/nodes`` and ``/roads/edges`` (docs/tables.md); the loaders
(:mod:`gmtiflow.scene.roadmap`, :mod:`~gmtiflow.scene.osm`, :mod:`~gmtiflow.scene.geojson_roads`)
build it with :meth:`RoadMap.from_lists`.
"""
from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from gmtiflow import frames
from gmtiflow.errors import RoadMapError
from gmtiflow.tables import Table


class RoadMap:
    """Nodes and edges tables, the routing graph, the ENU origin and the data attribution."""

    def __init__(self, origin: frames.Origin, nodes: Table, edges: Table,
                 attribution: str = "", source: str = "road map"):
        self.origin = origin
        self.nodes = nodes
        self.edges = edges
        self.attribution = attribution
        self.source = source
        self._graph = None        # the networkx graph, built on first use (see graph)
        self._arcs = None         # the routing arcs as arrays, built on first use (see arcs)
        self._name_to_id = {str(n): i for i, n in enumerate(nodes["name"])}
        self._xyz = np.column_stack([nodes["x_m"], nodes["y_m"], nodes["z_m"]])
        self._tree = None
        self._routing_csr = None  # built on first use by gmtiflow.scene.routes

    @classmethod
    def from_lists(cls, origin: frames.Origin, names: Sequence[str], xyz_m: np.ndarray,
                   edge_from: Sequence[int], edge_to: Sequence[int], oneway: Sequence[bool],
                   speed_limit_mps: Sequence[float], invisible: Sequence[bool],
                   road_class: Sequence[str], attribution: str = "",
                   source: str = "road map") -> "RoadMap":
        """Build the tables (lengths, geodetic coordinates) from plain lists and check them."""
        xyz = np.asarray(xyz_m, dtype=float).reshape(-1, 3)
        n = len(names)
        if n == 0 or len(edge_from) == 0:
            raise RoadMapError(f"{source}: the road map is empty (no {'roads' if n else 'nodes'}"
                               f" to drive on)")
        if not np.all(np.isfinite(xyz)):
            bad = int(np.flatnonzero(~np.all(np.isfinite(xyz), axis=1))[0])
            raise RoadMapError(f"{source}: node {names[bad]!r} has a non-finite position "
                               f"{xyz[bad].tolist()}")
        if len(set(map(str, names))) != n:
            seen, dup = set(), None
            for name in map(str, names):
                if name in seen:
                    dup = name
                    break
                seen.add(name)
            raise RoadMapError(f"{source}: node name {dup!r} is used twice")
        lat, lon, h = frames.enu_to_geodetic(origin, xyz[:, 0], xyz[:, 1], xyz[:, 2])
        nodes = {
            "node_id": np.arange(n, dtype=np.int64),
            "name": np.asarray([str(s) for s in names], dtype=str),
            "x_m": xyz[:, 0].copy(), "y_m": xyz[:, 1].copy(), "z_m": xyz[:, 2].copy(),
            "lat_deg": np.atleast_1d(lat), "lon_deg": np.atleast_1d(lon),
            "height_m": np.atleast_1d(h),
        }
        f = np.asarray(edge_from, dtype=np.int64)
        t = np.asarray(edge_to, dtype=np.int64)
        edges = {
            "edge_id": np.arange(len(f), dtype=np.int64),
            "from_node": f, "to_node": t,
            "length_m": np.linalg.norm(xyz[t] - xyz[f], axis=1),
            "oneway": np.asarray(oneway, dtype=bool),
            "speed_limit_mps": np.asarray([np.nan if v is None else float(v)
                                           for v in speed_limit_mps], dtype=float),
            "invisible": np.asarray(invisible, dtype=bool),
            "road_class": np.asarray([str(c) for c in road_class], dtype=str),
        }
        return cls(origin, nodes, edges, attribution=attribution, source=source)

    def draped(self, height_at, offset_m: float = 0.0) -> "RoadMap":
        """A copy with every node's z set to ``height_at(x_m, y_m) + offset_m`` (ENU metres).

        ``height_at`` is e.g. ``Terrain.height_at``; edge lengths, geodetic columns and the graph
        are recomputed. Tunnel nodes are draped too (their roads stay invisible).
        """
        n = self.nodes
        z = np.asarray(height_at(n["x_m"], n["y_m"]), dtype=float) + float(offset_m)
        if z.shape != n["x_m"].shape or not np.all(np.isfinite(z)):
            raise RoadMapError(f"{self.source}: height_at returned no finite height for every "
                               f"road node")
        e = self.edges
        xyz = np.column_stack([n["x_m"], n["y_m"], z])
        out = RoadMap.from_lists(self.origin, n["name"].tolist(), xyz, e["from_node"],
                                 e["to_node"], e["oneway"], e["speed_limit_mps"].tolist(),
                                 e["invisible"], e["road_class"].tolist(),
                                 attribution=self.attribution, source=self.source)
        return out

    # -- queries ------------------------------------------------------------------------------
    @property
    def graph(self) -> "nx.DiGraph":
        """The routing graph as a networkx DiGraph (built on first use: importing networkx
        and building the graph cost ~0.1–0.2 s, and routing and the largest component use
        :meth:`arcs`, so a run never needs it)."""
        if self._graph is None:
            self._graph = _build_graph(self.nodes, self.edges)
        return self._graph

    def arcs(self):
        """The routing graph's arcs as arrays ``(from, to, length_m, edge_id)``, in the order
        networkx's ``graph.edges`` lists them (by source node, then insertion): one arc per
        direction a road may be travelled, the first road between a pair wins, no self-loops —
        the arcs of :attr:`graph`, without networkx."""
        if self._arcs is None:
            e = self.edges
            f, t = e["from_node"].astype(np.int64), e["to_node"].astype(np.int64)
            keep = f != t
            both = ~e["oneway"].astype(bool)
            eid = e["edge_id"].astype(np.int64)
            length = e["length_m"].astype(float)
            # Candidates in the order _build_graph adds them: each road forwards, then backwards.
            a = np.column_stack([f, t]).ravel()
            b = np.column_stack([t, f]).ravel()
            ok = np.column_stack([keep, keep & both]).ravel()
            ids = np.repeat(eid, 2)
            ln = np.repeat(length, 2)
            a, b, ids, ln = a[ok], b[ok], ids[ok], ln[ok]
            n = self.n_nodes
            _, first = np.unique(a * n + b, return_index=True)
            first = np.sort(first)                       # insertion order of the kept arcs
            a, b, ids, ln = a[first], b[first], ids[first], ln[first]
            order = np.argsort(a, kind="stable")         # by source, then insertion
            self._arcs = (a[order], b[order], ln[order], ids[order])
        return self._arcs

    @property
    def n_nodes(self) -> int:
        return len(self.nodes["node_id"])

    def node_xyz(self, node_ids) -> np.ndarray:
        """ENU positions (n, 3) of the given node ids."""
        return self._xyz[np.asarray(node_ids, dtype=np.int64)]

    def node_index(self, ref: Any) -> int:
        """Node id of a reference: a node name, an OSM id (int), [x, y] metres or
        {lat_deg, lon_deg} (nearest node)."""
        if ref is None:
            raise RoadMapError(f"{self.source}: a node reference is missing (null)")
        if hasattr(ref, "keys"):
            try:
                ref = frames.point_to_enu(ref, self.origin)[:2]
            except (KeyError, TypeError, ValueError):
                raise RoadMapError(f"{self.source}: node reference {dict(ref)!r} must be "
                                   f"{{lat_deg, lon_deg}}") from None
        if isinstance(ref, (list, tuple)) or (hasattr(ref, "__len__") and
                                                not isinstance(ref, str)):
            vals = list(ref)
            if len(vals) not in (2, 3):
                raise RoadMapError(f"{self.source}: node reference {vals!r} must be a name, an "
                                   f"OSM id or [x, y] in metres")
            try:
                xy = np.asarray([float(vals[0]), float(vals[1])])
            except (TypeError, ValueError):
                raise RoadMapError(f"{self.source}: node reference {vals!r} is not [x, y] in "
                                   f"metres") from None
            if self._tree is None:
                from scipy.spatial import cKDTree
                self._tree = cKDTree(self._xyz[:, :2])
            return int(self._tree.query(xy)[1])
        if isinstance(ref, float) and ref.is_integer():
            ref = int(ref)
        key = str(ref)
        if key not in self._name_to_id:
            raise RoadMapError(f"{self.source}: unknown node {ref!r} (not a node name or OSM id "
                               f"of this road map)")
        return self._name_to_id[key]

    def largest_component(self) -> np.ndarray:
        """Node ids of the largest strongly connected component (sorted)."""
        from scipy.sparse import csr_matrix
        from scipy.sparse.csgraph import connected_components
        a, b, _, _ = self.arcs()
        n = self.n_nodes
        adj = csr_matrix((np.ones(len(a)), (a, b)), shape=(n, n))
        _, labels = connected_components(adj, directed=True, connection="strong")
        size = np.bincount(labels)
        first = np.full(len(size), n, dtype=np.int64)
        np.minimum.at(first, labels, np.arange(n, dtype=np.int64))
        # The largest; between equal sizes the one with the smallest node id.
        best = max(range(len(size)), key=lambda c: (int(size[c]), -int(first[c])))
        return np.flatnonzero(labels == best).astype(np.int64)


def _build_graph(nodes: Table, edges: Table) -> "nx.DiGraph":
    """Directed routing graph: both directions unless oneway; the first road between a pair wins."""
    import networkx as nx
    g = nx.DiGraph()
    g.add_nodes_from(range(len(nodes["node_id"])))
    for eid, f, t, length, one in zip(edges["edge_id"].tolist(), edges["from_node"].tolist(),
                                      edges["to_node"].tolist(), edges["length_m"].tolist(),
                                      edges["oneway"].tolist()):
        if f == t:
            continue
        for a, b in ((f, t),) if one else ((f, t), (t, f)):
            if not g.has_edge(a, b):
                g.add_edge(a, b, length_m=length, edge_id=eid)
    return g
