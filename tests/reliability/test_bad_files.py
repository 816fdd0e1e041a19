"""Bad input files found by the fuzzers (benchmarks/fuzz.py), each pinned as a regression:
the loader raises the project's own error naming the file and what is wrong, never a bare
UnicodeDecodeError / OSError / OverflowError / RecursionError, and never accepts wrong data."""
from __future__ import annotations

import json

import pytest

from gmtiflow.formats.csvtable import encode_csv, read_truth_csv
from gmtiflow.formats.errors import FormatError
from gmtiflow.formats import synthetic
from gmtiflow.errors import InputFileError, RoadMapError
from gmtiflow.scene.dem import read_ascii_grid
from gmtiflow.scene.geojson_roads import load_geojson
from gmtiflow.scene.osm import load_osm
from gmtiflow.sensor.rcs import load_table

OSM = """<?xml version="1.0" encoding="UTF-8"?>
<osm version="0.6">
 <node id="1" lat="{lat}" lon="{lon}"/>
 <node id="2" lat="43.7310" lon="7.4210"/>
 <way id="10"><nd ref="1"/><nd ref="2"/><tag k="highway" v="primary"/></way>
</osm>
"""

GRID = "ncols {ncols}\nnrows 2\nxllcorner {x}\nyllcorner 0\ncellsize 10\n1 2\n3 4\n"


@pytest.mark.parametrize("lat, lon", [("91", "7.42"), ("43.73", "200"), ("43.73", "inf"),
                                      ("nan", "7.42"), ("-90.5", "0")])
def test_osm_node_outside_the_globe_is_refused_with_its_line(tmp_path, lat, lon):
    # lat 91 / lon 200 used to be accepted and silently projected to a wrong place
    path = tmp_path / "bad.osm"
    path.write_text(OSM.format(lat=lat, lon=lon))
    with pytest.raises(RoadMapError, match=r"bad\.osm: node 1 \(line 3\)"):
        load_osm(path)


def test_osm_in_a_wrong_character_encoding_is_a_roadmap_error(tmp_path):
    # lxml raises OSError ("Invalid bytes in character encoding"), which used to escape
    path = tmp_path / "latin.osm"
    path.write_bytes(OSM.format(lat="43.73", lon="7.42").replace('id="10"', 'id="10\xe9"')
                     .encode("latin-1"))
    with pytest.raises(RoadMapError, match="latin.osm"):
        load_osm(path)


def test_deeply_nested_geojson_road_map_is_a_roadmap_error(tmp_path):
    path = tmp_path / "deep.geojson"
    path.write_text("[" * 100_000 + "]" * 100_000)      # used to raise RecursionError
    with pytest.raises(RoadMapError, match="nested too deeply"):
        load_geojson(path)


def test_geojson_road_map_of_points_only_is_refused(tmp_path):
    path = tmp_path / "points.geojson"
    path.write_text(json.dumps({"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {}, "geometry": {"type": "Point",
                                                           "coordinates": [7.4, 43.7]}}]}))
    with pytest.raises(RoadMapError, match="points.geojson"):
        load_geojson(path)


def test_rcs_table_that_is_not_utf8_names_the_file(tmp_path):
    path = tmp_path / "rcs.csv"
    path.write_bytes(b"aspect_deg,rcs_dbsm\n0,10\n\xff\xfe90,12\n")   # used to escape as
    with pytest.raises(InputFileError, match=r"rcs\.csv: not UTF-8"):  # UnicodeDecodeError
        load_table(str(path))


@pytest.mark.parametrize("ncols, x, match", [("inf", "0", "ncols must be an integer"),
                                             ("nan", "0", "ncols must be an integer"),
                                             ("2", "inf", "xllcorner must be a finite"),
                                             ("2", "nan", "xllcorner must be a finite")])
def test_ascii_grid_with_non_finite_header_is_refused(tmp_path, ncols, x, match):
    # ncols inf used to raise OverflowError; xllcorner inf was accepted (a grid at infinity)
    path = tmp_path / "grid.asc"
    path.write_text(GRID.format(ncols=ncols, x=x))
    with pytest.raises(InputFileError, match=match):
        read_ascii_grid(path)


def test_csv_integer_beyond_64_bits_is_a_format_error():
    text = encode_csv(synthetic.truth(2, 2), "truth", epoch_utc=synthetic.EPOCH_UTC).decode()
    lines = text.splitlines()
    cells = lines[1].split(",")
    cells[2] = "9" * 25                                 # vehicle_id: used to raise OverflowError
    lines[1] = ",".join(cells)
    with pytest.raises(FormatError, match=r"line 2, column 3 \(vehicle_id\).*within 64 bits"):
        read_truth_csv("\n".join(lines).encode())


def test_xml_number_the_schema_admits_but_python_cannot_read_is_a_format_error():
    # libxml2 validates "4e" as xs:double; float("4e") raised ValueError out of read_xml
    from gmtiflow.formats import xmldoc
    dwells, dets = synthetic.tables(2, 3)
    doc = xmldoc.encode_xml(dwells, dets, {"epoch_utc": synthetic.EPOCH_UTC}).decode()
    key = ' snr_db="'
    i = doc.index(key) + len(key)
    j = doc.index('"', i)
    bad = doc[:i] + "4e" + doc[j:]
    with pytest.raises(FormatError, match=r"line \d+: attribute .*'4e' is not a readable number"):
        xmldoc.read_xml(bad.encode())
