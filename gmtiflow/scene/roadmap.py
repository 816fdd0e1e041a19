"""Road network: crossroads (nodes) and straight roads between them (paper §2–3, DESIGN §3).

A :class:`RoadMap` holds

* ``nodes`` and ``edges`` tables with exactly the columns of ``/roads/nodes`` and
  ``/roads/edges`` in ``docs/tables.md``;
* ``graph``: a :class:`networkx.DiGraph` over ``node_id`` with one directed arc per direction a
  road may be travelled (a oneway road only ``from_node -> to_node``), arc attributes
  ``length_m`` (Euclidean 3-D length, the Dijkstra weight of the paper) and ``edge_id``;
* ``origin`` (:class:`gmtiflow.frames.Origin`) of the ENU frame, and ``attribution``.

Curves are chains of nodes, as in the paper and in vector road maps; an inline road's ``via``
points become such intermediate nodes (named ``"<from>~<to>#<i>"``).

Loaders (chosen by :attr:`RoadmapConfig.kind`):

* ``default``: the built-in demonstration town (:func:`default_scene_config`);
* ``inline``: nodes and roads written in the config;
* ``osm``: OpenStreetMap XML (:mod:`gmtiflow.scene.osm`);
* ``geojson``: GeoJSON LineStrings (:mod:`gmtiflow.scene.geojson_roads`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum
from typing import TYPE_CHECKING, Any, Dict, List, Optional, Sequence

import numpy as np

from gmtiflow import frames, schema
from gmtiflow.errors import RoadMapError
from gmtiflow.tables import Table

if TYPE_CHECKING:     # networkx is imported where a graph is built (start-up time)
    import networkx as nx

OSM_ATTRIBUTION = "© OpenStreetMap contributors"

#: Lake of the default scene (ENU metres, counter-clockwise): no default road enters it, and
#: clutter configs may point a lake-wave region at it.
DEFAULT_LAKE_POLYGON_M = [[1500.0, 1500.0], [3500.0, 1200.0], [4200.0, 2500.0],
                          [3000.0, 3500.0], [1600.0, 3000.0]]

#: Origin of the default scene (WGS-84).
DEFAULT_ORIGIN = frames.Origin(50.63, 7.13, 150.0)

#: OSM highway classes a vehicle may drive on (all others, e.g. footway, steps, path,
#: cycleway, pedestrian, track, bridleway, are dropped).
DRIVABLE_HIGHWAY_CLASSES = [
    "motorway", "motorway_link", "trunk", "trunk_link", "primary", "primary_link",
    "secondary", "secondary_link", "tertiary", "tertiary_link", "unclassified", "residential",
    "living_street", "service", "road",
]


class RoadmapKind(Enum):
    """Where the road map comes from."""

    default = "default"
    inline = "inline"
    osm = "osm"
    geojson = "geojson"


@dataclass
class RoadSpec:
    """One inline road from node ``from_node`` to node ``to_node``.

    ``from``/``to`` are Python keywords, hence ``from_node``/``to_node`` (the names of the
    ``/roads/edges`` columns). ``via``: intermediate curve points [x, y] or [x, y, z] (ENU m).
    """

    from_node: str = "???"
    to_node: str = "???"
    oneway: bool = False
    speed_limit_mps: Optional[float] = None
    invisible: bool = False
    road_class: str = "road"
    via: List[Any] = field(default_factory=list)     # [[x, y(, z)], ...]: see schema.point_problems

    def problems(self) -> List[schema.Problem]:
        out = schema.positive(self, "speed_limit_mps")
        for i, point in enumerate(self.via):
            out += schema.point_problems(f"via[{i}]", point, geodetic=True)
        return out


@dataclass
class RoadmapConfig:
    """Schema of the ``roadmap`` config group.

    Fields:
        kind: default | inline | osm | geojson.
        path: road map file (osm, geojson).
        origin_lat_deg, origin_lon_deg, origin_height_m: ENU origin (WGS-84). ``None`` = the
            default scene's origin (50.63 N, 7.13 E, 150 m) for default/inline maps, and for
            files the centre of the OSM ``<bounds>`` (or of the road nodes) at height 0.
        nodes: inline nodes, name -> [x, y, z] (ENU m; z may be omitted = 0).
        roads: inline roads (:class:`RoadSpec`).
        drivable_classes: OSM/GeoJSON ``highway`` values kept (GeoJSON features without a
            ``highway`` property are always kept).
        implied_oneway: treat ``highway=motorway`` and ``junction=roundabout`` as oneway unless
            tagged ``oneway=no`` (OSM convention).
        merge_decimals: GeoJSON vertices whose lon/lat agree to this many decimals are one node.
        attribution: credit line for outputs; ``None`` = automatic ("© OpenStreetMap
            contributors" for OSM files, "" otherwise).
    """

    kind: RoadmapKind = RoadmapKind.default
    path: Optional[str] = None
    origin_lat_deg: Optional[float] = None
    origin_lon_deg: Optional[float] = None
    origin_height_m: Optional[float] = None
    nodes: Dict[str, Any] = field(default_factory=dict)   # name -> [x, y(, z)] metres
    roads: List[RoadSpec] = field(default_factory=list)
    drivable_classes: List[str] = field(default_factory=lambda: list(DRIVABLE_HIGHWAY_CLASSES))
    implied_oneway: bool = True
    merge_decimals: int = 7
    attribution: Optional[str] = None

    def problems(self) -> List[schema.Problem]:
        out = schema.in_range(self, "origin_lat_deg", -90.0, 90.0)
        out += schema.in_range(self, "origin_lon_deg", -180.0, 180.0)
        out += schema.in_range(self, "origin_height_m", -1000.0, 10000.0)
        out += schema.in_range(self, "merge_decimals", 0, 12)
        kind = RoadmapKind(self.kind)
        if kind in (RoadmapKind.osm, RoadmapKind.geojson) and not schema.optional_path(self.path):
            label = "an OSM" if kind == RoadmapKind.osm else "a GeoJSON"
            out.append(schema.Problem("path", f"{label} road map needs a file path, e.g. "
                                              f"roadmap.path=/data/map.{kind.value}"))
        if kind == RoadmapKind.inline:
            if not self.nodes or not self.roads:
                out.append(schema.Problem("roads", "an inline road map needs at least one node "
                                                   "and one road"))
            for name, xyz in self.nodes.items():
                out += schema.point_problems(f"nodes.{name}", xyz, geodetic=True)
            for i, road in enumerate(self.roads):
                out += schema.prefixed(f"roads[{i}]", road.problems())
                for end in ("from_node", "to_node"):
                    ref = getattr(road, end)
                    if str(ref) not in self.nodes:
                        out.append(schema.Problem(f"roads[{i}].{end}",
                                                  f"unknown node {ref!r}"))
        return out


# --------------------------------------------------------------------------------------------
class RoadMap:
    """Nodes and edges tables, the routing graph, the ENU origin and the data attribution."""

    def __init__(self, origin: frames.Origin, nodes: Table, edges: Table,
                 attribution: str = "", source: str = "road map"):
        self.origin = origin
        self.nodes = nodes
        self.edges = edges
        self.attribution = attribution
        self.source = source
        self.graph = _build_graph(nodes, edges)
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
        import networkx as nx
        comps = nx.strongly_connected_components(self.graph)
        best = max(comps, key=lambda c: (len(c), -min(c)))
        return np.asarray(sorted(best), dtype=np.int64)


def _build_graph(nodes: Table, edges: Table) -> nx.DiGraph:
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


# --------------------------------------------------------------------------------------------
def load_roadmap(cfg: RoadmapConfig) -> RoadMap:
    """The road map the config asks for (raises RoadMapError / InputFileError on bad input)."""
    roadmap = _load(cfg)
    if cfg.attribution is not None:
        roadmap.attribution = str(cfg.attribution)
    return roadmap


def _load(cfg: RoadmapConfig) -> RoadMap:
    kind = RoadmapKind(cfg.kind)
    if kind == RoadmapKind.default:
        return from_inline(default_scene_config(), source="default scene")
    if kind == RoadmapKind.inline:
        return from_inline(cfg, source="roadmap (inline)")
    if kind == RoadmapKind.osm:
        from gmtiflow.scene.osm import load_osm
        return load_osm(cfg.path, cfg)
    if kind == RoadmapKind.geojson:
        from gmtiflow.scene.geojson_roads import load_geojson
        return load_geojson(cfg.path, cfg)
    raise RoadMapError(f"roadmap.kind: unknown kind {cfg.kind!r}")  # pragma: no cover


def _origin(cfg: RoadmapConfig, fallback: frames.Origin) -> frames.Origin:
    return frames.Origin(
        fallback.lat_deg if cfg.origin_lat_deg is None else float(cfg.origin_lat_deg),
        fallback.lon_deg if cfg.origin_lon_deg is None else float(cfg.origin_lon_deg),
        fallback.height_m if cfg.origin_height_m is None else float(cfg.origin_height_m))


def from_inline(cfg: RoadmapConfig, source: str = "roadmap (inline)") -> RoadMap:
    """A road map from inline nodes and roads (``via`` points become chain nodes)."""
    if not cfg.nodes or not cfg.roads:
        raise RoadMapError(f"{source}: the road map is empty (it needs nodes and roads)")
    names: List[str] = []
    xyz: List[List[float]] = []
    index: Dict[str, int] = {}
    origin = _origin(cfg, DEFAULT_ORIGIN)

    def add_node(name: str, point) -> int:
        try:        # [x, y(, z)] metres or {lat_deg, lon_deg, height_m} (frames.point_to_enu)
            vals = frames.point_to_enu(point, origin)
        except (KeyError, TypeError, ValueError):
            raise RoadMapError(f"{source}: node {name!r} must be [x, y], [x, y, z] in metres or "
                               f"{{lat_deg, lon_deg, height_m}}, got {point!r}") from None
        if len(vals) == 2:
            vals.append(0.0)
        if len(vals) != 3 or not all(math.isfinite(v) for v in vals):
            raise RoadMapError(f"{source}: node {name!r} must be [x, y] or [x, y, z] in finite "
                               f"metres, got {list(point)!r}")
        index[name] = len(names)
        names.append(name)
        xyz.append(vals)
        return index[name]

    for name, point in cfg.nodes.items():
        add_node(str(name), point)
    ef, et, one, lim, inv, cls = [], [], [], [], [], []
    for i, road in enumerate(cfg.roads):
        a, b = str(road.from_node), str(road.to_node)
        for end, ref in (("from_node", a), ("to_node", b)):
            if ref not in index:
                raise RoadMapError(f"{source}: roads[{i}].{end}: unknown node {ref!r}")
        if road.speed_limit_mps is not None and not (road.speed_limit_mps > 0):
            raise RoadMapError(f"{source}: roads[{i}].speed_limit_mps must be > 0, got "
                               f"{road.speed_limit_mps!r}")
        chain = [index[a]]
        for j, point in enumerate(road.via):
            chain.append(add_node(f"{a}~{b}#{j + 1}", point))
        chain.append(index[b])
        for u, v in zip(chain[:-1], chain[1:]):
            ef.append(u)
            et.append(v)
            one.append(bool(road.oneway))
            lim.append(road.speed_limit_mps)
            inv.append(bool(road.invisible))
            cls.append(road.road_class)
    return RoadMap.from_lists(origin, names, np.asarray(xyz), ef, et, one,
                              lim, inv, cls, source=source)


# --------------------------------------------------------------------------------------------
def default_scene_config() -> RoadmapConfig:
    """The built-in demonstration town, about 8 km x 8 km around (50.63 N, 7.13 E, 150 m).

    * ``hw_*``: a motorway crossing E–W at y = -1500 m (x -4000 … 4000), 33.3 m/s limit, with a
      1 km invisible tunnel between ``hw_tunnel_w`` (x = 1500) and ``hw_tunnel_e`` (x = 2500).
    * ``g_<i>_<j>``: a town grid, x = -2000 … 1000 m (i = 0 … 6, 500 m apart),
      y = -1000, -500, 0 m (j = 0 … 2), 13.9 m/s; ``g_0_1 -> g_1_1`` is oneway eastwards.
      Link roads ``g_2_0 - hw_x-1000`` and ``g_6_0 - hw_x1000``.
    * ``c_*``: a curved road (a quarter circle of radius 1000 m around (1000, -1000), 10 nodes)
      from ``g_6_2`` to ``c_end`` (2000, -1000), on to ``e_link`` (3000, -1000) and down to
      the motorway at ``hw_x3000``.
    * ``n_*``: a country road E–W at y = 1000 … 1400 m, north of the ridge the terrain config
      places along y = 500 m (x -3000 … 3000); it is reached by two N–S roads at x = ±3500 m
      around the ridge ends.
    * Every road stays outside :data:`DEFAULT_LAKE_POLYGON_M`. All nodes at z = 0.
    """
    nodes: Dict[str, List[float]] = {}
    roads: List[RoadSpec] = []
    hw_x = [-4000, -3500, -3000, -2000, -1000, 0, 1000, 1500, 2500, 3000, 3500, 4000]
    hw_names = []
    for x in hw_x:
        name = {1500: "hw_tunnel_w", 2500: "hw_tunnel_e"}.get(x, f"hw_x{x}")
        nodes[name] = [float(x), -1500.0, 0.0]
        hw_names.append(name)
    for a, b in zip(hw_names[:-1], hw_names[1:]):
        roads.append(RoadSpec(a, b, speed_limit_mps=33.3, road_class="motorway",
                              invisible=(a == "hw_tunnel_w")))
    xs = [-2000, -1500, -1000, -500, 0, 500, 1000]
    ys = [-1000, -500, 0]
    for i, x in enumerate(xs):
        for j, y in enumerate(ys):
            nodes[f"g_{i}_{j}"] = [float(x), float(y), 0.0]
    for j in range(len(ys)):
        for i in range(len(xs) - 1):
            roads.append(RoadSpec(f"g_{i}_{j}", f"g_{i + 1}_{j}", speed_limit_mps=13.9,
                                  road_class="residential", oneway=(i == 0 and j == 1)))
    for i in range(len(xs)):
        for j in range(len(ys) - 1):
            roads.append(RoadSpec(f"g_{i}_{j}", f"g_{i}_{j + 1}", speed_limit_mps=13.9,
                                  road_class="residential"))
    roads.append(RoadSpec("g_2_0", "hw_x-1000", speed_limit_mps=22.2, road_class="primary"))
    roads.append(RoadSpec("g_6_0", "hw_x1000", speed_limit_mps=22.2, road_class="primary"))
    # Curved road: quarter circle centred on (1000, -1000), from (1000, 0) to (2000, -1000).
    prev = "g_6_2"
    for k in range(1, 10):
        th = 0.5 * math.pi * k / 10
        name = f"c_{k}"
        nodes[name] = [1000.0 + 1000.0 * math.sin(th), -1000.0 + 1000.0 * math.cos(th), 0.0]
        roads.append(RoadSpec(prev, name, speed_limit_mps=19.4, road_class="secondary"))
        prev = name
    nodes["c_end"] = [2000.0, -1000.0, 0.0]
    nodes["e_link"] = [3000.0, -1000.0, 0.0]
    roads.append(RoadSpec(prev, "c_end", speed_limit_mps=19.4, road_class="secondary"))
    roads.append(RoadSpec("c_end", "e_link", speed_limit_mps=19.4, road_class="secondary"))
    roads.append(RoadSpec("e_link", "hw_x3000", speed_limit_mps=19.4, road_class="secondary"))
    # Country road north of the ridge.
    north = [(-4000, 1400), (-3500, 1350), (-3000, 1300), (-2000, 1200), (-1000, 1250),
             (0, 1300), (1000, 1200), (2000, 1050), (3000, 1000), (3500, 1000), (4000, 1000)]
    prev = None
    for x, y in north:
        name = f"n_x{x}"
        nodes[name] = [float(x), float(y), 0.0]
        if prev:
            roads.append(RoadSpec(prev, name, speed_limit_mps=27.8, road_class="secondary"))
        prev = name
    # N-S roads around the ends of the ridge (with a gentle bend as via points).
    roads.append(RoadSpec("hw_x-3500", "n_x-3500", speed_limit_mps=22.2, road_class="tertiary",
                          via=[[-3550.0, -500.0], [-3600.0, 500.0]]))
    roads.append(RoadSpec("hw_x3500", "n_x3500", speed_limit_mps=22.2, road_class="tertiary",
                          via=[[3550.0, -500.0], [3600.0, 300.0]]))
    return RoadmapConfig(kind=RoadmapKind.inline, origin_lat_deg=DEFAULT_ORIGIN.lat_deg,
                         origin_lon_deg=DEFAULT_ORIGIN.lon_deg,
                         origin_height_m=DEFAULT_ORIGIN.height_m, nodes=nodes, roads=roads)


def point_in_polygon(x, y, polygon) -> np.ndarray:
    """Even-odd rule point-in-polygon test, vectorised over points (ENU metres)."""
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    poly = np.asarray(polygon, float)
    inside = np.zeros(np.broadcast(x, y).shape, dtype=bool)
    for (x1, y1), (x2, y2) in zip(poly, np.roll(poly, -1, axis=0)):
        crosses = (y1 > y) != (y2 > y)
        with np.errstate(divide="ignore", invalid="ignore"):
            xc = x1 + (y - y1) * (x2 - x1) / (y2 - y1)
        inside ^= crosses & (x < xc)
    return inside
