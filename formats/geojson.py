"""GeoJSON (RFC 7946) FeatureCollection of detections, truth, roads and clutter regions.

For QGIS and web maps.  Positions are ``[lon_deg, lat_deg, height_m]`` (WGS-84, height above the
ellipsoid), no ``crs`` member (RFC 7946 §4).  Every feature has ``properties.kind``:

* ``"detection"`` — Point per detection; properties: every other detection column
  (``det_id``, ``dwell_id``, ``time_s``, ``range_m``, ... ``truth_id``) and ``time_utc``.
* ``"truth"`` — LineString per vehicle through its samples in time order (a Point if it has one
  sample); properties: ``vehicle_id``, ``convoy_id`` and, per vertex, arrays of the other truth
  columns (``time_s``, ``speed_mps``, ...), so the truth table can be read back.  Booleans are
  written per vertex as 0/1 (GDAL reads lists of integers, not of booleans); NaN is ``null``,
  and GDAL types a list holding ``null`` as text (gmtiflow's /truth has no NaN).  Truth goes in a file of
  its own (``truth.geojson``): one property name has one type in a file, and ``time_s`` is a
  scalar on detections but a list on truth lines, which GDAL cannot read as one field.
* ``"track"`` — LineString per track (a Point if it has one update), the same way: properties
  ``track_id`` and per-vertex lists of the other /tracks columns; positions 2-D.  Tracks go in
  a file of their own too (``tracks.geojson``).
* ``"road_node"`` — Point per road node (``node_id``, ``name``, ``x_m y_m z_m``);
  ``"road"`` — LineString per edge between its two nodes (``edge_id from_node to_node length_m
  oneway speed_limit_mps invisible road_class``).
* ``"clutter"`` — Polygon per clutter region (a closed exterior ring, counter-clockwise as RFC
  7946 §3.1.6 recommends) plus the region's scalar properties.

Floats are written column-wise by :mod:`formats._text` in digits that read back exactly, so
positions and values round-trip exactly, a block of features at a time (:func:`iter_geojson`);
NaN is written as ``null`` (RFC 8259 has no NaN) and read back as NaN.  A table given without
rows is listed with its columns in the foreign member ``empty_tables``, so it reads back with
them.  The geometry needs geodetic columns: ``lat_deg lon_deg height_m`` on detections, truth and road nodes (the caller converts
ENU with ``gmtiflow.frames``; formats never imports gmtiflow).
"""
from __future__ import annotations

import json
import math
from typing import Iterator, Mapping, Sequence

import numpy as np

from . import _text as _cells
from ._io import n_rows, parse_epoch, read_source, source_name, write_chunks
from .csvtable import COLUMNS
from .errors import FormatError, where

__all__ = ["write_geojson", "encode_geojson", "iter_geojson", "read_geojson"]

_GEO = ("lat_deg", "lon_deg", "height_m")
NODE_COLUMNS = {"node_id": "int", "name": "str", "x_m": "float", "y_m": "float", "z_m": "float"}
EDGE_COLUMNS = {"edge_id": "int", "from_node": "int", "to_node": "int", "length_m": "float",
                "oneway": "bool", "speed_limit_mps": "float", "invisible": "bool",
                "road_class": "str"}


def _num(v):
    """JSON value of a numpy scalar: NaN/inf -> null."""
    if isinstance(v, (bool, np.bool_)):
        return bool(v)
    if isinstance(v, (int, np.integer)):
        return int(v)
    if isinstance(v, (float, np.floating)):
        v = float(v)
        return v if math.isfinite(v) else None
    return str(v)


def _need(table, cols, what):
    missing = [c for c in cols if c not in table]
    if missing:
        raise ValueError(f"GeoJSON writer: {what} table lacks {missing} (convert ENU to "
                         "geodetic first, e.g. with gmtiflow.frames)")


def _json_field(col: np.ndarray, rows=None) -> _cells.Field:
    """JSON text of a column (of ``col[rows]`` when ``rows`` is given: the whole column is
    passed so that the formats of one table format it once, :func:`formats._text.shared_columns`):
    numbers exact (NaN and inf as null), booleans, quoted strings."""
    col = np.asarray(col)
    if col.dtype.kind == "b":
        return _cells.choice(col if rows is None else col[rows], "true", "false")
    if col.dtype.kind in "iu":
        return _cells.int_cells(col, rows)
    if col.dtype.kind == "f":
        return _cells.float_cells(col, nan="null", inf="null", rows=rows)
    return _cells.strings(col if rows is None else col[rows], quote=json.dumps)


_ROWS = 1 << 14                        # features formatted at a time (bounded memory)


def _floats(col):
    """``col`` as float64 (the same array when it is one already, so its text can be shared)."""
    col = np.asarray(col)
    return col if col.dtype == np.float64 else col.astype(np.float64)


def _detection_blocks(dets: Mapping[str, np.ndarray], epoch) -> Iterator[bytes]:
    """Point features of the detections, a block of rows at a time (features joined by ",\n")."""
    n = n_rows(dets, "detections")
    _need(dets, _GEO[:2], "detections")
    props = [c for c in dets if c not in _GEO]
    names = [f",{json.dumps(c)}:" for c in props]
    for a, b in _cells.row_chunks(n, _ROWS):
        m = b - a
        rows = slice(a, b)
        lon = np.asarray(dets["lon_deg"], np.float64)[rows]
        lat = np.asarray(dets["lat_deg"], np.float64)[rows]
        located = np.isfinite(lon) & np.isfinite(lat)   # RFC 7946 §3.2: else a null geometry
        h = np.asarray(dets["height_m"], np.float64)[rows] if "height_m" in dets else None
        point = _cells.literal('{"type":"Point","coordinates":[', m)
        comma = _cells.literal(",", m)
        pieces: list = ['{"type":"Feature","geometry":',
                        _cells.literal("null", m).masked(~located), point.masked(located),
                        _cells.masked(_json_field(_floats(dets["lon_deg"]), rows), located),
                        comma.masked(located),
                        _cells.masked(_json_field(_floats(dets["lat_deg"]), rows), located)]
        if h is not None:
            has_h = located & np.isfinite(h)
            pieces += [comma.masked(has_h),
                       _cells.masked(_json_field(_floats(dets["height_m"]), rows), has_h)]
        pieces += [_cells.literal("]}", m).masked(located),
                   ',"properties":{"kind":"detection"']
        for c, nm in zip(props, names):
            pieces += [nm, _json_field(dets[c], rows)]
        if epoch is not None and "time_s" in dets:
            pieces += [',"time_utc":"', _cells.utc_cells(
                epoch, np.asarray(dets["time_s"], np.float64)[a:b]), '"']
        pieces.append("}},\n")
        yield _cells.join(pieces, m)[:-2]


_LINES = {"truth": ("vehicle_id", ("convoy_id",)), "track": ("track_id", ())}
"""Kinds written as one line per object: (id column, per-object columns)."""


def _line_blocks(truth: Mapping[str, np.ndarray], kind: str = "truth") -> Iterator[bytes]:
    """LineString (or Point) features, one per vehicle (``truth``) or track (``track``), a group
    of them at a time; the other columns as per-vertex lists."""
    id_col, static = _LINES[kind]
    _need(truth, (id_col, "time_s") + _GEO[:2], kind)
    vid_all = np.asarray(truth[id_col])
    order = np.lexsort((np.asarray(truth["time_s"], float), vid_all))
    vid = vid_all[order]
    n = len(vid)
    starts = np.flatnonzero(np.r_[True, vid[1:] != vid[:-1]]) if n else np.zeros(0, np.int64)
    ends = np.r_[starts[1:], n].astype(np.int64)
    per_vertex = [c for c in truth if c not in _GEO + (id_col,) + static]
    # groups of whole vehicles of about _ROWS samples each
    cut = np.searchsorted(ends, np.arange(_ROWS, n + _ROWS, _ROWS), side="left")
    bounds = np.unique(np.r_[0, np.minimum(cut + 1, len(starts))])
    for g0, g1 in zip(bounds[:-1].tolist(), bounds[1:].tolist()):
        if g0 == g1:
            continue
        a, b = int(starts[g0]), int(ends[g1 - 1])
        m = b - a
        sel = order[a:b]
        v_start = starts[g0:g1] - a
        v_end = ends[g0:g1] - a
        last = np.zeros(m, bool)
        last[v_end - 1] = True
        sep = _cells.choice(last, "", ",")
        pos = ["[", _json_field(_floats(truth["lon_deg"]), sel), ",",
               _json_field(_floats(truth["lat_deg"]), sel)]
        if "height_m" in truth:
            fin = np.isfinite(np.asarray(truth["height_m"], np.float64)[sel])
            pos += [_cells.literal(",", m).masked(fin),
                    _cells.masked(_json_field(_floats(truth["height_m"]), sel), fin)]
        coords, c_off = _cells.join_rows(pos + ["]", sep], m)
        lists = []
        for c in per_vertex:
            x = np.asarray(truth[c])
            if x.dtype.kind == "b":           # GDAL reads lists of integers, not of booleans
                field = _json_field(x[sel].astype(np.int64))
            else:
                field = _json_field(x, sel)
            blob, off = _cells.join_rows([field, sep], m)
            lists.append((f",{json.dumps(c)}:[".encode(), blob, off.tolist()))
        # the features, assembled from slices of the formatted blocks
        first = sel[v_start]
        head = [f'{{"kind":"{kind}","{id_col}":{int(v)}'.encode()
                for v in np.asarray(truth[id_col])[first].tolist()]
        for c in static:
            if c in truth:
                head = [h + f',"{c}":{int(v)}'.encode()
                        for h, v in zip(head, np.asarray(truth[c])[first].tolist())]
        c_off = c_off.tolist()
        out = []
        put = out.append
        for k, (i, j) in enumerate(zip(v_start.tolist(), v_end.tolist())):
            put(b',\n{"type":"Feature","geometry":{"type":"Point","coordinates":' if j - i == 1
                else b',\n{"type":"Feature","geometry":{"type":"LineString","coordinates":[')
            put(coords[c_off[i]:c_off[j]])
            put(b'},"properties":' if j - i == 1 else b']},"properties":')
            put(head[k])
            for key, blob, off in lists:
                put(key)
                put(blob[off[i]:off[j]])
                put(b"]")
            put(b"}}")
        yield b"".join(out)[2:]


def _coords(lat, lon, h):
    return [[_num(a), _num(b)] + ([] if c is None or not math.isfinite(c) else [float(c)])
            for a, b, c in zip(lon, lat, h if h is not None else [None] * len(lat))]


def _position_field(lat, lon, h, m) -> list:
    """``lon,lat[,h]`` text of positions (no height where ``h`` is None or NaN)."""
    out = [_json_field(np.asarray(lon, np.float64)), ",", _json_field(np.asarray(lat, np.float64))]
    if h is not None:
        h = np.asarray(h, np.float64)
        fin = np.isfinite(h)
        out += [_cells.literal(",", m).masked(fin), _cells.masked(_json_field(h), fin)]
    return out


def _props(table, columns, rows) -> list:
    out: list = []
    for c in columns:
        if c in table:
            out += [f",{json.dumps(c)}:", _json_field(np.asarray(table[c])[rows])]
    return out


def _road_blocks(nodes, edges) -> Iterator[bytes]:
    """Point features of the road nodes, then LineString features of the edges (from-node to
    to-node), a block at a time."""
    _need(nodes, ("node_id",) + _GEO[:2], "road nodes")
    nid = np.asarray(nodes["node_id"], dtype=np.int64)
    lat = np.asarray(nodes["lat_deg"], float)
    lon = np.asarray(nodes["lon_deg"], float)
    h = np.asarray(nodes["height_m"], float) if "height_m" in nodes else None
    for a, b in _cells.row_chunks(len(nid), _ROWS):
        r = np.arange(a, b)
        yield _cells.join(['{"type":"Feature","properties":{"kind":"road_node"']
                          + _props(nodes, NODE_COLUMNS, r)
                          + ['},"geometry":{"type":"Point","coordinates":[']
                          + _position_field(lat[r], lon[r], None if h is None else h[r], b - a)
                          + ["]}},\n"], b - a)[:-2]
    if edges is None:
        return
    _need(edges, ("edge_id", "from_node", "to_node"), "road edges")
    ne = n_rows(edges, "road edges")
    sorter = np.argsort(nid, kind="stable")
    ends = []
    for c in ("from_node", "to_node"):
        k = np.asarray(edges[c], np.int64)
        pos = np.minimum(np.searchsorted(nid[sorter], k), max(len(nid) - 1, 0))
        bad = (len(nid) == 0) | (nid[sorter][pos] != k) if ne else np.zeros(0, bool)
        if np.any(bad):
            i = int(np.flatnonzero(bad)[0])
            raise ValueError(f"GeoJSON writer: road edge {i} refers to unknown node {k[i]}")
        ends.append(sorter[pos])
    for a, b in _cells.row_chunks(ne, _ROWS):
        r, m = np.arange(a, b), b - a
        f, t = ends[0][a:b], ends[1][a:b]
        yield _cells.join(['{"type":"Feature","properties":{"kind":"road"'] + _props(
            edges, EDGE_COLUMNS, r) + ['},"geometry":{"type":"LineString","coordinates":[[']
            + _position_field(lat[f], lon[f], None if h is None else h[f], m) + ["],["]
            + _position_field(lat[t], lon[t], None if h is None else h[t], m)
            + ["]]}},\n"], m)[:-2]


def _clutter_features(regions: Sequence[Mapping]) -> list[dict]:
    feats = []
    for k, reg in enumerate(regions):
        if "lat_deg" not in reg or "lon_deg" not in reg:
            raise ValueError(f"GeoJSON writer: clutter region {k} needs lat_deg and lon_deg arrays")
        lat = np.asarray(reg["lat_deg"], float)
        lon = np.asarray(reg["lon_deg"], float)
        if len(lat) != len(lon) or len(lat) < 3:
            raise ValueError(f"GeoJSON writer: clutter region {k} needs >= 3 vertices")
        if lat[0] == lat[-1] and lon[0] == lon[-1] and len(lat) > 3:
            lat, lon = lat[:-1], lon[:-1]
        # exterior ring counter-clockwise (positive shoelace area in lon/lat)
        area = np.sum(lon * np.roll(lat, -1) - np.roll(lon, -1) * lat)
        if area < 0:
            lat, lon = lat[::-1], lon[::-1]
        ring = _coords(np.r_[lat, lat[0]].tolist(), np.r_[lon, lon[0]].tolist(), None)
        props = {"kind": "clutter"}
        for c, v in reg.items():
            if c in ("lat_deg", "lon_deg"):
                continue
            if np.ndim(v):
                raise ValueError(f"GeoJSON writer: clutter region {k} property {c!r} is not a scalar")
            props[c] = _num(np.asarray(v)[()]) if not isinstance(v, str) else v
        feats.append({"type": "Feature", "properties": props,
                      "geometry": {"type": "Polygon", "coordinates": [ring]}})
    return feats


def iter_geojson(*, detections=None, truth=None, road_nodes=None, road_edges=None,
                 clutter_regions=None, tracks=None,
                 epoch_utc: str | None = None) -> Iterator[bytes]:
    """The FeatureCollection of whatever is given, in pieces (bounded memory; see the module
    docstring).  Truth and tracks each come alone (``truth.geojson``, ``tracks.geojson``): one
    property name, one type."""
    epoch = parse_epoch(epoch_utc) if epoch_utc is not None else None
    has_truth = truth is not None and n_rows(truth, "truth") > 0
    has_tracks = tracks is not None and n_rows(tracks, "tracks") > 0
    others = [x is not None and (len(x) if not isinstance(x, Mapping) else n_rows(x, "table"))
              for x in (detections, road_nodes, clutter_regions)]
    if (has_truth or has_tracks) and (any(others) or (has_truth and has_tracks)):
        what = "truth" if has_truth else "tracks"
        raise ValueError(f"GeoJSON writer: write {what} to a file of its own ({what}.geojson): "
                         "its per-vertex list properties (time_s, ...) would clash with the "
                         "scalar properties of the same name on detections and roads, which "
                         "GIS tools (GDAL) cannot read as one field")
    dumps = lambda f: json.dumps(f, allow_nan=False, separators=(",", ":"))   # noqa: E731
    head = '{"type":"FeatureCollection"'
    if epoch is not None:
        head += f',"scene_epoch_utc":"{epoch.strftime("%Y-%m-%dT%H:%M:%S.%fZ")}"'
    # a table without rows has no feature to carry its property names: list its columns
    empty = {name: list(table) for name, table in (("detections", detections), ("truth", truth),
                                                   ("tracks", tracks))
             if table is not None and not n_rows(table, name)}
    if empty:
        head += f',"empty_tables":{dumps(empty)}'
    yield (head + ',"features":[\n').encode()

    def blocks():
        if detections is not None and n_rows(detections, "detections"):
            yield from _detection_blocks(detections, epoch)
        if has_truth:
            yield from _line_blocks(truth, "truth")
        if has_tracks:
            yield from _line_blocks(tracks, "track")
        if road_nodes is not None and n_rows(road_nodes, "road nodes"):
            yield from _road_blocks(road_nodes, road_edges)
        if clutter_regions:
            yield ",\n".join(dumps(f) for f in _clutter_features(clutter_regions)).encode()

    first = True
    for block in blocks():
        if not block:
            continue
        yield block if first else b",\n" + block
        first = False
    yield b"\n]}\n"


def encode_geojson(**kwargs) -> bytes:
    """UTF-8 bytes of :func:`iter_geojson`'s FeatureCollection."""
    return b"".join(iter_geojson(**kwargs))


def write_geojson(dest, **kwargs) -> None:
    """Write :func:`iter_geojson`'s document to a path (atomically) or binary file object, a
    block of features at a time."""
    write_chunks(dest, iter_geojson(**kwargs))


# ---------------------------------------------------------------------------------------------

def _is_num(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _typed(values: list, kind: str | None, what: str) -> np.ndarray:
    if kind == "bool":
        if not all(isinstance(v, bool) for v in values):
            raise ValueError("expected true or false")
        return np.array(values, dtype=bool)
    if kind in ("int", "u8"):
        if not all(v is None or (_is_num(v) and float(v).is_integer()) for v in values):
            raise ValueError("expected integers")
        a = np.array([-1 if v is None else int(v) for v in values], dtype=np.int64)
        if kind == "u8" and np.any((a < 0) | (a > 255)):
            raise ValueError("expected integers 0..255")
        return a.astype(np.uint8) if kind == "u8" else a
    if kind == "float":
        if not all(v is None or _is_num(v) for v in values):
            raise ValueError("expected numbers or null")
        return np.array([np.nan if v is None else v for v in values], dtype=np.float64)
    if kind == "str":
        return np.array(["" if v is None else str(v) for v in values], dtype=str)
    if all(v is None or isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
        return np.array([np.nan if v is None else v for v in values], dtype=np.float64)
    if all(isinstance(v, bool) for v in values):
        return np.array(values, dtype=bool)
    return np.array(["" if v is None else str(v) for v in values], dtype=str)


def _props_table(props: list[dict], kinds: dict, what: str) -> dict:
    keys: list[str] = []
    for p in props:
        for k in p:
            if k not in keys and k != "kind":
                keys.append(k)
    out = {}
    for k in keys:
        try:
            out[k] = _typed([p.get(k) for p in props], kinds.get(k), what)
        except (TypeError, ValueError) as exc:
            raise FormatError(f"{what}: property {k!r} has a value of the wrong type "
                              f"({exc})") from None
    return out


def _position(c, name, i):
    if (not isinstance(c, list) or len(c) not in (2, 3)
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in c)):
        raise FormatError(f"{where(name)}feature {i}: a position must be [lon, lat] or "
                          f"[lon, lat, height] numbers, got {str(c)[:60]}")
    return float(c[1]), float(c[0]), float(c[2]) if len(c) == 3 else np.nan


def _lines_table(features: list, kind: str, table: str, name, coords_of) -> dict:
    """The table of ``truth`` or ``track`` line features: one row per vertex, sorted by time
    and id (the per-vertex lists give the columns; booleans travel as 0/1)."""
    id_col, static = _LINES[kind]
    parts = []
    for i, g, p in features:
        _, c = coords_of(i, g, ("Point", "LineString"))
        if c is None:
            raise FormatError(f"{where(name)}feature {i}: {kind} without geometry")
        n = len(c)
        row = {id_col: [p.get(id_col)] * n}
        for k in static:
            if k in p:
                row[k] = [p[k]] * n
        for k, v in p.items():
            if k in ("kind", id_col) + static:
                continue
            if not isinstance(v, list) or len(v) != n:
                raise FormatError(f"{where(name)}feature {i}: {kind} property {k!r} must be a "
                                  f"list of {n} per-vertex values")
            row[k] = v
        arr = np.array(c, dtype=np.float64).reshape(-1, 3)
        row["lat_deg"], row["lon_deg"] = arr[:, 0].tolist(), arr[:, 1].tolist()
        if kind == "truth" or np.isfinite(arr[:, 2]).any():
            row["height_m"] = arr[:, 2].tolist()
        parts.append(row)
    if not parts:
        return {}
    keys = list(dict.fromkeys(k for r in parts for k in r))
    merged = [{k: r[k][j] if k in r else None for k in keys}
              for r in parts for j in range(len(r[id_col]))]
    for k, kk in COLUMNS[table].items():          # booleans travel as 0/1 per vertex
        if kk == "bool" and k in keys:
            for r in merged:
                if r[k] in (0, 1) and not isinstance(r[k], bool):
                    r[k] = bool(r[k])
    out = _props_table(merged, COLUMNS[table], f"{where(name)}{table}")
    if "time_s" in out:
        order = np.lexsort((out[id_col], out["time_s"]))
        out = {k: v[order] for k, v in out.items()}
    return out


def read_geojson(source) -> dict:
    """Read a FeatureCollection written by :func:`write_geojson` (or any with ``kind``-tagged
    features) back to ``{"detections", "truth", "tracks", "road_nodes", "road_edges",
    "clutter_regions"}``.

    Features without a known ``kind`` are ignored.  Malformed JSON raises FormatError with line
    and column; a malformed feature raises FormatError naming its index.
    """
    name = source_name(source)
    raw = read_source(source)
    try:
        doc = json.loads(raw)
    except UnicodeDecodeError as exc:
        raise FormatError(f"{where(name)}not UTF-8 text (byte {exc.start})") from None
    except json.JSONDecodeError as exc:
        raise FormatError(f"{where(name)}line {exc.lineno}, column {exc.colno}: not JSON: "
                          f"{exc.msg}") from None
    except RecursionError:
        raise FormatError(f"{where(name)}JSON nested too deeply") from None
    if not isinstance(doc, dict) or doc.get("type") != "FeatureCollection" \
            or not isinstance(doc.get("features"), list):
        raise FormatError(f"{where(name)}not a GeoJSON FeatureCollection (expected an object with "
                          "type 'FeatureCollection' and a 'features' list)")
    groups: dict[str, list] = {"detection": [], "truth": [], "track": [], "road_node": [],
                               "road": [], "clutter": []}
    for i, f in enumerate(doc["features"]):
        if not isinstance(f, dict) or f.get("type") != "Feature":
            raise FormatError(f"{where(name)}feature {i}: not a GeoJSON Feature object")
        props = f.get("properties")
        geom = f.get("geometry")
        if not isinstance(props, dict) or (geom is not None and not isinstance(geom, dict)):
            raise FormatError(f"{where(name)}feature {i}: properties must be an object and "
                              "geometry an object or null")
        kind = props.get("kind")
        if kind in groups:
            groups[kind].append((i, geom, props))

    def coords_of(i, geom, allowed):
        if geom is None:
            return None, None
        t = geom.get("type")
        c = geom.get("coordinates")
        if t not in allowed:
            raise FormatError(f"{where(name)}feature {i}: geometry type {t!r}, expected one of {allowed}")
        if t == "Point":
            return t, [_position(c, name, i)]
        if t == "LineString":
            if not isinstance(c, list) or len(c) < 2:
                raise FormatError(f"{where(name)}feature {i}: a LineString needs >= 2 positions")
            return t, [_position(p, name, i) for p in c]
        if not isinstance(c, list) or not c or not isinstance(c[0], list) or len(c[0]) < 4:
            raise FormatError(f"{where(name)}feature {i}: a Polygon needs a ring of >= 4 positions")
        return t, [_position(p, name, i) for p in c[0]]

    out: dict = {}
    # detections
    rows = groups["detection"]
    pos = []
    for i, g, p in rows:
        _, c = coords_of(i, g, ("Point",))
        pos.append(c[0] if c else (np.nan, np.nan, np.nan))
    det_kinds = COLUMNS["detections"]
    dets = _props_table([p for _, _, p in rows], det_kinds, f"{where(name)}detections")
    dets.pop("time_utc", None)
    if rows:
        p = np.array(pos, dtype=np.float64).reshape(-1, 3)
        dets["lat_deg"], dets["lon_deg"], dets["height_m"] = p[:, 0], p[:, 1], p[:, 2]
    out["detections"] = dets
    for kind, table in (("truth", "truth"), ("track", "tracks")):
        out[table] = _lines_table(groups[kind], kind, table, name, coords_of)
    # roads
    nodes = []
    for i, g, p in groups["road_node"]:
        _, c = coords_of(i, g, ("Point",))
        lat, lon, h = c[0] if c else (np.nan, np.nan, np.nan)
        nodes.append(dict(p, lat_deg=lat, lon_deg=lon, height_m=h))
    out["road_nodes"] = _props_table(nodes, dict(NODE_COLUMNS, lat_deg="float", lon_deg="float",
                                                 height_m="float"), f"{where(name)}road nodes")
    edges = []
    for i, g, p in groups["road"]:
        coords_of(i, g, ("LineString",))
        edges.append(p)
    out["road_edges"] = _props_table(edges, EDGE_COLUMNS, f"{where(name)}roads")
    # clutter
    regions = []
    for i, g, p in groups["clutter"]:
        _, c = coords_of(i, g, ("Polygon",))
        ring = np.array(c, dtype=np.float64)[:-1]
        reg = {k: v for k, v in p.items() if k != "kind"}
        reg["lat_deg"], reg["lon_deg"] = ring[:, 0], ring[:, 1]
        regions.append(reg)
    out["clutter_regions"] = regions
    out["attrs"] = {"scene_epoch_utc": doc.get("scene_epoch_utc")}
    _add_empty_tables(out, doc.get("empty_tables"), name)
    return out


_DTYPES = {"float": np.float64, "int": np.int64, "bool": bool, "u8": np.uint8, "str": str}


def _add_empty_tables(out: dict, listed, name) -> None:
    """The columns of the tables written without rows (the ``empty_tables`` member), as
    zero-row arrays of their types (:data:`formats.csvtable.COLUMNS`)."""
    if listed is None:
        return
    if not isinstance(listed, dict) or not all(
            isinstance(cols, list) and all(isinstance(c, str) for c in cols)
            for cols in listed.values()):
        raise FormatError(f"{where(name)}'empty_tables' must map table names to lists of "
                          "column names")
    for table, cols in listed.items():
        if table not in ("detections", "truth", "tracks"):
            continue
        got = out[table]
        if got and len(next(iter(got.values()))):
            raise FormatError(f"{where(name)}'empty_tables' lists {table!r}, which has "
                              "features")
        for c in cols:
            kind = COLUMNS[table].get(c, "float")
            got.setdefault(c, np.zeros(0, _DTYPES.get(kind, np.float64)))
