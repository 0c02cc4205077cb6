"""OSM maps: hand-made files in both dialects, round trips, malformed input."""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import pytest

from sigmarl.compose import compose_config
from sigmarl.errors import MapError, SigmarlError
from sigmarl.maps import load_map, routes
from sigmarl.maps.cpm import CPM_LOOPS, load_cpm
from sigmarl.maps.model import Lanelet, RoadMap
from sigmarl.maps.osm import load_osm
from sigmarl.maps.osm_write import save_lanelet2_osm
from sigmarl.maps.routes import enumerate_routes

DATA = Path(__file__).parent / "data"
CENTERLINE = DATA / "centerline_ways.osm"
LANELET2 = DATA / "lanelet2_two_way.osm"


def unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


# --- center-line ways (SigmaRL style) ------------------------------------------------------


def test_centerline_dialect_by_hand():
    m = load_osm(CENTERLINE)
    assert m.name == "centerline_ways" and sorted(m.lanelets) == [1, 2, 3]  # ids from lanes=<id>
    la1, la2, la3 = (m.lanelets[i] for i in (1, 2, 3))
    # x = (lat - 50.0) * 1e5 + 0.24, y = (lon - 6.0) * 1e5 + 0.24
    np.testing.assert_allclose(la1.center, [[0.24, 1.24], [1.24, 1.24]], atol=1e-8)
    np.testing.assert_allclose(la2.center, [[1.24, 1.24], [2.24, 1.24], [2.24, 2.24]], atol=1e-8)
    np.testing.assert_allclose(la3.center, [[1.24, 1.24], [2.24, 0.24]], atol=1e-8)
    # Node 2 joins three ways: its normal is the mean of their segments' normals
    # (north, north, and north-east for the south-east way 3).
    n2 = unit([0, 2] + unit([1, 1]))
    np.testing.assert_allclose(la2.left, [[1.24, 1.24] + 0.1 * n2, [2.24, 1.24] + 0.1 * unit([-1, 1]), [2.14, 2.24]], atol=1e-8)
    np.testing.assert_allclose(la2.right, [[1.24, 1.24] - 0.1 * n2, [2.24, 1.24] - 0.1 * unit([-1, 1]), [2.34, 2.24]], atol=1e-8)
    np.testing.assert_allclose(la1.left, [[0.24, 1.34], [1.24, 1.24] + 0.1 * n2], atol=1e-8)
    np.testing.assert_allclose(la3.right[-1], [2.24, 0.24] - 0.1 * unit([1, 1]), atol=1e-8)
    for la in m.lanelets.values():
        np.testing.assert_allclose(la.width, 0.2, atol=1e-12)
    assert la1.successors == [2, 3] and la2.predecessors == [1] and la3.predecessors == [1]
    assert [r.lanelet_ids for r in m.routes] == [(1, 2), (1, 3)]
    assert [r.name for r in m.routes] == ["1-2", "1-3"]


def test_centerline_lane_width_moves_the_origin():
    m = load_osm(CENTERLINE, lane_width=0.3)
    np.testing.assert_allclose(m.lanelets[1].center[0], [0.36, 1.36], atol=1e-8)  # 1.2 * 0.3
    np.testing.assert_allclose(m.lanelets[1].left[0], [0.36, 1.51], atol=1e-8)


def test_explicit_routes_and_broken_route():
    m = load_osm(CENTERLINE, routes=[[1, 3]])
    assert [r.lanelet_ids for r in m.routes] == [(1, 3)]
    with pytest.raises(MapError, match=r"centerline_ways\.osm: route 2-3: lanelet 2 is not connected to lanelet 3"):
        load_osm(CENTERLINE, routes=[[1, 2], [2, 3]])
    with pytest.raises(MapError, match=r"centerline_ways\.osm: route 1-9: lanelet 9 does not exist"):
        load_osm(CENTERLINE, routes=[[1, 9]])
    with pytest.raises(MapError, match=r"route 1 must be a list of lanelet ids"):
        load_osm(CENTERLINE, routes=[["a"]])


# --- standard Lanelet2 --------------------------------------------------------------------


def test_lanelet2_dialect_by_hand():
    m = load_osm(LANELET2)
    assert sorted(m.lanelets) == [10, 20, 30, 40]  # the regulatory element is not a lanelet
    L = m.lanelets
    np.testing.assert_allclose(L[10].left, [[0, 0.2], [0.5, 0.2], [1, 0.2]])
    np.testing.assert_allclose(L[10].right, [[0, 0], [0.5, 0], [1, 0]])
    # 20 drives west: both stored bounds are reversed.
    np.testing.assert_allclose(L[20].left, [[1, 0.2], [0.5, 0.2], [0, 0.2]])
    np.testing.assert_allclose(L[20].right, [[1, 0.4], [0.5, 0.4], [0, 0.4]])
    # 30: left stored westwards; its 2-node right bound gets a point at the left's mid arc length.
    np.testing.assert_allclose(L[30].left, [[1, 0.2], [1.5, 0.2], [2, 0.2]])
    np.testing.assert_allclose(L[30].right, [[1, 0], [1.5, 0], [2, 0]])
    np.testing.assert_allclose(L[40].center, [[2, 0.3], [1.5, 0.3], [1, 0.3]])
    assert (L[10].successors, L[40].successors, L[30].predecessors, L[20].predecessors) == ([30], [20], [10], [40])
    assert not L[20].successors and not L[30].successors
    for a, b in ((10, 20), (20, 10), (30, 40), (40, 30)):
        assert L[a].adj_left == b and not L[a].adj_left_same  # shared divider, opposite directions
        assert L[a].adj_right is None
    assert [r.lanelet_ids for r in m.routes] == [(10, 30), (40, 20)]


def test_lanelet2_falls_back_to_lat_lon(tmp_path):
    text = LANELET2.read_text()
    for tag in ("local_x", "local_y"):
        text = text.replace(f"<tag k='{tag}'", "<tag k='ignored'")
    f = tmp_path / "latlon.osm"
    f.write_text(text)
    by_latlon, by_local = load_osm(f), load_osm(LANELET2)
    for i, la in by_local.lanelets.items():
        np.testing.assert_allclose(by_latlon.lanelets[i].left, la.left + 0.24, atol=1e-8)
        np.testing.assert_allclose(by_latlon.lanelets[i].right, la.right + 0.24, atol=1e-8)


# --- round trips ---------------------------------------------------------------------------


def assert_same_map(a: RoadMap, b: RoadMap) -> None:
    assert list(a.lanelets) == list(b.lanelets)
    for i, la in a.lanelets.items():
        lb = b.lanelets[i]
        np.testing.assert_allclose(lb.left, la.left, rtol=0, atol=1e-6, err_msg=f"lanelet {i}")
        np.testing.assert_allclose(lb.right, la.right, rtol=0, atol=1e-6, err_msg=f"lanelet {i}")
        assert (sorted(lb.successors), sorted(lb.predecessors)) == (sorted(la.successors), sorted(la.predecessors)), i
        assert (lb.adj_left, lb.adj_right) == (la.adj_left, la.adj_right), i
        if la.adj_left is not None:
            assert lb.adj_left_same == la.adj_left_same
        if la.adj_right is not None:
            assert lb.adj_right_same == la.adj_right_same
    assert [(r.lanelet_ids, r.is_loop) for r in a.routes] == [(r.lanelet_ids, r.is_loop) for r in b.routes]
    for ra, rb in zip(a.routes, b.routes, strict=True):
        for key in ("center", "left", "right"):
            assert getattr(ra, key).shape == getattr(rb, key).shape
            assert float((getattr(ra, key) - getattr(rb, key)).abs().max()) < 1e-6, (ra.name, key)


@pytest.mark.parametrize("name", ["intersection", "on_ramp", "roundabout"])
def test_builder_round_trip(tmp_path, name):
    m = load_map(compose_config([f"map={name}"]).map)
    f = save_lanelet2_osm(m, tmp_path / f"{name}.osm")
    back = load_osm(f, lane_width=m.lane_width)
    assert_same_map(m, back)
    assert [r.name for r in back.routes] == [r.name for r in m.routes]


def test_cpm_round_trip(tmp_path):
    m = load_cpm("loops")
    f = save_lanelet2_osm(m, tmp_path / "cpm.osm")
    back = load_osm(f, lane_width=0.15, routes=[[*loop, loop[0]] for loop in CPM_LOOPS])
    assert_same_map(m, back)
    assert [r.name for r in back.routes] == [f"loop{i}" for i in range(1, 8)]


def test_saved_file_shares_nodes_and_ways(tmp_path):
    m = load_map(compose_config(["map=intersection"]).map)
    text = save_lanelet2_osm(m, tmp_path / "x.osm").read_text()
    # 20 lanelets have 40 bounds; the 4 arm dividers and the 2 straight-through dividers are shared.
    assert text.count("<way ") == 40 - 6
    assert text.count("<relation ") == 20


# --- malformed input -----------------------------------------------------------------------


def write(tmp_path: Path, body: str) -> Path:
    f = tmp_path / "bad.osm"
    f.write_text(f"<?xml version='1.0'?>\n<osm version='0.6'>\n{body}\n</osm>\n")
    return f


NODES = "<node id='1' lat='50' lon='6'/><node id='2' lat='50.00001' lon='6'/>"


@pytest.mark.parametrize(
    "body, message",
    [
        (NODES + "<way id='7'><nd ref='1'/><nd ref='3'/><tag k='lanes' v='1'/></way>", r"way 7 refers to node 3"),
        ("<node id='1' lat='50' lon='6'/><node id='2'/><way id='7'><nd ref='1'/><nd ref='2'/><tag k='lanes' v='1'/></way>",
         r"node 2 has no coordinates"),
        (NODES + "<way id='7'><nd ref='1'/><nd ref='2'/><tag k='lanes' v='one'/></way>", r"way 7 tag lanes"),
        (NODES + "<way id='7'><nd ref='1'/><tag k='lanes' v='1'/></way>", r"way 7 needs at least 2 nodes"),
        (NODES + "<way id='7'><nd ref='1'/><nd ref='2'/><tag k='lanes' v='1'/></way>"
         "<way id='8'><nd ref='2'/><nd ref='1'/><tag k='lanes' v='1'/></way>", r"ways 7 and 8 both have lanes=1"),
        (NODES + "<way id='7'><nd ref='1'/><nd ref='2'/></way>"
         "<relation id='5'><member type='way' ref='7' role='left'/><tag k='type' v='lanelet'/></relation>",
         r"relation 5 \(lanelet\) has no right member way"),
        (NODES + "<relation id='5'><tag k='type' v='lanelet'/></relation>", r"relation 5 \(lanelet\) has no member ways"),
        (NODES + "<way id='7'><nd ref='1'/><nd ref='2'/></way><relation id='5'><member type='way' ref='7' role='left'/>"
         "<member type='way' ref='8' role='right'/><tag k='type' v='lanelet'/></relation>",
         r"relation 5 \(lanelet\) refers to way 8, which does not exist"),
        (NODES + "<way id='7'><nd ref='1'/><nd ref='2'/></way>", r"no lanelets found"),
        ("<node id='1' lat='north' lon='6'/><node id='2' lat='50' lon='6'/>"
         "<way id='7'><nd ref='1'/><nd ref='2'/><tag k='lanes' v='1'/></way>", r"node 1: lat='north' is not a number"),
    ],
)
def test_malformed_files_name_file_and_element(tmp_path, body, message):
    f = write(tmp_path, body)
    with pytest.raises(MapError, match=rf"bad\.osm: .*{message}"):
        load_osm(f)


def test_missing_and_truncated_files(tmp_path):
    with pytest.raises(MapError, match=r"map file not found: .*nope\.osm"):
        load_osm(tmp_path / "nope.osm")
    text = LANELET2.read_text()
    f = tmp_path / "cut.osm"
    f.write_text(text[: len(text) // 2])
    with pytest.raises(MapError, match=r"cut\.osm: not well-formed XML .*truncated"):
        load_osm(f)
    g = tmp_path / "other.osm"
    g.write_text("<gpx></gpx>")
    with pytest.raises(MapError, match=r"other\.osm: root element is <gpx>"):
        load_osm(g)


def test_osm_through_config(tmp_path):
    cfg = compose_config(["map=osm", f"map.path={LANELET2}", "map.routes=[[10,30]]"]).map
    m = load_map(cfg)
    assert m.name == "lanelet2_two_way" and [r.lanelet_ids for r in m.routes] == [(10, 30)]
    with pytest.raises(SigmarlError, match="map.path"):  # caught at composition now
        compose_config(["map=osm"])


# --- route enumeration on long or looping lanelet graphs -------------------------------------


def _graph(successors: dict[int, list[int]]) -> dict[int, Lanelet]:
    line = np.array([[0.0, 0.0], [1.0, 0.0]])
    predecessors: dict[int, list[int]] = {i: [] for i in successors}
    for a, nexts in successors.items():
        for b in nexts:
            predecessors[b].append(a)
    return {i: Lanelet(i, line + [0, 0.1], line - [0, 0.1], list(s), predecessors[i]) for i, s in successors.items()}


def _forks(k: int) -> dict[int, list[int]]:
    """Entry 1 into hub 100; hub 100+j forks into 200+j and 300+j, which join at hub 101+j;
    the last hub leads back to hub 100: 2**k partial paths and no exit."""
    succ = {1: [100], 100 + k: [100]}
    for j in range(k):
        succ[100 + j] = [200 + j, 300 + j]
        succ[200 + j] = succ[300 + j] = [101 + j]
    return succ


def test_a_chain_longer_than_the_recursion_limit_is_one_route():
    n = 3 * sys.getrecursionlimit()
    routes = enumerate_routes(_graph({i: [i + 1] if i < n else [] for i in range(1, n + 1)}))
    assert routes == [list(range(1, n + 1))]


def test_forks_that_loop_back_without_an_exit_stop_at_the_bound():
    started = time.perf_counter()
    with pytest.raises(MapError, match=r"more than 1,000 steps and 0 routes .*list the routes"):
        enumerate_routes(_graph(_forks(22)), max_steps=1000)
    with pytest.raises(MapError, match=r"more than 200,000 steps"):
        enumerate_routes(_graph(_forks(22)))
    assert time.perf_counter() - started < 30


def test_forks_with_an_exit_give_every_route_and_stop_at_the_route_bound():
    succ = _forks(3)
    succ[103] = [100, 999]  # the last hub also leaves the map
    succ[999] = []
    routes = enumerate_routes(_graph(succ))
    assert len(routes) == 2**3 and all(r[0] == 1 and r[-1] == 999 for r in routes)  # each fork: up or down
    assert routes[0] == [1, 100, 200, 101, 201, 102, 202, 103, 999]  # depth first, successors in order
    with pytest.raises(MapError, match=r"more than 7 routes"):
        enumerate_routes(_graph(succ), max_routes=7)


def test_a_map_file_of_looping_forks_is_one_error_naming_it(tmp_path, monkeypatch):
    nodes = {1: (-1.0, 0.0), 999: (9.0, 3.0)}
    ways = {1: [1, 100], 9: [108, 999, 100]}
    for j in range(8):
        nodes.update({100 + j: (2.0 * j, 0.0), 200 + j: (2.0 * j + 1, 0.5), 300 + j: (2.0 * j + 1, -0.5)})
        ways[10 + 2 * j], ways[11 + 2 * j] = [100 + j, 200 + j, 101 + j], [100 + j, 300 + j, 101 + j]
    nodes[108] = (16.0, 0.0)
    body = "".join(f"<node id='{i}' lat='{50 + x * 1e-5!r}' lon='{6 + y * 1e-5!r}'/>" for i, (x, y) in nodes.items())
    body += "".join(f"<way id='{w}'>" + "".join(f"<nd ref='{r}'/>" for r in refs) + f"<tag k='lanes' v='{w}'/></way>"
                    for w, refs in ways.items())
    f = write(tmp_path, body)
    with pytest.raises(MapError, match=r"bad\.osm: more than 10 steps and 0 routes"):
        monkeypatch.setattr(routes, "MAX_STEPS", 10)
        load_osm(f)
