"""The ``roadmap`` config group and the constants of the built-in maps (docs/scene.md).

The loaders that read it are in :mod:`gmtiflow.scene.roadmap`.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum
from typing import Any, Dict, List, Optional

from gmtiflow import frames, schema

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
