"""GeoJSON opened by GDAL (pyogrio, test extra): every file we write opens, each property has
one type, and the values GDAL reads are ours."""
from __future__ import annotations

import numpy as np
import pytest

from gmtiflow.formats import geojson, synthetic
from tests.external_tools import gdal_read

EPOCH = synthetic.EPOCH_UTC


def _roads():
    nodes = {"node_id": np.arange(3), "name": np.array(["a", "b", "osm:42"]),
             "x_m": np.array([0.0, 10.0, 20.0]), "y_m": np.zeros(3), "z_m": np.array([1.0, 2.0, 3.0]),
             "lat_deg": np.array([43.7, 43.71, 43.72]), "lon_deg": np.array([7.4, 7.41, 7.42]),
             "height_m": np.array([10.0, 20.0, 30.0])}
    edges = {"edge_id": np.arange(2), "from_node": np.array([0, 1]), "to_node": np.array([1, 2]),
             "length_m": np.array([100.0, 200.0]), "oneway": np.array([True, False]),
             "speed_limit_mps": np.array([np.nan, 13.9]), "invisible": np.array([False, True]),
             "road_class": np.array(["primary", "service"])}
    return nodes, edges


def test_gdal_opens_the_scene_file_with_one_type_per_property(tmp_path):
    _, dets = synthetic.tables(5, 40, seed=3)
    dets["snr_db"][3] = np.nan
    nodes, edges = _roads()
    path = tmp_path / "scene.geojson"
    geojson.write_geojson(path, detections=dets, road_nodes=nodes, road_edges=edges,
                          clutter_regions=[{"name": "lake", "density_per_km2": 2.0,
                                            "lat_deg": [43.0, 43.1, 43.0],
                                            "lon_deg": [7.0, 7.0, 7.1]}], epoch_utc=EPOCH)
    fields, types, _ = gdal_read(path)
    assert types["det_id"].startswith("OFTInteger") and types["time_s"] == "OFTReal"
    assert types["snr_db"] == "OFTReal" and types["kind"] == "OFTString"
    assert not any(t.endswith("List") for t in types.values())
    kind = fields["kind"].astype(str)
    det = kind == "detection"
    assert det.sum() == 40 and (kind == "road").sum() == 2 and (kind == "clutter").sum() == 1
    np.testing.assert_array_equal(fields["time_s"][det].astype(float), dets["time_s"])
    snr = fields["snr_db"][det].astype(float)
    assert np.isnan(snr[3]) and np.array_equal(snr[:3], dets["snr_db"][:3])
    np.testing.assert_array_equal(fields["det_id"][det].astype(np.int64), dets["det_id"])


def test_gdal_opens_the_truth_file_with_numeric_per_vertex_lists(tmp_path):
    truth = synthetic.truth(3, 7)
    truth["invisible"] = np.arange(len(truth["time_s"])) % 3 == 0
    path = tmp_path / "truth.geojson"
    geojson.write_geojson(path, truth=truth, epoch_utc=EPOCH)
    fields, types, geom = gdal_read(path)
    assert geom.startswith("LineString")
    assert types["time_s"] == "OFTRealList" and types["vehicle_id"].startswith("OFTInteger")
    assert types["invisible"] == "OFTIntegerList"                 # booleans as 0/1
    order = np.lexsort((truth["time_s"], truth["vehicle_id"]))
    got = np.concatenate([np.asarray(v, float) for v in fields["time_s"]])
    np.testing.assert_array_equal(got, np.asarray(truth["time_s"])[order])
    back = geojson.read_geojson(path)["truth"]
    assert back["invisible"].dtype == bool
    assert sorted(back["invisible"].tolist()) == sorted(truth["invisible"].tolist())
