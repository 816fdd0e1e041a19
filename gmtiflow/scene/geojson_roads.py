"""GeoJSON road maps (RFC 7946): LineString and MultiLineString features in lon/lat.

* Accepts a FeatureCollection, a single Feature, or a bare (Multi)LineString geometry. Other
  geometry types (points, polygons) are ignored; a file without any line is an error.
* Coordinates are [lon, lat] or [lon, lat, height] (WGS-84 degrees, metres; heights within
  :data:`~gmtiflow.scene.dem.SURFACE_HEIGHT_RANGE_M`). Vertices whose lon/lat agree to
  ``merge_decimals`` decimals (default 7, about 1 cm) are one node, so lines that share an end
  point or cross at a shared vertex are connected; node names are ``gj<i>`` in order of first
  appearance.
* Properties: ``oneway`` (true/"yes"/"1" along, "-1"/"reverse" against, else both ways),
  ``tunnel`` (true/"yes"/… ⇒ invisible), ``maxspeed`` (a number in km/h or a string as in OSM),
  ``highway`` (if present, filtered by ``drivable_classes``; stored as ``road_class``).
* Origin: the centre of the line vertices' bounding box (across the antimeridian: near ±180°) at
  height 0 unless ``origin_*`` are set.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Dict, List, Optional

import numpy as np

from gmtiflow import frames
from gmtiflow.errors import InputFileError, RoadMapError
from gmtiflow.paths import check_input_file
from gmtiflow.scene.dem import SURFACE_HEIGHT_RANGE_M
from gmtiflow.scene.osm import parse_maxspeed
from gmtiflow.scene.road_network import RoadMap
from gmtiflow.scene.roadmap_config import RoadmapConfig


MAX_GEOJSON_BYTES = 2 * 2**30
"""GeoJSON is parsed in memory (about 10 times its size): larger files are refused."""


def _all_numbers(part: Any) -> bool:
    """Whether ``part`` is a list of positions whose members are JSON numbers (not booleans)."""
    if not isinstance(part, list):
        return False
    for pos in part:
        if not isinstance(pos, list):
            return False
        for v in pos:
            if type(v) not in (int, float):
                return False
    return True


def _truthy(value: Any) -> bool:
    if isinstance(value, bool):
        return value
    if value is None:
        return False
    return str(value).strip().lower() not in ("", "no", "false", "0")


def _features(doc: Any, where: str):
    if not isinstance(doc, dict) or "type" not in doc:
        raise RoadMapError(f"{where}: not a GeoJSON object (a dict with a 'type')")
    kind = doc["type"]
    if kind == "FeatureCollection":
        feats = doc.get("features")
        if not isinstance(feats, list):
            raise RoadMapError(f"{where}: FeatureCollection without a 'features' list")
        for i, f in enumerate(feats):
            if not isinstance(f, dict) or f.get("type") != "Feature":
                raise RoadMapError(f"{where}: features[{i}] is not a GeoJSON Feature")
            yield i, f.get("geometry"), f.get("properties") or {}
    elif kind == "Feature":
        yield 0, doc.get("geometry"), doc.get("properties") or {}
    else:
        yield 0, doc, {}


def load_geojson(path, cfg: Optional[RoadmapConfig] = None) -> RoadMap:
    """Road map from the LineStrings of a GeoJSON file."""
    cfg = cfg or RoadmapConfig()
    if not path:
        raise InputFileError("roadmap.path: a GeoJSON road map needs a file path")
    p = Path(path)
    if not p.exists():   # a directory or device: check_input_file says so
        raise InputFileError(f"{p}: GeoJSON file not found")
    check_input_file(p, "GeoJSON file", MAX_GEOJSON_BYTES, memory_factor=10.0)
    try:
        doc = json.loads(p.read_text(encoding="utf-8"))
    except UnicodeDecodeError as exc:
        raise RoadMapError(f"{p}: not UTF-8 text (byte {exc.start})") from None
    except json.JSONDecodeError as exc:
        raise RoadMapError(f"{p}: not valid JSON (line {exc.lineno}, column {exc.colno}): "
                           f"{exc.msg}") from None
    except ValueError:          # an integer of more than 4,300 digits (Python's limit)
        raise RoadMapError(f"{p}: holds a number too long to be a coordinate") from None
    except RecursionError:      # json recurses per nesting level: '[[[[...' exhausts the stack
        raise RoadMapError(f"{p}: JSON nested too deeply to be a GeoJSON road map") from None
    except OSError as exc:
        raise RoadMapError(f"{p}: cannot read ({exc.strerror or exc})") from None
    drivable = set(cfg.drivable_classes)
    lines = []
    for i, geom, props in _features(doc, str(p)):
        if not isinstance(geom, dict):
            continue
        gtype = geom.get("type")
        if gtype not in ("LineString", "MultiLineString"):
            continue
        if not isinstance(props, dict):
            raise RoadMapError(f"{p}: features[{i}].properties is not an object")
        hw = props.get("highway")
        if hw is not None and str(hw) not in drivable:
            continue
        kind = props.get("kind")
        if kind is not None and kind != "road":
            continue        # gmtiflow's own exports: truth trajectories etc. are not roads
        parts = [geom.get("coordinates")] if gtype == "LineString" else geom.get("coordinates")
        if not isinstance(parts, list):
            raise RoadMapError(f"{p}: features[{i}] {gtype} has no coordinates list")
        for part in parts:
            if not _all_numbers(part):
                raise RoadMapError(f"{p}: features[{i}]: coordinates must be [lon, lat] or "
                                   f"[lon, lat, height] numbers (true, false, null and text "
                                   f"are not)")
            try:
                pts = np.asarray(part, dtype=float)
            except (TypeError, ValueError):
                raise RoadMapError(f"{p}: features[{i}]: coordinates must be [lon, lat] or "
                                   f"[lon, lat, height] numbers") from None
            if pts.ndim != 2 or pts.shape[1] not in (2, 3) or len(pts) < 2 \
                    or not np.all(np.isfinite(pts)):
                raise RoadMapError(f"{p}: features[{i}]: a line needs >= 2 finite positions "
                                   f"[lon, lat(, height)]")
            if np.any(np.abs(pts[:, 1]) > 90) or np.any(np.abs(pts[:, 0]) > 180):
                raise RoadMapError(f"{p}: features[{i}]: lon/lat out of range (GeoJSON order is "
                                   f"[lon, lat])")
            lo, hi = SURFACE_HEIGHT_RANGE_M      # 1e9 m or -5e6 m used to be accepted
            off = np.flatnonzero((pts[:, 2] < lo) | (pts[:, 2] > hi)) if pts.shape[1] == 3 \
                else ()
            if len(off):
                raise RoadMapError(f"{p}: features[{i}]: height {pts[off[0], 2]:.6g} m "
                                   f"(position {int(off[0])}) outside {lo:g}..{hi:g} m; GeoJSON "
                                   f"heights are metres above the WGS-84 ellipsoid")
            lines.append((i, pts, props))
    if not lines:
        raise RoadMapError(f"{p}: no drivable LineString or MultiLineString features; it holds "
                           f"no road network")
    dec = int(cfg.merge_decimals)
    index: Dict[tuple, int] = {}
    lonlat: List[List[float]] = []
    heights: List[float] = []
    ef, et, one, lim, inv, cls = [], [], [], [], [], []
    for i, pts, props in lines:
        ids = []
        for q in pts:
            key = (round(float(q[0]), dec), round(float(q[1]), dec))
            if key not in index:
                index[key] = len(lonlat)
                lonlat.append([float(q[0]), float(q[1])])
                heights.append(float(q[2]) if len(q) > 2 else np.nan)
            ids.append(index[key])
        ow = props.get("oneway")
        ows = str(ow).strip().lower() if ow is not None else ""
        reverse = ows in ("-1", "reverse")
        oneway = reverse or (ow is True) or ows in ("yes", "true", "1")
        if reverse:
            ids = ids[::-1]
        speed = props.get("maxspeed")
        speed = (float(speed) / 3.6 if isinstance(speed, (int, float)) and speed > 0
                 else parse_maxspeed(None if speed is None else str(speed)))
        for a, b in zip(ids[:-1], ids[1:]):
            if a == b:
                continue
            ef.append(a)
            et.append(b)
            one.append(oneway)
            lim.append(speed)
            inv.append(_truthy(props.get("tunnel")))
            cls.append(str(props.get("highway", "road")))
    ll = np.asarray(lonlat)
    origin = frames.Origin(
        float(0.5 * (ll[:, 1].min() + ll[:, 1].max())) if cfg.origin_lat_deg is None
        else float(cfg.origin_lat_deg),
        frames.lon_centre_deg(ll[:, 0]) if cfg.origin_lon_deg is None
        else float(cfg.origin_lon_deg),
        0.0 if cfg.origin_height_m is None else float(cfg.origin_height_m))
    h = np.asarray(heights)
    h = np.where(np.isfinite(h), h, origin.height_m)
    x, y, z = frames.geodetic_to_enu(origin, ll[:, 1], ll[:, 0], h)
    names = [f"gj{k}" for k in range(len(ll))]
    return RoadMap.from_lists(origin, names, np.column_stack([x, y, z]), ef, et, one, lim, inv,
                              cls, source=str(p))
