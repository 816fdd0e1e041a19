"""Road maps: table columns, graph, the default scene's layout, inline maps and bad input."""
import numpy as np
import pytest
from omegaconf import OmegaConf

from gmtiflow.errors import RoadMapError
from gmtiflow.scene.roadmap import (DEFAULT_LAKE_POLYGON_M, RoadmapConfig, RoadmapKind, RoadSpec,
                                    from_inline, load_roadmap, point_in_polygon)

NODE_COLUMNS = ["node_id", "name", "x_m", "y_m", "z_m", "lat_deg", "lon_deg", "height_m"]
EDGE_COLUMNS = ["edge_id", "from_node", "to_node", "length_m", "oneway", "speed_limit_mps",
                "invisible", "road_class"]


@pytest.fixture(scope="module")
def default_map():
    return load_roadmap(RoadmapConfig())


def test_tables_have_exactly_the_documented_columns(default_map):
    assert list(default_map.nodes) == NODE_COLUMNS
    assert list(default_map.edges) == EDGE_COLUMNS
    n = default_map.nodes
    assert n["node_id"].dtype == np.int64 and n["name"].dtype.kind == "U"
    assert np.array_equal(n["node_id"], np.arange(len(n["node_id"])))
    e = default_map.edges
    assert e["oneway"].dtype == bool and e["invisible"].dtype == bool
    assert e["from_node"].dtype == np.int64
    assert default_map.attribution == ""


def test_edge_length_is_euclidean_3d_and_graph_honours_oneway(default_map):
    e, n = default_map.edges, default_map.nodes
    xyz = np.column_stack([n["x_m"], n["y_m"], n["z_m"]])
    assert np.allclose(e["length_m"], np.linalg.norm(xyz[e["to_node"]] - xyz[e["from_node"]],
                                                     axis=1))
    g = default_map.graph
    for eid, f, t, one in zip(e["edge_id"], e["from_node"], e["to_node"], e["oneway"]):
        assert g.edges[f, t]["edge_id"] == eid
        assert g.has_edge(t, f) != bool(one)
    assert e["oneway"].sum() == 1


def test_geodetic_columns_round_trip_to_the_origin(default_map):
    o = default_map.origin
    assert (o.lat_deg, o.lon_deg, o.height_m) == (50.63, 7.13, 150.0)
    n = default_map.nodes
    i = default_map.node_index("g_4_2")  # the node at (0, 0)
    assert (n["x_m"][i], n["y_m"][i]) == (0.0, 0.0)
    assert n["lat_deg"][i] == pytest.approx(50.63, abs=1e-9)
    assert n["height_m"][i] == pytest.approx(150.0, abs=1e-6)
    # 1 km north is 1/111.2 degree of latitude at 50.6 N (meridian arc ~111.2 km/deg).
    j = default_map.node_index("g_4_0")  # (0, -1000)
    assert n["lat_deg"][i] - n["lat_deg"][j] == pytest.approx(1000 / 111_210, rel=2e-3)


def test_default_scene_layout(default_map):
    n, e = default_map.nodes, default_map.edges
    assert np.all(np.abs(n["x_m"]) <= 4000) and np.all(np.abs(n["y_m"]) <= 4000)
    # Motorway at y = -1500 with one invisible 1 km tunnel.
    hw = np.char.startswith(n["name"], "hw_") & (np.char.find(n["name"], "~") < 0)
    assert hw.sum() >= 10 and np.all(n["y_m"][hw] == -1500)
    inv = e["invisible"]
    assert inv.sum() == 1 and e["length_m"][inv].sum() == pytest.approx(1000.0)
    assert set(e["road_class"][inv]) == {"motorway"}
    # Country road north of the ridge (y 1000..1500).
    north = np.char.startswith(n["name"], "n_")
    assert north.sum() >= 5 and np.all((n["y_m"][north] >= 1000) & (n["y_m"][north] <= 1500))
    # A curved road: a chain of >= 8 nodes whose turning angles are small.
    curve = np.char.startswith(n["name"], "c_")
    assert curve.sum() >= 8


def test_no_default_road_enters_the_lake(default_map):
    n, e = default_map.nodes, default_map.edges
    f = np.linspace(0.0, 1.0, 201)[:, None]
    x = n["x_m"][e["from_node"]] + f * (n["x_m"][e["to_node"]] - n["x_m"][e["from_node"]])
    y = n["y_m"][e["from_node"]] + f * (n["y_m"][e["to_node"]] - n["y_m"][e["from_node"]])
    assert not point_in_polygon(x, y, DEFAULT_LAKE_POLYGON_M).any()
    # The test itself can fail: the lake's centre is inside.
    assert point_in_polygon(2800.0, 2300.0, DEFAULT_LAKE_POLYGON_M)


def test_default_scene_is_one_strongly_connected_network(default_map):
    assert len(default_map.largest_component()) == default_map.n_nodes


def test_inline_via_points_become_a_chain(square_map):
    n = square_map.nodes
    i = square_map.node_index("s0~t1#1")
    assert (n["x_m"][i], n["y_m"][i]) == (400.0, 600.0)
    assert square_map.graph.has_edge(square_map.node_index("s0"), i)
    assert square_map.graph.has_edge(i, square_map.node_index("t1"))


def test_node_references(square_map):
    assert square_map.node_index("t1") == 2
    assert square_map.node_index([990.0, 20.0]) == square_map.node_index("s1")
    assert square_map.node_index((5090, 4990)) == square_map.node_index("iso_b")
    with pytest.raises(RoadMapError, match="unknown node 'nowhere'"):
        square_map.node_index("nowhere")
    with pytest.raises(RoadMapError, match="must be a name"):
        square_map.node_index([1.0])


@pytest.mark.parametrize("nodes, roads, match", [
    ({}, [], "empty"),
    ({"a": [0, 0]}, [], "empty"),
    ({"a": [0, 0], "b": [1, 0]}, [RoadSpec("a", "c")], r"roads\[0\].to_node: unknown node 'c'"),
    ({"a": [0, 0], "b": [1, float("nan")]}, [RoadSpec("a", "b")], "node 'b'"),
    ({"a": [0, 0], "b": [1]}, [RoadSpec("a", "b")], "node 'b'"),
    ({"a": [0, 0], "b": [1, 0]}, [RoadSpec("a", "b", speed_limit_mps=-3)], "speed_limit_mps"),
])
def test_bad_inline_maps_raise_roadmap_error(nodes, roads, match):
    with pytest.raises(RoadMapError, match=match):
        from_inline(RoadmapConfig(kind=RoadmapKind.inline, nodes=nodes, roads=roads))


def test_problems_name_the_key():
    cfg = RoadmapConfig(kind=RoadmapKind.inline, nodes={"a": [0, 0]},
                        roads=[RoadSpec("a", "zz", speed_limit_mps=0.0)],
                        origin_lat_deg=95.0)
    keys = {p.key for p in cfg.problems()}
    assert keys == {"origin_lat_deg", "roads[0].speed_limit_mps", "roads[0].to_node"}
    assert [p.key for p in RoadmapConfig(kind=RoadmapKind.osm).problems()] == ["path"]
    assert RoadmapConfig().problems() == []


@pytest.mark.parametrize("name", ["default", "osm", "geojson"])
def test_presets_use_only_schema_fields(name):
    from pathlib import Path
    path = Path(__file__).resolve().parents[2] / "conf" / "roadmap" / f"{name}.yaml"
    raw = OmegaConf.to_container(OmegaConf.load(path))
    # The only defaults entry a file map may carry: it brings the random fleet, since the
    # default vehicles name nodes of the built-in town.
    defaults = raw.pop("defaults", [])
    assert defaults == ([] if name == "default" else
                        [{"override /vehicles@_global_.vehicles": "random"}])
    cfg = OmegaConf.merge(OmegaConf.structured(RoadmapConfig), raw)
    assert RoadmapKind(cfg.kind).value == name
    if name != "default":
        assert raw["path"] == "???"


def test_point_in_polygon_square():
    sq = [[0, 0], [1, 0], [1, 1], [0, 1]]
    got = point_in_polygon([0.5, 1.5, -0.1, 0.99], [0.5, 0.5, 0.5, 0.01], sq)
    assert got.tolist() == [True, False, False, True]


def test_draping_on_terrain_recomputes_lengths(square_map):
    hill = lambda x, y: 0.1 * np.asarray(x)  # noqa: E731  (a 10 % slope up to the east)
    d = square_map.draped(hill, offset_m=1.0)
    assert np.allclose(d.nodes["z_m"], 0.1 * d.nodes["x_m"] + 1.0)
    i = d.node_index("s1")
    assert d.nodes["height_m"][i] - d.nodes["height_m"][d.node_index("s0")] == \
        pytest.approx(100.0, abs=0.1)
    e = d.edges["edge_id"][0]                                   # s0 -> s1, 1000 m east
    assert d.edges["length_m"][e] == pytest.approx(np.hypot(1000.0, 100.0))
    assert d.graph.edges[0, 1]["length_m"] == pytest.approx(np.hypot(1000.0, 100.0))
    assert np.all(square_map.nodes["z_m"] == 0.0)                 # the original is unchanged
    with pytest.raises(RoadMapError, match="finite"):
        square_map.draped(lambda x, y: np.full_like(x, np.nan))
