"""Small road maps shared by the scene tests."""
import pytest

from gmtiflow.scene.roadmap import RoadmapConfig, RoadmapKind, RoadSpec, from_inline


def inline(nodes, roads):
    return from_inline(RoadmapConfig(kind=RoadmapKind.inline, nodes=nodes, roads=roads))


@pytest.fixture
def straight_map():
    """One 20 km straight road (no speed limit), with a middle node as a stop point."""
    return inline({"a": [0, 0, 0], "m": [5000, 0, 0], "b": [20000, 0, 0]},
                  [RoadSpec("a", "m"), RoadSpec("m", "b")])


@pytest.fixture
def corner_map():
    """An L: 100 m east, then 300 m north (a crossroad with a 90° turn)."""
    return inline({"a": [0, 0, 0], "c": [100, 0, 0], "b": [100, 300, 0]},
                  [RoadSpec("a", "c"), RoadSpec("c", "b")])


@pytest.fixture
def square_map():
    """A 1 km square with a diagonal; the top edge t1->t0 is oneway westwards."""
    nodes = {"s0": [0, 0, 0], "s1": [1000, 0, 0], "t1": [1000, 1000, 0], "t0": [0, 1000, 0],
             "iso_a": [5000, 5000, 0], "iso_b": [5100, 5000, 0]}
    roads = [RoadSpec("s0", "s1"), RoadSpec("s1", "t1"), RoadSpec("t1", "t0", oneway=True),
             RoadSpec("t0", "s0"), RoadSpec("s0", "t1", via=[[400, 600]]),
             RoadSpec("iso_a", "iso_b")]
    return inline(nodes, roads)


@pytest.fixture(scope="session")
def make_map():
    """Factory: inline road map from {name: xyz} nodes and RoadSpec roads."""
    return inline


@pytest.fixture(scope="session")
def long_road():
    """A 200 km straight road for long statistical runs."""
    return inline({"a": [0, 0, 0], "b": [200_000, 0, 0]}, [RoadSpec("a", "b")])


ROUTE_FIELDS = ("node_ids", "xyz_m", "s_m", "edge_id", "invisible", "speed_limit_mps")


def same_route(a, b):
    """Two routes bit for bit the same, field by field (dtype, shape and bytes)."""
    for f in ROUTE_FIELDS:
        x, y = getattr(a, f), getattr(b, f)
        assert x.dtype == y.dtype and x.shape == y.shape and x.tobytes() == y.tobytes(), f


def batch_routes_match_one_by_one(rm, pairs) -> int:
    """``routes.shortest_routes`` of ``pairs`` on road map ``rm`` (its routing searches
    cleared first) against ``shortest_route`` pair by pair: the same route bit for bit, None
    where the one-pair call refuses; returns how many were refused."""
    from gmtiflow.errors import RoadMapError
    from gmtiflow.scene.routes import shortest_route, shortest_routes
    rm._routing_csr = None                      # a fresh map: no searches cached
    got = shortest_routes(rm, [a for a, _ in pairs], [b for _, b in pairs])
    refused = 0
    for (a, b), r in zip(pairs, got):
        try:
            want = shortest_route(rm, a, b)
        except RoadMapError:
            assert r is None, (a, b)
            refused += 1
            continue
        same_route(r, want)
    return refused
