"""Road network: crossroads (nodes) and straight roads between them (paper §2–3, DESIGN §3).

A :class:`RoadMap` holds

* ``nodes`` and ``edges`` tables with exactly the columns of ``/roads/nodes`` and
  ``/roads/edges`` in ``docs/tables.md``;
* ``graph``: a :class:`networkx.DiGraph` over ``node_id`` with one directed arc per direction a
  road may be travelled (a oneway road only ``from_node -> to_node``), arc attributes
  ``length_m`` (Euclidean 3-D length, the Dijkstra weight of the paper) and ``edge_id``, built
  on first use; routing and the random fleet use the same arcs as arrays (``arcs()``);
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
from typing import Dict, List

import numpy as np

from gmtiflow import frames
from gmtiflow.errors import RoadMapError
from gmtiflow.scene.geojson_roads import load_geojson
from gmtiflow.scene.osm import load_osm
from gmtiflow.scene.road_network import RoadMap
from gmtiflow.scene.roadmap_config import (DEFAULT_LAKE_POLYGON_M, DEFAULT_ORIGIN,
                                           DRIVABLE_HIGHWAY_CLASSES, OSM_ATTRIBUTION,
                                           RoadmapConfig, RoadmapKind, RoadSpec)

__all__ = ["DEFAULT_LAKE_POLYGON_M", "DEFAULT_ORIGIN", "DRIVABLE_HIGHWAY_CLASSES",
           "OSM_ATTRIBUTION", "RoadMap", "RoadSpec", "RoadmapConfig", "RoadmapKind",
           "default_scene_config", "from_inline", "load_roadmap", "point_in_polygon"]


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
        return load_osm(cfg.path, cfg)
    if kind == RoadmapKind.geojson:
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
