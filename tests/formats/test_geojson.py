"""GeoJSON: RFC 7946 layout, exact round trips, errors."""
from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from gmtiflow.formats import geojson, synthetic
from gmtiflow.formats.errors import FormatError

EPOCH = synthetic.EPOCH_UTC


def _roads():
    nodes = {"node_id": np.arange(3), "name": np.array(["a", "b", "osm:42"]),
             "x_m": np.array([0.0, 10.0, 20.0]), "y_m": np.zeros(3), "z_m": np.array([1.0, 2.0, 3.0]),
             "lat_deg": np.array([43.7, 43.71, 43.72]), "lon_deg": np.array([7.4, -7.41, 7.42]),
             "height_m": np.array([10.0, 20.0, -30.0])}
    edges = {"edge_id": np.arange(2), "from_node": np.array([0, 1]), "to_node": np.array([1, 2]),
             "length_m": np.array([100.0, 200.0]), "oneway": np.array([True, False]),
             "speed_limit_mps": np.array([np.nan, 13.9]), "invisible": np.array([False, True]),
             "road_class": np.array(["primary", "service"])}
    return nodes, edges


def _same(a, b):
    for k, v in a.items():
        v = np.asarray(v)
        if v.dtype.kind == "f":
            np.testing.assert_array_equal(v, b[k], err_msg=k)
        else:
            assert v.tolist() == b[k].tolist(), k


def test_feature_collection_layout_follows_rfc7946():
    _, dets = synthetic.tables(3, 5)
    nodes, edges = _roads()
    doc = json.loads(geojson.encode_geojson(
        detections=dets, road_nodes=nodes, road_edges=edges,
        clutter_regions=[{"name": "c", "lat_deg": [43.0, 43.1, 43.0], "lon_deg": [7.0, 7.0, 7.1]}],
        epoch_utc=EPOCH))
    assert doc["type"] == "FeatureCollection" and "crs" not in doc
    kinds = [f["properties"]["kind"] for f in doc["features"]]
    assert kinds.count("detection") == 5
    truth_doc = json.loads(geojson.encode_geojson(truth=synthetic.truth(2, 3), epoch_utc=EPOCH))
    assert [f["properties"]["kind"] for f in truth_doc["features"]] == ["truth", "truth"]
    assert kinds.count("road_node") == 3 and kinds.count("road") == 2 and kinds.count("clutter") == 1
    det = doc["features"][0]
    assert det["geometry"]["type"] == "Point"
    assert det["geometry"]["coordinates"] == [dets["lon_deg"][0], dets["lat_deg"][0], dets["height_m"][0]]
    assert det["properties"]["time_utc"].endswith("Z")
    road = next(f for f in doc["features"] if f["properties"]["kind"] == "road")
    assert road["geometry"]["coordinates"] == [[7.4, 43.7, 10.0], [-7.41, 43.71, 20.0]]
    assert road["properties"]["speed_limit_mps"] is None             # NaN -> null
    poly = next(f for f in doc["features"] if f["properties"]["kind"] == "clutter")
    ring = np.array(poly["geometry"]["coordinates"][0])
    assert ring[0].tolist() == ring[-1].tolist()                     # closed
    x, y = ring[:, 0], ring[:, 1]
    assert np.sum(x[:-1] * y[1:] - x[1:] * y[:-1]) > 0               # counter-clockwise


def test_round_trip_of_everything_is_exact(tmp_path):
    _, dets = synthetic.tables(6, 50)
    dets["snr_db"][2] = np.nan
    truth = synthetic.truth(4, 6)
    nodes, edges = _roads()
    regions = [{"name": "town", "density_per_km2": 3.5,
                "lat_deg": np.array([43.7, 43.8, 43.7]), "lon_deg": np.array([7.4, 7.45, 7.5])}]
    path = tmp_path / "scene.geojson"
    geojson.write_geojson(path, detections=dets, road_nodes=nodes, road_edges=edges,
                          clutter_regions=regions, epoch_utc=EPOCH)
    geojson.write_geojson(tmp_path / "truth.geojson", truth=truth, epoch_utc=EPOCH)
    r = geojson.read_geojson(path)
    _same(dets, r["detections"])
    _same(truth, geojson.read_geojson(tmp_path / "truth.geojson")["truth"])
    _same(nodes, r["road_nodes"])
    _same(edges, r["road_edges"])
    reg = r["clutter_regions"][0]
    assert reg["name"] == "town" and reg["density_per_km2"] == 3.5
    assert sorted(zip(reg["lat_deg"], reg["lon_deg"])) == sorted(zip(regions[0]["lat_deg"], regions[0]["lon_deg"]))
    assert r["attrs"]["scene_epoch_utc"].startswith("2026-11-21T13:00:00.25")


def test_single_sample_vehicle_is_a_point_and_unlocated_detection_has_null_geometry():
    truth = synthetic.truth(2, 1)
    _, dets = synthetic.tables(2, 2)
    dets["lat_deg"][1] = np.nan
    doc = json.loads(geojson.encode_geojson(truth=truth))
    assert [f["geometry"]["type"] for f in doc["features"]] == ["Point", "Point"]
    assert len(geojson.read_geojson(json.dumps(doc).encode())["truth"]["time_s"]) == 2
    doc = json.loads(geojson.encode_geojson(detections=dets))
    assert doc["features"][1]["geometry"] is None
    r = geojson.read_geojson(json.dumps(doc).encode())
    assert np.isnan(r["detections"]["lat_deg"][1])


def test_truth_is_refused_beside_other_layers():
    _, dets = synthetic.tables(2, 2)
    with pytest.raises(ValueError, match="truth.geojson"):
        geojson.encode_geojson(truth=synthetic.truth(2, 2), detections=dets)


@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**31), n=st.integers(1, 40), lat=st.floats(-80, 80), lon=st.floats(-170, 170))
def test_round_trip_random_detections(seed, n, lat, lon):
    _, dets = synthetic.tables(4, n, seed=seed, lat0=lat, lon0=lon)
    _same(dets, geojson.read_geojson(geojson.encode_geojson(detections=dets))["detections"])


def test_writer_needs_geodetic_columns():
    truth = synthetic.truth(2, 2)
    del truth["lat_deg"]
    with pytest.raises(ValueError, match="geodetic"):
        geojson.encode_geojson(truth=truth)


@pytest.mark.parametrize("data,match", [
    (b"{", r"line 1, column 2: not JSON"),
    (b"[]", "not a GeoJSON FeatureCollection"),
    (b'{"type":"FeatureCollection","features":[1]}', "feature 0: not a GeoJSON Feature"),
    (b'{"type":"FeatureCollection","features":[{"type":"Feature","properties":{"kind":"detection"},'
     b'"geometry":{"type":"Point","coordinates":["a",1]}}]}', "feature 0: a position"),
    (b'{"type":"FeatureCollection","features":[{"type":"Feature","properties":{"kind":"road"},'
     b'"geometry":{"type":"Point","coordinates":[1,2]}}]}', "geometry type 'Point'"),
    (b'{"type":"FeatureCollection","features":[{"type":"Feature","properties":{"kind":"truth",'
     b'"vehicle_id":1,"time_s":[1]},"geometry":{"type":"LineString","coordinates":[[1,2],[3,4]]}}]}',
     "per-vertex"),
    (b'{"type":"FeatureCollection","features":[{"type":"Feature","properties":{"kind":"detection",'
     b'"det_id":"x"},"geometry":null}]}', "det_id"),
    (b'{"type":"FeatureCollection","features":[{"type":"Feature","properties":{"kind":"detection",'
     b'"snr_db":"loud"},"geometry":null}]}', "snr_db"),
    (b'{"type":"FeatureCollection","features":[{"type":"Feature","properties":{"kind":"detection",'
     b'"truth_id":1.5},"geometry":null}]}', "truth_id"),
    (b"\xff\xfe", "not"),
    (b"[" * 100000, "nested|not JSON"),
])
def test_malformed_input_raises_format_error(data, match):
    with pytest.raises(FormatError, match=match):
        geojson.read_geojson(data)


def test_tracks_file_reads_back_exactly_and_stays_apart_from_detections():
    t = synthetic.tracks(4, 6, seed=3)
    t = dict(t, lat_deg=43.7 + t["y_m"] / 111e3, lon_deg=7.4 + t["x_m"] / 80e3)
    doc = geojson.encode_geojson(tracks=t, epoch_utc=EPOCH)
    back = geojson.read_geojson(doc)["tracks"]
    o = np.lexsort((t["track_id"], t["time_s"]))
    _same({k: np.asarray(v)[o] for k, v in t.items()}, back)
    assert "height_m" not in back                       # 2-D positions
    _, dets = synthetic.tables(2, 4)
    with pytest.raises(ValueError, match="tracks.geojson"):
        geojson.encode_geojson(tracks=t, detections=dets)


def _check_same_columns(written, got, what):
    """Every column written comes back with its dtype and values (NaN as NaN)."""
    assert set(written) <= set(got), (what, sorted(set(written) - set(got)))
    for c, v in written.items():
        v = np.asarray(v)
        assert got[c].dtype == v.dtype and got[c].shape == v.shape, (what, c, v.dtype, got[c].dtype)
        np.testing.assert_array_equal(got[c], v, err_msg=f"{what}.{c}")


def _empty(table):
    return {k: np.asarray(v)[:0] for k, v in table.items()}


def test_empty_tables_come_back_with_their_columns():
    """A run without detections, vehicles or tracks: the tables come back with every column
    written and no rows (there is no feature to carry the property names)."""
    _, dets = synthetic.tables(2, 4)
    dets = _empty(dets)
    back = geojson.read_geojson(geojson.encode_geojson(detections=dets, epoch_utc=EPOCH))
    _check_same_columns(dets, back["detections"], "detections")
    t = synthetic.tracks(2, 3)
    t = _empty(dict(t, lat_deg=43.7 + t["y_m"] / 111e3, lon_deg=7.4 + t["x_m"] / 80e3))
    _check_same_columns(t, geojson.read_geojson(geojson.encode_geojson(tracks=t))["tracks"],
                        "tracks")
    truth = synthetic.truth(2, 3)
    truth = _empty(dict(truth, lat_deg=43.7 + truth["y_m"] / 111e3,
                        lon_deg=7.4 + truth["x_m"] / 80e3, height_m=truth["x_m"] * 0))
    _check_same_columns(truth, geojson.read_geojson(geojson.encode_geojson(truth=truth))["truth"],
                        "truth")
    # documents with rows are as before: no list of columns
    _, dets = synthetic.tables(2, 4)
    assert b"empty_tables" not in geojson.encode_geojson(detections=dets, epoch_utc=EPOCH)


def test_a_column_without_any_value_comes_back_as_nan():
    _, dets = synthetic.tables(3, 9)
    for c in ("wrap_velocity_mps", "snr_db", "rcs_dbsm"):
        dets[c][:] = np.nan
    back = geojson.read_geojson(geojson.encode_geojson(detections=dets, epoch_utc=EPOCH))
    _check_same_columns(dets, back["detections"], "detections")
