"""OpenStreetMap XML road maps (OSM XML 0.6) via lxml with a hardened parser.

* Parser: no entity resolution, no DTD loading, no network access (``lxml.etree.XMLParser``
  with ``resolve_entities=False, load_dtd=False, no_network=True``), so a hostile file cannot
  read local files or reach the network.
* Roads: ``<way>`` elements with a ``highway`` tag in ``RoadmapConfig.drivable_classes``;
  other classes (footway, steps, path, cycleway, pedestrian, track …) are dropped. Every way
  vertex becomes a road node named by its OSM id, and consecutive vertices become an edge
  (curves are chains of nodes, as in the paper).
* ``oneway=yes|true|1`` travel along the way, ``oneway=-1|reverse`` against it (the edge is
  stored reversed), ``oneway=no`` both ways; without a tag, ``highway=motorway|motorway_link``
  and ``junction=roundabout|circular`` are oneway (OSM's implied oneway) when
  ``implied_oneway`` is set.
* ``tunnel=<anything but no>`` (yes, building_passage …) marks the edges invisible.
* ``maxspeed``: a number in km/h, or with a unit ``km/h``, ``mph`` or ``knots``; anything
  else (``none``, ``signals``, ``RU:urban``) is no limit (NaN).
* Origin: the centre of ``<bounds>``, else of the drivable road nodes (a map across the
  antimeridian is centred near ±180°), at height 0 (override with ``origin_*``); node heights
  are the origin's (OSM carries no elevation), so z is 0 up to the curvature of the earth
  (-0.3 m at 2 km).  A ``<bounds>`` box that does not meet the box of the drivable road nodes
  is refused (its centre would be away from the roads), unless ``origin_*`` are given.
* Ids: a node repeated at the same position, or a way repeated with the same nodes and tags,
  is read once; a node or way id used twice with different content is refused (way ids are
  checked over all ways, node ids over the nodes the drivable ways use).
* No metadata attributes (version, timestamp, user) are required; elements marked
  ``action="delete"`` or ``visible="false"`` (JOSM files) are ignored.
* Isolated pieces of road are kept; routes are only possible within connected parts.
"""
from __future__ import annotations

import re
from pathlib import Path
from typing import Dict, List, Optional

import numpy as np

from gmtiflow import frames
from gmtiflow.errors import InputFileError, RoadMapError
from gmtiflow.paths import check_input_file
from gmtiflow.scene.road_network import RoadMap
from gmtiflow.scene.roadmap_config import OSM_ATTRIBUTION, RoadmapConfig

MAX_OSM_BYTES = 4 * 2**30
"""OSM XML is parsed in memory (about 5 times its size): larger extracts are refused."""

_MAXSPEED = re.compile(r"^\s*(\d+(?:\.\d+)?)\s*(km/h|kmh|kph|mph|knots)?\s*$", re.IGNORECASE)
_UNIT_MPS = {None: 1 / 3.6, "km/h": 1 / 3.6, "kmh": 1 / 3.6, "kph": 1 / 3.6,
             "mph": 0.44704, "knots": 0.514444}


def parse_maxspeed(value: Optional[str]) -> float:
    """OSM ``maxspeed`` -> m/s (NaN when absent or not a plain number with a unit)."""
    if value is None:
        return float("nan")
    m = _MAXSPEED.match(value)
    if not m:
        return float("nan")
    speed = float(m.group(1)) * _UNIT_MPS[m.group(2).lower() if m.group(2) else None]
    return speed if speed > 0 else float("nan")


def _deleted(element) -> bool:
    """JOSM/osmChange leftovers: ``action="delete"`` or ``visible="false"``."""
    return element.get("action") == "delete" or element.get("visible") == "false"


def hardened_parser():
    """An XML parser (``lxml.etree.XMLParser``) that resolves no entities, loads no DTD and
    never touches the network."""
    from lxml import etree      # only when an OSM file is read: not on every start-up
    return etree.XMLParser(resolve_entities=False, load_dtd=False, no_network=True,
                           dtd_validation=False, huge_tree=False, remove_comments=True,
                           remove_pis=True)


_COMPRESSED = ((b"\x1f\x8b", "gzip", "gunzip"), (b"\xfd7zXZ\x00", "xz", "unxz"),
               (b"BZh", "bzip2", "bunzip2"), (b"\x28\xb5\x2f\xfd", "zstd", "unzstd"))


def _refuse_other_encodings(p: Path) -> None:
    """RoadMapError for a compressed file or OSM PBF, before parsing.  libxml2 decompresses gzip
    by itself, so the size and memory checks (made on the file's size) saw a 3.6 MB .osm.gz
    whose parse took 1.3 GB (53 MB of XML); PBF used to be "Document is empty, line 1"."""
    with open(p, "rb") as f:
        head = f.read(32)
    for magic, kind, tool in _COMPRESSED:
        if head.startswith(magic):
            raise RoadMapError(f"{p}: compressed ({kind}); decompress it first ({tool} {p.name}):"
                               f" the size and memory checks are made on the XML itself")
    if b"OSMHeader" in head:
        raise RoadMapError(f"{p}: OSM PBF (binary) is not read; convert it to OSM XML, e.g. "
                           f"osmium cat {p.name} -o map.osm")


def _check_repeated_way(p: Path, first, again) -> None:
    """RoadMapError unless ``again`` repeats way ``first`` exactly (the same nodes in the same
    order and the same tags), as a node repeated at the same position is the same node."""
    def content(way):
        return ([nd.get("ref") for nd in way.iterfind("nd")],
                {t.get("k"): t.get("v") for t in way.iterfind("tag")})

    (refs_a, tags_a), (refs_b, tags_b) = content(first), content(again)
    differ = [what for what, a, b in (("nodes", refs_a, refs_b), ("tags", tags_a, tags_b))
              if a != b]
    if differ:
        raise RoadMapError(f"{p}: way {first.get('id')} appears twice with different "
                           f"{' and '.join(differ)} (lines {first.sourceline} and "
                           f"{again.sourceline}); way ids must be unique (several versions of "
                           f"one way: a history file or overlapping extracts concatenated? "
                           f"osmium merge gives one of each)")


def _check_bounds_meet_roads(p: Path, line: int, b: Dict[str, float],
                             latlon: np.ndarray) -> None:
    """RoadMapError if the ``<bounds>`` box and the box of the drivable road nodes are disjoint:
    its centre would put the scene's origin away from the roads.  An export's bounds are the
    area asked for, and ways crossing its edge bring nodes outside it; a box touching the
    roads' box, or crossed by a way with no node inside, still meets it."""
    lat_lo, lat_hi = float(latlon[:, 0].min()), float(latlon[:, 0].max())
    lon_lo, lon_hi = float(latlon[:, 1].min()), float(latlon[:, 1].max())
    if (b["minlat"] <= lat_hi and lat_lo <= b["maxlat"]
            and b["minlon"] <= lon_hi and lon_lo <= b["maxlon"]):
        return
    raise RoadMapError(f"{p}: <bounds> (line {line}) lat {b['minlat']:g} .. {b['maxlat']:g}, "
                       f"lon {b['minlon']:g} .. {b['maxlon']:g} holds none of the drivable roads "
                       f"(lat {lat_lo:g} .. {lat_hi:g}, lon {lon_lo:g} .. {lon_hi:g}): its centre "
                       f"would put the scene's origin away from them; correct or delete <bounds> "
                       f"(the roads' centre is then the origin), or set roadmap.origin_lat_deg "
                       f"and roadmap.origin_lon_deg")


def load_osm(path, cfg: Optional[RoadmapConfig] = None) -> RoadMap:
    """Road map of the drivable highways in an OSM XML file."""
    cfg = cfg or RoadmapConfig()
    if not path:
        raise InputFileError("roadmap.path: an OSM road map needs a file path")
    p = Path(path)
    if not p.exists():   # a directory or device: check_input_file says so
        raise InputFileError(f"{p}: OSM file not found (roadmap.path; experiment=monaco reads "
                             f"monaco.osm and N43E007.hgt from the folder in GMTIFLOW_DATA_DIR)")
    check_input_file(p, "OSM file", MAX_OSM_BYTES, memory_factor=6.0)
    _refuse_other_encodings(p)
    from lxml import etree
    try:
        root = etree.parse(str(p), hardened_parser()).getroot()
    except etree.XMLSyntaxError as exc:
        raise RoadMapError(f"{p}: not well-formed OSM XML (line {exc.lineno}): {exc.msg}") from None
    except OSError as exc:      # lxml reports bad character encodings and unreadable files so
        raise RoadMapError(f"{p}: cannot read as OSM XML: {exc}") from None
    if root.tag != "osm":
        raise RoadMapError(f"{p}: root element is <{root.tag}>, expected <osm> (OSM XML 0.6)")
    drivable = set(cfg.drivable_classes)
    ways = []
    first: Dict[str, object] = {}
    for way in root.iterfind("way"):
        if _deleted(way):
            continue
        wid = way.get("id")
        if wid is not None and first.setdefault(wid, way) is not way:
            _check_repeated_way(p, first[wid], way)
            continue        # the same way again: read once
        tags = {t.get("k"): t.get("v") for t in way.iterfind("tag")}
        hw = tags.get("highway")
        if hw is None or hw not in drivable:
            continue
        refs = [nd.get("ref") for nd in way.iterfind("nd")]
        ways.append((wid, hw, tags, refs))
    if not ways:
        raise RoadMapError(f"{p}: no drivable highway ways (classes {sorted(drivable)}) in the "
                           f"file; it holds no road network")
    needed = {r for _, _, _, refs in ways for r in refs}
    coords: Dict[str, tuple] = {}
    lines: Dict[str, int] = {}
    for node in root.iterfind("node"):
        nid = node.get("id")
        if nid in needed and not _deleted(node):
            try:
                lat, lon = float(node.get("lat")), float(node.get("lon"))
            except (TypeError, ValueError):
                raise RoadMapError(f"{p}: node {nid} (line {node.sourceline}) has no valid "
                                   f"lat/lon") from None
            if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):   # also NaN, inf
                raise RoadMapError(f"{p}: node {nid} (line {node.sourceline}): lat {lat!r}, "
                                   f"lon {lon!r} out of range (lat in [-90, 90], lon in "
                                   f"[-180, 180] degrees)")
            if nid in coords and coords[nid] != (lat, lon):
                raise RoadMapError(f"{p}: node {nid} appears twice with different positions "
                                   f"(lines {lines[nid]} and {node.sourceline}); node ids must "
                                   f"be unique")
            coords[nid] = (lat, lon)
            lines.setdefault(nid, node.sourceline)
    names: List[str] = []
    index: Dict[str, int] = {}
    ef, et, one, lim, inv, cls = [], [], [], [], [], []
    for wid, hw, tags, refs in ways:
        missing = [r for r in refs if r not in coords]
        if missing:
            raise RoadMapError(f"{p}: way {wid} refers to node {missing[0]} which is not in the "
                               f"file")
        ow = (tags.get("oneway") or "").lower()
        if ow in ("yes", "true", "1"):
            direction = 1
        elif ow in ("-1", "reverse"):
            direction = -1
        elif ow in ("no", "false", "0"):
            direction = 0
        elif cfg.implied_oneway and (hw in ("motorway", "motorway_link") or
                                     tags.get("junction") in ("roundabout", "circular")):
            direction = 1
        else:
            direction = 0
        invisible = tags.get("tunnel", "no").lower() not in ("no", "false", "0")
        speed = parse_maxspeed(tags.get("maxspeed"))
        ids = []
        for r in refs:
            if r not in index:
                index[r] = len(names)
                names.append(r)
            ids.append(index[r])
        if direction == -1:
            ids = ids[::-1]
        for a, b in zip(ids[:-1], ids[1:]):
            if a == b:
                continue
            ef.append(a)
            et.append(b)
            one.append(direction != 0)
            lim.append(speed)
            inv.append(invisible)
            cls.append(hw)
    if not ef:
        raise RoadMapError(f"{p}: the drivable ways have no segments (each needs two nodes)")
    latlon = np.asarray([coords[n] for n in names], dtype=float)
    bounds = root.find("bounds")
    if bounds is not None:
        try:
            b = {k: float(bounds.get(k)) for k in ("minlat", "maxlat", "minlon", "maxlon")}
        except (TypeError, ValueError):
            raise RoadMapError(f"{p}: <bounds> (line {bounds.sourceline}) lacks numeric "
                               f"minlat/maxlat/minlon/maxlon") from None
        if not (-90 <= b["minlat"] <= b["maxlat"] <= 90
                and -180 <= b["minlon"] <= b["maxlon"] <= 180):      # also NaN, inf
            raise RoadMapError(f"{p}: <bounds> (line {bounds.sourceline}) out of range: "
                               f"need -90 <= minlat <= maxlat <= 90 and -180 <= minlon <= "
                               f"maxlon <= 180 degrees")
        if cfg.origin_lat_deg is None or cfg.origin_lon_deg is None:
            _check_bounds_meet_roads(p, bounds.sourceline, b, latlon)
        lat0 = 0.5 * (b["minlat"] + b["maxlat"])
        lon0 = 0.5 * (b["minlon"] + b["maxlon"])
    else:
        lat0 = float(0.5 * (latlon[:, 0].min() + latlon[:, 0].max()))
        lon0 = frames.lon_centre_deg(latlon[:, 1])    # across ±180° too
    origin = frames.Origin(
        lat0 if cfg.origin_lat_deg is None else float(cfg.origin_lat_deg),
        lon0 if cfg.origin_lon_deg is None else float(cfg.origin_lon_deg),
        0.0 if cfg.origin_height_m is None else float(cfg.origin_height_m))
    x, y, z = frames.geodetic_to_enu(origin, latlon[:, 0], latlon[:, 1],
                                     np.full(len(names), origin.height_m))
    return RoadMap.from_lists(origin, names, np.column_stack([x, y, z]), ef, et, one, lim, inv,
                              cls, attribution=OSM_ATTRIBUTION, source=str(p))
