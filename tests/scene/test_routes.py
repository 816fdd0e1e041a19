"""Routes: Dijkstra picks the shortest path, honours oneway, and reports unreachable goals."""
import itertools
import math

import networkx as nx
import numpy as np
import pytest

from gmtiflow.errors import RoadMapError
from gmtiflow.scene.roadmap import RoadmapConfig, load_roadmap
from gmtiflow.scene import routes
from gmtiflow.scene.routes import off_road_route, shortest_route

from .conftest import batch_routes_match_one_by_one, same_route


def brute_force_shortest(graph, a, b):
    return min(sum(graph.edges[u, v]["length_m"] for u, v in zip(p[:-1], p[1:]))
               for p in nx.all_simple_paths(graph, a, b))


def test_route_is_the_shortest_of_all_simple_paths(square_map):
    nodes = ["s0", "s1", "t1", "t0"]
    for a, b in itertools.permutations(nodes, 2):
        r = shortest_route(square_map, a, b)
        ia, ib = square_map.node_index(a), square_map.node_index(b)
        assert r.length_m == pytest.approx(brute_force_shortest(square_map.graph, ia, ib))
        assert r.node_ids[0] == ia and r.node_ids[-1] == ib


def test_shortest_on_the_default_scene_against_brute_force():
    rm = load_roadmap(RoadmapConfig())
    g = rm.graph
    # All simple paths in the grid would be too many; compare with Bellman-Ford instead.
    for a, b in [("g_0_0", "g_6_2"), ("hw_x-4000", "n_x4000"), ("c_5", "g_1_1")]:
        r = shortest_route(rm, a, b)
        want = nx.bellman_ford_path_length(g, rm.node_index(a), rm.node_index(b),
                                           weight="length_m")
        assert r.length_m == pytest.approx(want)


def test_oneway_is_honoured(square_map):
    # t1 -> t0 directly (oneway westwards) is 1000 m ...
    assert shortest_route(square_map, "t1", "t0").length_m == pytest.approx(1000.0)
    # ... but t0 -> t1 must go round: via s0 and the diagonal chain (1000 + 721.1 + 721.1).
    r = shortest_route(square_map, "t0", "t1")
    diag = np.hypot(400, 600) + np.hypot(600, 400)
    assert r.length_m == pytest.approx(1000.0 + diag)
    names = square_map.nodes["name"][r.node_ids].tolist()
    assert names == ["t0", "s0", "s0~t1#1", "t1"]


def test_polyline_columns(square_map):
    r = shortest_route(square_map, "s1", "t0", stopovers=["t1"])
    assert len(r.edge_id) == len(r.node_ids) - 1 == len(r.invisible)
    assert r.s_m[0] == 0 and np.all(np.diff(r.s_m) > 0)
    assert np.allclose(np.diff(r.s_m), square_map.edges["length_m"][r.edge_id])
    assert np.allclose(r.position_at(r.s_m), r.xyz_m)
    assert np.allclose(r.position_at(500.0), [1000.0, 500.0, 0.0])


def test_stopovers_are_visited_in_order(square_map):
    r = shortest_route(square_map, "s0", "s0", stopovers=["t1"])
    names = square_map.nodes["name"][r.node_ids].tolist()
    assert names[0] == "s0" and names[-1] == "s0" and "t1" in names
    # Out over the diagonal chain and back the same way (cheaper than the oneway top edge).
    assert r.length_m == pytest.approx(2 * (np.hypot(400, 600) + np.hypot(600, 400)))


def test_unreachable_goal_names_vehicle_and_nodes(square_map):
    with pytest.raises(RoadMapError, match=r"car-9: no route from node 's0' to node 'iso_a'"):
        shortest_route(square_map, "s0", "iso_a", who="car-9")


def test_unknown_node_names_vehicle(square_map):
    with pytest.raises(RoadMapError, match=r"truck-2: .*unknown node 'x9'"):
        shortest_route(square_map, "x9", "s0", who="truck-2")


def test_same_start_and_end_is_an_error(square_map):
    with pytest.raises(RoadMapError, match="same node"):
        shortest_route(square_map, "s0", "s0", who="v")


def test_off_road_route():
    r = off_road_route([[0, 0], [30, 40], [30, 40], [30, 100, 5]])
    assert r.length_m == pytest.approx(50 + np.hypot(60, 5))
    assert np.all(r.edge_id == -1) and not r.invisible.any()
    with pytest.raises(RoadMapError, match="two waypoints"):
        off_road_route([[1, 2]])
    # the repeated waypoint is dropped; the arc length is the segments' running sum
    assert r.xyz_m.tolist() == [[0, 0, 0], [30, 40, 0], [30, 100, 5]]
    assert r.s_m.tolist() == [0.0, 50.0, 50.0 + float(np.hypot(60, 5))]
    with pytest.raises(RoadMapError, match="all coincide"):
        off_road_route([[1, 2], [1, 2, 0], [1.0, 2.0]])
    for bad in ([1, float("nan")], [1, 2, float("inf")], [1, 2, 3, 4], [1]):
        with pytest.raises(RoadMapError, match="finite metres"):
            off_road_route([[0, 0], bad])


@pytest.mark.parametrize("walk_entries", [None, 150])
def test_many_routes_at_once_are_each_vehicles_own_route(square_map, monkeypatch, walk_entries):
    """shortest_routes (the random fleet's routes in one go) gives every vehicle the route
    shortest_route gives it, bit for bit, in any order and with repeated pairs; None where
    shortest_route refuses (same node, unreachable, unknown node) and the others unharmed;
    also when the paths are walked a few sources at a time (a large map's groups)."""
    if walk_entries is not None:
        monkeypatch.setattr(routes, "_WALK_ENTRIES", walk_entries)
    for rm in (square_map, load_roadmap(RoadmapConfig())):
        names = [str(x) for x in rm.nodes["name"]]
        g = np.random.default_rng(4)
        pairs = [tuple(g.choice(names, 2)) for _ in range(300)] + [(names[0], names[0])]
        pairs += [("no such node", names[1]), (names[2], "nor this")]
        if rm is square_map:
            pairs += [("iso_a", "s0"), ("t1", "t0"), ("s0", "t1")]
        refused = batch_routes_match_one_by_one(rm, pairs)
        assert refused >= 3 + (rm is square_map)


def test_many_off_road_routes_at_once_are_each_vehicles_own():
    from gmtiflow.scene.routes import off_road_routes
    g = np.random.default_rng(6)
    ways = [g.uniform(-5e3, 5e3, (int(g.integers(2, 9)), int(g.choice([2, 3])))).tolist()
            for _ in range(200)]
    ways += [[[0, 0], [0, 0], [5, 5]],              # coinciding: dropped, route by route
             [[1, 1]],                              # one waypoint: refused
             [[0, 0], [1, 2, 3, 4]],                # not a point: refused
             [[0, 0], [float("nan"), 1]],           # not finite: refused
             [[3, 4], [3, 4, 0.0]]]                 # all coincide: refused
    got = off_road_routes(ways)
    for w, r in zip(ways, got):
        try:
            want = off_road_route(w)
        except RoadMapError:
            assert r is None
            continue
        if r is None:                               # handed back: only for dropped waypoints
            assert len(want.s_m) < len(w)
            continue
        same_route(r, want)
    assert sum(r is None for r in got) == 5 and got[0] is not None


@pytest.mark.parametrize("width", [2, 3])
def test_waypoint_lists_read_in_bulk_give_each_vehicles_own_route(width):
    from gmtiflow.scene import routes
    g = np.random.default_rng(7)
    ways = [g.uniform(-5e3, 5e3, (int(g.integers(2, 9)), width)).tolist() for _ in range(100)]
    ways[3] = [[int(v) for v in p] for p in ways[3]]            # ints as floats
    ways[5] = [tuple(p) for p in ways[5]]
    ways[7] = [ways[7][0], ways[7][0], *ways[7][1:]]           # coinciding: handed back
    assert routes._stacked_waypoints(ways) is not None
    got = routes.off_road_routes(ways)
    for i, (w, r) in enumerate(zip(ways, got)):
        if i == 7:
            assert r is None
            continue
        same_route(r, off_road_route(w))
    assert routes._stacked_waypoints(ways[:4] + [[[0.0, 0.0], [10 ** 400, 1.0]]]) is None
    for bad in ([[0.0, 0.0], [True, 1.0]], [[0.0, 0.0]],
                [[0.0, 0.0], [math.inf, 1.0]], [[0.0, 0.0, 0.0][:width], [1.0, 2.0, 3.0, 4.0]]):
        assert routes._stacked_waypoints(ways[:4] + [bad]) is None     # read one by one
        got = routes.off_road_routes(ways[:4] + [bad])
        for w, r in zip(ways[:4], got):
            same_route(r, off_road_route(w))
        try:
            same_route(got[4], off_road_route(bad))                     # a bool is 1.0
        except RoadMapError:
            assert got[4] is None
