"""OSM XML and GeoJSON road maps: real data (Monaco, Bautzen), tags, and malformed files."""
import json
from pathlib import Path

import numpy as np
import pytest
from lxml import etree

from gmtiflow.errors import InputFileError, RoadMapError
from gmtiflow.scene.geojson_roads import load_geojson
from gmtiflow.scene.osm import hardened_parser, load_osm, parse_maxspeed
from gmtiflow.scene.roadmap import (DRIVABLE_HIGHWAY_CLASSES, OSM_ATTRIBUTION, RoadmapConfig,
                                    RoadmapKind, load_roadmap)
from gmtiflow.scene.routes import shortest_route
from gmtiflow.scene.vehicles import RandomFleetSpec, VehiclesConfig, build_fleet

from .conftest import batch_routes_match_one_by_one

DATA = Path("/work/shared/data")
MONACO = DATA / "monaco.osm"
BAUTZEN = DATA / "bautzen.osm"
needs_data = pytest.mark.skipif(not MONACO.is_file() or not BAUTZEN.is_file(),
                                reason="shared OSM test data not present")


@pytest.fixture(scope="module")
def monaco():
    return load_roadmap(RoadmapConfig(kind=RoadmapKind.osm, path=str(MONACO)))


@pytest.fixture(scope="module")
def monaco_ways():
    """(tags, node refs) of the drivable ways, read independently of the loader."""
    root = etree.parse(str(MONACO)).getroot()
    out = []
    for w in root.iter("way"):
        tags = {t.get("k"): t.get("v") for t in w.iter("tag")}
        if tags.get("highway") in DRIVABLE_HIGHWAY_CLASSES:
            out.append((tags, [nd.get("ref") for nd in w.iter("nd")]))
    return out


@needs_data
def test_monaco_counts_match_the_data_readme(monaco):
    e = monaco.edges
    assert len(e["edge_id"]) == 3221                          # node-to-node segments
    assert e["length_m"].sum() / 1000 == pytest.approx(60.7, abs=0.1)
    assert e["length_m"][e["invisible"]].sum() / 1000 == pytest.approx(6.6, abs=0.1)
    assert set(e["road_class"]) <= set(DRIVABLE_HIGHWAY_CLASSES)
    assert "footway" not in set(e["road_class"]) and "steps" not in set(e["road_class"])
    assert monaco.attribution == OSM_ATTRIBUTION
    # No <bounds>: the origin is the centre of the road nodes, inside the README's box.
    assert 43.72177 < monaco.origin.lat_deg < 43.75196
    assert 7.40434 < monaco.origin.lon_deg < 7.43928
    assert monaco.origin.height_m == 0.0
    # Node names are OSM ids.
    assert monaco.node_index(int(monaco.nodes["name"][17])) == 17


@needs_data
def test_monaco_tunnels_are_invisible_and_oneways_honoured(monaco, monaco_ways):
    g = monaco.graph
    e = monaco.edges
    tunnel_ways = [refs for tags, refs in monaco_ways if tags.get("tunnel") == "yes"]
    assert len(tunnel_ways) == 51
    for refs in tunnel_ways:
        for a, b in zip(refs[:-1], refs[1:]):
            ia, ib = monaco.node_index(a), monaco.node_index(b)
            eid = g.edges[ia, ib]["edge_id"] if g.has_edge(ia, ib) else g.edges[ib, ia]["edge_id"]
            assert e["invisible"][eid]
    two_way = set()
    for tags, refs in monaco_ways:
        if tags.get("oneway") not in ("yes", "-1") and tags.get("junction") != "roundabout":
            two_way |= {frozenset(p) for p in zip(refs[:-1], refs[1:])}
    checked = 0
    for tags, refs in monaco_ways:
        ow = tags.get("oneway")
        if ow not in ("yes", "-1"):
            continue
        for a, b in zip(refs[:-1], refs[1:]):
            if frozenset((a, b)) in two_way:
                continue                                    # also part of a two-way road
            if ow == "-1":
                a, b = b, a
            ia, ib = monaco.node_index(a), monaco.node_index(b)
            assert g.has_edge(ia, ib) and not g.has_edge(ib, ia), (a, b)
            checked += 1
    assert checked > 500


@needs_data
def test_monaco_routes_and_random_fleet(monaco):
    comp = monaco.largest_component()
    assert 0.8 * monaco.n_nodes < len(comp) < monaco.n_nodes      # isolated bits are kept
    a, b = comp[0], comp[len(comp) // 2]
    r = shortest_route(monaco, int(monaco.nodes["name"][a]), str(monaco.nodes["name"][b]))
    assert r.length_m > 0
    fl = build_fleet(VehiclesConfig(random=RandomFleetSpec(count=25, random_stop_rate_per_s=0.01)),
                     monaco, 2, 300.0, 1.0)
    tt = fl.truth_table(np.arange(0.0, 300.0, 1.0))
    assert np.all(np.isin(tt["edge_id"], monaco.edges["edge_id"]))
    assert np.array_equal(tt["invisible"], monaco.edges["invisible"][tt["edge_id"]])


@needs_data
def test_monaco_routes_are_as_short_as_networkx_dijkstra(monaco):
    import networkx as nx
    comp = monaco.largest_component()
    rng = np.random.default_rng(0)
    for a, b in rng.choice(comp, size=(15, 2)):
        if a == b:
            continue
        r = shortest_route(monaco, str(monaco.nodes["name"][a]), str(monaco.nodes["name"][b]))
        want = nx.dijkstra_path_length(monaco.graph, int(a), int(b), weight="length_m")
        assert r.length_m == pytest.approx(want, rel=1e-12)
        for u, v, eid in zip(r.node_ids[:-1], r.node_ids[1:], r.edge_id):
            assert monaco.graph.edges[u, v]["edge_id"] == eid       # only allowed directions


@needs_data
def test_bautzen_without_metadata_attributes():
    rm = load_osm(BAUTZEN)
    e = rm.edges
    assert len(e["edge_id"]) == 228
    assert not e["invisible"].any()
    # <bounds> 51.1872-51.1919 N, 14.4079-14.4160 E: the origin is its centre.
    assert rm.origin.lat_deg == pytest.approx(51.18955)
    assert rm.origin.lon_deg == pytest.approx(14.41195)
    # Motorways are oneway (tagged or implied); the cycleway and tracks are dropped.
    assert np.all(e["oneway"][e["road_class"] == "motorway"])
    assert not set(e["road_class"]) & {"cycleway", "track"}
    lax = load_osm(BAUTZEN, RoadmapConfig(implied_oneway=False))
    assert lax.edges["oneway"].sum() <= e["oneway"].sum()


def test_maxspeed_parsing():
    assert parse_maxspeed("50") == pytest.approx(50 / 3.6)
    assert parse_maxspeed("30 mph") == pytest.approx(13.4112)
    assert parse_maxspeed("80 km/h") == pytest.approx(80 / 3.6)
    for bad in (None, "none", "signals", "RU:urban", "50;30", "-5", "0"):
        assert np.isnan(parse_maxspeed(bad))


def osm_text(body, header=""):
    return f'<?xml version="1.0"?>{header}<osm version="0.6">{body}</osm>'


NODES = ('<node id="1" lat="50.0" lon="7.0"/><node id="2" lat="50.001" lon="7.0"/>'
         '<node id="3" lat="50.001" lon="7.001"/>')


def write(tmp_path, text, name="map.osm"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_small_osm_tags(tmp_path):
    body = NODES + (
        '<way id="10"><nd ref="1"/><nd ref="2"/><tag k="highway" v="primary"/>'
        '<tag k="oneway" v="-1"/><tag k="maxspeed" v="30 mph"/></way>'
        '<way id="11"><nd ref="2"/><nd ref="3"/><tag k="highway" v="residential"/>'
        '<tag k="tunnel" v="yes"/></way>'
        '<way id="12"><nd ref="1"/><nd ref="3"/><tag k="highway" v="footway"/></way>')
    rm = load_osm(write(tmp_path, osm_text(body)))
    e = rm.edges
    assert rm.nodes["name"].tolist() == ["1", "2", "3"]
    assert len(e["edge_id"]) == 2                              # the footway is dropped
    assert (e["from_node"][0], e["to_node"][0]) == (1, 0)      # oneway=-1: stored reversed
    assert e["oneway"].tolist() == [True, False]
    assert e["invisible"].tolist() == [False, True]
    assert e["speed_limit_mps"][0] == pytest.approx(13.4112) and np.isnan(e["speed_limit_mps"][1])
    assert rm.graph.has_edge(1, 0) and not rm.graph.has_edge(0, 1)
    assert rm.nodes["y_m"][1] - rm.nodes["y_m"][0] == pytest.approx(111.2, abs=0.2)  # 0.001°


def test_deleted_elements_are_ignored(tmp_path):
    body = NODES + ('<way id="10"><nd ref="1"/><nd ref="2"/><tag k="highway" v="primary"/></way>'
                    '<way id="11" action="delete"><nd ref="2"/><nd ref="3"/>'
                    '<tag k="highway" v="primary"/></way>')
    rm = load_osm(write(tmp_path, osm_text(body)))
    assert len(rm.edges["edge_id"]) == 1 and rm.n_nodes == 2


@pytest.mark.parametrize("text, match", [
    ("this is not xml", "not well-formed"),
    ('<?xml version="1.0"?><gpx></gpx>', "expected <osm>"),
    (osm_text(NODES), "no drivable highway"),
    (osm_text(NODES + '<way id="7"><nd ref="1"/><nd ref="99"/><tag k="highway" v="primary"/>'
                      '</way>'), "way 7 refers to node 99"),
    (osm_text('<node id="1" lat="x" lon="7"/><node id="2" lat="50" lon="7"/><way id="7">'
              '<nd ref="1"/><nd ref="2"/><tag k="highway" v="primary"/></way>'),
     "node 1 .* no valid lat/lon"),
    (osm_text(NODES + '<way id="7"><nd ref="1"/><tag k="highway" v="primary"/></way>'),
     "no segments"),
])
def test_malformed_osm_raises_roadmap_error(tmp_path, text, match):
    with pytest.raises(RoadMapError, match=match):
        load_osm(write(tmp_path, text))


def test_osm_parser_is_hardened(tmp_path):
    secret = tmp_path / "secret.txt"
    secret.write_text("TOPSECRET")
    header = f'<!DOCTYPE osm [<!ENTITY leak SYSTEM "file://{secret}">]>'
    body = NODES + ('<way id="7"><nd ref="1"/><nd ref="2"/><tag k="highway" v="primary"/>'
                    '<tag k="name">&leak;</tag></way>')
    path = write(tmp_path, osm_text(body, header))
    naive = etree.parse(str(path), etree.XMLParser(resolve_entities=True, load_dtd=True))
    assert "TOPSECRET" in etree.tostring(naive).decode()          # the attack works on a naive one
    hard = etree.parse(str(path), hardened_parser())
    assert "TOPSECRET" not in etree.tostring(hard).decode()
    assert len(load_osm(path).edges["edge_id"]) == 1


def test_osm_parser_refuses_entity_expansion_bombs(tmp_path):
    lol = ('<!DOCTYPE osm [<!ENTITY a "aaaaaaaaaa">' + "".join(
        f'<!ENTITY {c} "{("&" + p + ";") * 10}">' for p, c in zip("abcdefgh", "bcdefghi")) + "]>")
    with pytest.raises(RoadMapError):
        load_osm(write(tmp_path, osm_text(NODES + '<way id="7"><nd ref="1"/><nd ref="2"/>'
                                          '<tag k="highway" v="&i;"/></way>', lol)))


def test_missing_osm_file():
    with pytest.raises(InputFileError, match="not found"):
        load_osm("/nonexistent/map.osm")
    with pytest.raises(InputFileError, match="path"):
        load_roadmap(RoadmapConfig(kind=RoadmapKind.osm))


# -- GeoJSON ------------------------------------------------------------------------------------
def feature(coords, multi=False, **props):
    return {"type": "Feature", "properties": props,
            "geometry": {"type": "MultiLineString" if multi else "LineString",
                         "coordinates": coords}}


def test_geojson_lines_merge_at_shared_vertices(tmp_path):
    doc = {"type": "FeatureCollection", "features": [
        feature([[7.0, 50.0], [7.0, 50.001]], oneway="yes", maxspeed=50, highway="primary"),
        feature([[7.0, 50.001], [7.001, 50.001]], tunnel=True),
        feature([[[7.001, 50.001], [7.001, 50.0]], [[7.001, 50.0], [7.0, 50.0]]], multi=True,
                oneway="-1", maxspeed="30 mph"),
        feature([[7.0, 50.0], [7.002, 50.0]], highway="footway"),
        {"type": "Feature", "properties": {}, "geometry": {"type": "Point",
                                                           "coordinates": [7, 50]}},
    ]}
    rm = load_geojson(write(tmp_path, json.dumps(doc), "r.geojson"))
    e = rm.edges
    assert rm.n_nodes == 4 and len(e["edge_id"]) == 4           # a closed square, footway dropped
    assert e["oneway"].tolist() == [True, False, True, True]
    assert e["invisible"].tolist() == [False, True, False, False]
    assert e["speed_limit_mps"][0] == pytest.approx(50 / 3.6)
    assert e["speed_limit_mps"][2] == pytest.approx(13.4112)
    # oneway=-1: the MultiLineString is travelled from its end to its start: gj0 -> gj3 -> gj2.
    assert list(zip(e["from_node"][2:], e["to_node"][2:])) == [(3, 2), (0, 3)]
    # gj0 -> gj1 and gj0 -> gj3 -> gj2 are oneway away from gj0: only gj1 <-> gj2 is strongly
    # connected.
    assert rm.largest_component().tolist() == [1, 2]
    assert rm.origin.lat_deg == pytest.approx(50.0005) and rm.attribution == ""


@pytest.mark.parametrize("text, match", [
    ("{not json", "not valid JSON"),
    (json.dumps([1, 2]), "not a GeoJSON object"),
    (json.dumps({"type": "FeatureCollection", "features": []}), "no drivable LineString"),
    (json.dumps({"type": "LineString", "coordinates": [[7, 50]]}), ">= 2 finite"),
    (json.dumps({"type": "LineString", "coordinates": [[50, 97], [50, 98]]}), "out of range"),
    (json.dumps({"type": "FeatureCollection", "features": [1]}), r"features\[0\]"),
])
def test_malformed_geojson(tmp_path, text, match):
    with pytest.raises(RoadMapError, match=match):
        load_geojson(write(tmp_path, text, "bad.geojson"))


@needs_data
def test_arcs_and_largest_component_are_networkx_s(monaco):
    # Routing and the random fleet use RoadMap.arcs() and scipy, not the networkx graph: the
    # same arcs in the same order, the same component (ties: the smallest node id).
    import networkx as nx
    g = monaco.graph
    arcs = list(g.edges(data=True))
    a, b, length, eid = monaco.arcs()
    assert list(zip(a.tolist(), b.tolist())) == [(u, v) for u, v, _ in arcs]
    assert length.tolist() == [d["length_m"] for *_, d in arcs]
    assert eid.tolist() == [d["edge_id"] for *_, d in arcs]
    comps = list(nx.strongly_connected_components(g))
    best = max(comps, key=lambda c: (len(c), -min(c)))
    assert len(comps) > 1
    assert monaco.largest_component().tolist() == sorted(best)


@needs_data
def test_many_routes_at_once_on_monaco_are_each_vehicles_own(monaco):
    """shortest_routes on a map of thousands of nodes (predecessor rows walked as arrays, not
    lists; Dijkstra from many sources in one call) gives every vehicle shortest_route's route
    bit for bit, None where it refuses."""
    names = [str(x) for x in monaco.nodes["name"]]
    g = np.random.default_rng(8)
    pairs = [tuple(g.choice(names, 2)) for _ in range(400)]
    refused = batch_routes_match_one_by_one(monaco, pairs)
    assert monaco.n_nodes * len({a for a, _ in pairs}) > 1_000_000      # the array walk
    assert refused < len(pairs) // 2


# -- maps across the antimeridian ---------------------------------------------------------------
# A road from lon 179.9999 to -179.9999 is 22 m long; the origin used to be the mean of the
# extreme longitudes (lon 0, the other side of the earth), which put the two nodes 40,000 km
# apart (x = +-19,970 km) and the run finished without a word.
def test_osm_road_across_the_antimeridian_stays_22_m_long(tmp_path):
    body = ('<node id="1" lat="-17.0" lon="179.9999"/><node id="2" lat="-17.0" lon="-179.9999"/>'
            '<way id="7"><nd ref="1"/><nd ref="2"/><tag k="highway" v="primary"/></way>')
    rm = load_osm(write(tmp_path, osm_text(body)))
    assert abs(abs(rm.origin.lon_deg) - 180.0) < 1e-9 and rm.origin.lat_deg == -17.0
    assert np.ptp(rm.nodes["x_m"]) == pytest.approx(21.3, abs=0.1)      # 0.0002° at 17° S
    assert np.all(np.abs(rm.nodes["x_m"]) < 11.0)


def test_geojson_road_across_the_antimeridian_stays_22_m_long(tmp_path):
    doc = {"type": "FeatureCollection",
           "features": [feature([[179.9999, -17.0], [-179.9999, -17.0]])]}
    rm = load_geojson(write(tmp_path, json.dumps(doc), "r.geojson"))
    assert abs(abs(rm.origin.lon_deg) - 180.0) < 1e-9
    assert np.ptp(rm.nodes["x_m"]) == pytest.approx(21.3, abs=0.1)


@pytest.mark.parametrize("height", [1e9, -5e6, 9500.0])
def test_geojson_road_heights_off_the_earth_are_refused(tmp_path, height):
    """Road heights of 1e9 m or -5e6 m (below the earth's centre) were accepted: the run ended
    with exit 0 and no vehicle ever visible."""
    doc = {"type": "FeatureCollection", "features": [
        feature([[7.0, 50.0, 10.0], [7.0, 50.01, height]])]}
    with pytest.raises(RoadMapError, match=r"r\.geojson: features\[0\]: height .* outside "
                                           r"-1000\.\.9000 m"):
        load_geojson(write(tmp_path, json.dumps(doc), "r.geojson"))


def test_geojson_road_heights_on_the_earth_are_kept(tmp_path):
    doc = {"type": "FeatureCollection", "features": [
        feature([[35.5, 31.5, -410.0], [35.5, 31.51, 8800.0]])]}
    rm = load_geojson(write(tmp_path, json.dumps(doc), "r.geojson"))
    assert rm.nodes["z_m"].max() - rm.nodes["z_m"].min() == pytest.approx(9210.0, abs=1.0)


@pytest.mark.parametrize("load, what", [(load_osm, "OSM file"), (load_geojson, "GeoJSON file")])
def test_a_directory_or_device_as_road_map_is_not_called_missing(tmp_path, load, what):
    """``roadmap.path=`` a directory or /dev/zero said "OSM file not found" (it is there)."""
    for path in (tmp_path, "/dev/zero"):
        with pytest.raises(InputFileError, match=f"^{what} {path}: not a regular file"):
            load(path)


def test_a_compressed_osm_file_is_refused_before_parsing(tmp_path):
    """libxml2 decompresses gzip by itself, so the size and memory checks (made on the file's
    size) saw a 3.6 MB .osm.gz whose parse took 1.3 GB and 14 s (53 MB of XML)."""
    import gzip
    p = tmp_path / "map.osm.gz"
    p.write_bytes(gzip.compress(osm_text(NODES + '<way id="7"><nd ref="1"/><nd ref="2"/>'
                                         '<tag k="highway" v="primary"/></way>').encode()))
    with pytest.raises(RoadMapError, match=r"map\.osm\.gz: compressed \(gzip\); decompress it "
                                           r"first"):
        load_osm(p)


def test_an_osm_pbf_file_is_named_as_such(tmp_path):
    p = tmp_path / "map.osm.pbf"
    p.write_bytes(b"\x00\x00\x00\x0d\x0a\x09OSMHeader\x18\x7f" + bytes(200))
    with pytest.raises(RoadMapError, match=r"map\.osm\.pbf: OSM PBF .*osmium cat"):
        load_osm(p)


# ---- <bounds> and the origin; duplicate ids --------------------------------------------------
ROADS = ('<node id="1" lat="43.700" lon="7.400"/><node id="2" lat="43.705" lon="7.410"/>'
         '<node id="3" lat="43.710" lon="7.420"/>'
         '<way id="10"><nd ref="1"/><nd ref="2"/><tag k="highway" v="primary"/></way>'
         '<way id="11"><nd ref="2"/><nd ref="3"/><tag k="highway" v="residential"/></way>')


def bounds(minlat, minlon, maxlat, maxlon):
    return f'<bounds minlat="{minlat}" minlon="{minlon}" maxlat="{maxlat}" maxlon="{maxlon}"/>'


@pytest.mark.parametrize("box, origin", [
    ((43.69, 7.39, 43.72, 7.43), (43.705, 7.41)),        # an export's box around the roads
    ((43.704, 7.405, 43.706, 7.415), (43.705, 7.41)),    # a small box: ways cross it
    ((43.702, 7.404, 43.703, 7.406), (43.7025, 7.405)),  # no node inside, a way crosses it
    ((43.71, 7.42, 43.80, 7.50), (43.755, 7.46)),        # touching the roads' corner
])
def test_bounds_that_meet_the_roads_give_the_origin(tmp_path, box, origin):
    rm = load_osm(write(tmp_path, osm_text(bounds(*box) + ROADS)))
    assert (rm.origin.lat_deg, rm.origin.lon_deg) == pytest.approx(origin, abs=1e-12)


@pytest.mark.parametrize("box", [
    (44.70, 8.40, 44.72, 8.43),          # a degree away (the audit's file: origin 110 km off)
    (43.70, 7.421, 43.71, 7.45),         # beside the roads, east
    (43.60, 7.39, 43.699, 7.43),         # beside the roads, south
])
def test_bounds_away_from_the_roads_are_refused_naming_file_and_line(tmp_path, box):
    p = write(tmp_path, osm_text(bounds(*box) + ROADS))
    with pytest.raises(RoadMapError) as err:
        load_osm(p)
    message = str(err.value)
    assert message.startswith(f"{p}: <bounds> (line 1) ")
    assert "none of the drivable roads" in message
    assert "lat 43.7 .. 43.71, lon 7.4 .. 7.42" in message             # where the roads are
    assert "roadmap.origin_lat_deg" in message and "\n" not in message


def test_bounds_away_from_the_roads_are_unused_when_the_origin_is_given(tmp_path):
    p = write(tmp_path, osm_text(bounds(44.70, 8.40, 44.72, 8.43) + ROADS))
    rm = load_osm(p, RoadmapConfig(origin_lat_deg=43.7, origin_lon_deg=7.4))
    assert (rm.origin.lat_deg, rm.origin.lon_deg) == (43.7, 7.4)


@pytest.mark.parametrize("second", [
    '<way id="10"><nd ref="2"/><nd ref="3"/><tag k="highway" v="primary"/></way>',
    '<way id="10"><nd ref="1"/><nd ref="2"/><tag k="highway" v="secondary"/></way>',
    '<way id="10"><nd ref="1"/><nd ref="3"/><tag k="highway" v="footway"/></way>',
])
def test_a_way_id_used_twice_for_different_ways_is_refused(tmp_path, second):
    p = write(tmp_path, osm_text(ROADS + "\n" + second))
    with pytest.raises(RoadMapError) as err:
        load_osm(p)
    message = str(err.value)
    assert message.startswith(f"{p}: way 10 appears twice with different ")
    assert "(lines 1 and 2)" in message and "\n" not in message


def test_a_way_repeated_identically_is_read_once(tmp_path):
    # as a node repeated at the same position: the same element twice (concatenated extracts)
    again = '<way id="10"><nd ref="1"/><nd ref="2"/><tag k="highway" v="primary"/></way>'
    once = load_osm(write(tmp_path, osm_text(ROADS), "once.osm"))
    twice = load_osm(write(tmp_path, osm_text(ROADS + again), "twice.osm"))
    for table in ("nodes", "edges"):
        for column, values in once.__getattribute__(table).items():
            np.testing.assert_array_equal(getattr(twice, table)[column], values)


def test_a_deleted_copy_of_a_way_is_not_a_duplicate(tmp_path):
    gone = ('<way id="10" action="delete"><nd ref="2"/><nd ref="3"/>'
            '<tag k="highway" v="primary"/></way>')
    rm = load_osm(write(tmp_path, osm_text(ROADS + gone)))
    assert len(rm.edges["edge_id"]) == 2


def test_ways_without_an_id_are_no_duplicates_of_each_other(tmp_path):
    # OSM requires ids, but id-less hand-written ways were read before the duplicate check came
    body = NODES + ('<way><nd ref="1"/><nd ref="2"/><tag k="highway" v="primary"/></way>'
                    '<way><nd ref="2"/><nd ref="3"/><tag k="highway" v="primary"/></way>')
    assert len(load_osm(write(tmp_path, osm_text(body))).edges["edge_id"]) == 2
