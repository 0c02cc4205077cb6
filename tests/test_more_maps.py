"""SigmaRL's twelve later hand-drawn maps against the measured facts, and the loader's
side-by-side lanes.

tests/data/sigmarl_more_maps.json is a verbatim copy of the reference facts (per map: each
lanelet's center line within 2 mm and successors, the lane width, the routes the authors
listed with their lengths, their agent count). The maps under test are the shipped files,
loaded through the normal path (conf/map/<key>.yaml -> load_map -> load_osm -> build_route);
shapely is the oracle for lengths and geometry.
"""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest
import torch
from map_facts import assert_lanelets_are_the_facts
from shapely import ops
from shapely.geometry import LineString, Point, Polygon

from sigmarl.compose import compose_config
from sigmarl.env import make_env
from sigmarl.env.spawn import MIN_GAP
from sigmarl.maps import load_map
from sigmarl.maps.multilane import project, substring
from sigmarl.maps.osm import load_osm
from sigmarl.maps.osm_write import save_centerline_osm
from sigmarl.maps.routes import enumerate_routes
from sigmarl.scenarios import scenario

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(__file__).parent / "data"
FACTS = json.loads((DATA / "sigmarl_more_maps.json").read_text())["maps"]
KEYS = list(FACTS)


def _writer():
    spec = importlib.util.spec_from_file_location("write_more_maps", ROOT / "scripts" / "write_more_maps.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


_MAPS: dict = {}


def roadmap(key: str):
    if key not in _MAPS:
        _MAPS[key] = load_map(compose_config([f"map={key}"]).map)
    return _MAPS[key]


def route_centerline(m, ids) -> np.ndarray:
    """The route's center line through its lanelets' vertices, joints not repeated."""
    return np.concatenate([m.lanelets[ids[0]].center] + [m.lanelets[i].center[1:] for i in ids[1:]])


def test_twelve_maps_with_the_authors_agent_counts():
    assert len(KEYS) == 12
    assert {k: (f["lane_width"], f["n_agents"]) for k, f in FACTS.items()} == {
        "interchange_1": (0.3, 8), "interchange_2": (0.2, 10), "interchange_3": (0.2, 10),
        "intersection_1": (0.3, 6), "intersection_3": (0.2, 8), "intersection_4": (0.3, 8),
        "intersection_5": (0.2, 10), "intersection_6": (0.2, 10), "intersection_7": (0.2, 8),
        "intersection_8": (0.2, 10), "on_ramp_2_multilane": (0.2, 10), "roundabout_2": (0.2, 10),
    }
    for key, f in FACTS.items():
        assert (scenario(key).map, scenario(key).n_agents, scenario(key).paper) == (key, f["n_agents"], False)
    assert (scenario("CPM-30").map, scenario("CPM-30").n_agents) == ("cpm", 30)
    assert (scenario("CPM-45").map, scenario("CPM-45").n_agents) == ("cpm", 45)


def test_shipped_files_are_the_facts_converted(tmp_path):
    """The OSM files, map configs and scenario files are what the committed script writes."""
    written = _writer().write_more_maps(DATA / "sigmarl_more_maps.json", tmp_path)
    assert len(written) == 3 * 12
    for path in written:
        shipped = ROOT / path.relative_to(tmp_path)
        assert shipped.read_bytes() == path.read_bytes(), shipped
    for name in ("CPM-30", "CPM-45"):
        text = (ROOT / "conf" / "scenario" / f"{name}.yaml").read_text()
        assert f"n_agents: {name[4:]}\n" in text and "map: cpm\n" in text and "paper: false\n" in text
    for path in (ROOT / "conf" / "scenario").glob("*.yaml"):
        lines = path.read_text().splitlines()
        assert lines[0].startswith("# ") and [ln.split(":")[0] for ln in lines[1:]] == ["map", "n_agents", "paper"]
        assert (scenario(path.stem).map, scenario(path.stem).n_agents) == (lines[1].split()[1], int(lines[2].split()[1]))


@pytest.mark.parametrize("key", KEYS)
def test_center_lines_successors_and_width_are_the_facts(key):
    facts, m = FACTS[key], roadmap(key)
    assert m.lane_width == facts["lane_width"]
    assert_lanelets_are_the_facts(m, facts)


def test_route_length_is_the_center_line_polyline_by_hand():
    """Which length the authors list: intersection_3's route [1] is one lanelet, 17 vertices
    from (3.9204, 0.2415) to (0.2440, 0.2746). Its chord is 3.6765 m, 1.5 mm short of the
    listed 3.678; the polyline through its vertices is 3.6775 m, within 0.5 mm."""
    c = np.array(FACTS["intersection_3"]["lanelets"]["1"]["center"])
    assert FACTS["intersection_3"]["routes"][0] == {"lanelets": [1], "length_m": 3.678}
    assert np.hypot(3.9204 - 0.2440, 0.2415 - 0.2746) == pytest.approx(3.6765, abs=1e-4)
    assert LineString(c).length == pytest.approx(3.6775, abs=1e-4)
    assert abs(np.hypot(*(c[-1] - c[0])) - 3.678) > 1e-3 > abs(LineString(c).length - 3.678)


@pytest.mark.parametrize("key", KEYS)
def test_route_lengths_match_the_authors_to_1mm(key):
    """Compared: the length of the polyline through the route's lanelets' center-line vertices,
    joined end to start (shapely), against `length_m`; and the route's own `length`."""
    facts, m = FACTS[key], roadmap(key)
    assert [list(r.lanelet_ids) for r in m.routes] == [r["lanelets"] for r in facts["routes"]]
    for r, fact in zip(m.routes, facts["routes"], strict=True):
        line = LineString(route_centerline(m, r.lanelet_ids))
        assert abs(line.length - fact["length_m"]) <= 1e-3, (r.name, line.length, fact["length_m"])
        assert r.length == pytest.approx(line.length, abs=1e-9)
        res = r.center[: r.n_points].numpy()  # the resampled center line lies on it
        assert max(line.distance(Point(p)) for p in res) < 1e-9


# Entry-to-exit paths of the lanelet graph that the authors did not list: on intersection_7
# one can also leave 6 through 11 after coming round through 12.
UNLISTED = {"intersection_7": [[1, 2, 3, 12, 6, 11, 10]]}


@pytest.mark.parametrize("key", KEYS)
def test_lanelet_graph_yields_the_listed_routes(key):
    """Every path from a lanelet without predecessor to one without successor (no lanelet
    twice) is a listed route, and every listed route is such a path; the one exception named."""
    found = sorted(enumerate_routes(roadmap(key).lanelets))
    listed = sorted(r["lanelets"] for r in FACTS[key]["routes"])
    assert found == sorted(listed + UNLISTED.get(key, []))


@pytest.mark.parametrize("key", KEYS)
def test_lanes_join_without_gaps_at_splits_and_merges(key):
    """Where a lane splits or lanes merge, every lanelet's boundaries start where each
    predecessor's end, and the lane keeps at least 87% of its width across its heading there
    (the narrowest: intersection_1's right turn 4, drawn with a 29 degree kink where it leaves
    lane 1, keeps 87.8%: a junction node's normal is the mean of all the lanes that meet)."""
    m = roadmap(key)
    w = m.lane_width
    for la in m.lanelets.values():
        for s in la.successors:
            nxt = m.lanelets[s]
            np.testing.assert_allclose([la.left[-1], la.right[-1]], [nxt.left[0], nxt.right[0]], atol=1e-12)
        for end, t in ((0, la.center[1] - la.center[0]), (-1, la.center[-1] - la.center[-2])):
            t, across = t / np.linalg.norm(t), la.left[end] - la.right[end]
            assert abs(t[0] * across[1] - t[1] * across[0]) >= 0.87 * w


@pytest.mark.parametrize("key", KEYS)
def test_a_vehicle_on_the_center_line_touches_no_boundary_of_its_lane(key):
    """Along each lanelet and into each successor, a vehicle on the center line, heading along
    it, is clear of both boundaries of that stretch (the environment would flag it)."""
    m = roadmap(key)
    box = np.array([[-0.08, -0.04], [0.08, -0.04], [0.08, 0.04], [-0.08, 0.04]])
    pairs = [(a, s) for a in m.lanelets for s in m.lanelets[a].successors] + [
        (a,) for a in m.lanelets if not m.lanelets[a].successors]
    for ids in pairs:
        parts = [m.lanelets[i] for i in ids]
        c = np.concatenate([parts[0].center] + [p.center[1:] for p in parts[1:]])
        bounds = [LineString(np.concatenate([parts[0].left] + [p.left[1:] for p in parts[1:]])),
                  LineString(np.concatenate([parts[0].right] + [p.right[1:] for p in parts[1:]]))]
        line = LineString(c)
        for s in np.arange(0.1, line.length - 0.1, 0.04):
            p, q = np.array(line.interpolate(s).coords[0]), np.array(line.interpolate(s + 0.01).coords[0])
            h = np.arctan2(*(q - p)[::-1])
            rot = np.array([[np.cos(h), -np.sin(h)], [np.sin(h), np.cos(h)]])
            poly = Polygon(box @ rot.T + p)
            assert not any(poly.intersects(b) for b in bounds), (key, ids, s)


def _drive(env, td, n_sims: int, n: int, steps: int = 20) -> None:
    """`steps` steps at a constant action (with whatever respawns they cause); observations stay finite."""
    action = torch.tensor([0.5, 0.0]).expand(n_sims, n, 2).clone()
    for _ in range(steps):
        td.set(("agents", "action"), action)
        td = env.step_mdp(env.step(td))
        assert torch.isfinite(td.get(("agents", "observation"))).all()


@pytest.mark.parametrize("key", KEYS)
def test_authors_agent_count_spawns_and_drives(key):
    """The evaluation's protocol (test mode, 32 simulations, the default evaluation seed) at the
    authors' agent count: every vehicle starts on its route's center line, not in its first
    0.25 m nor its last 0.24 m, heading along it, MIN_GAP from all others; then 20 steps at a constant
    action run (with whatever respawns they cause) and the vehicles move forward."""
    cfg = compose_config(["obs.noise=0", "threads=1"])
    n = FACTS[key]["n_agents"]
    m = roadmap(key)
    env = make_env(cfg, num_envs=cfg.eval.n_sims, n_agents=n, mode="test", max_steps=20,
                   map_cfg=compose_config([f"map={key}"]).map, seed=cfg.eval.seed)
    td = env.reset()
    sc = env.scenario
    pos0 = sc.pos.double().clone()
    lines = [LineString(r.center[: r.n_points].numpy()) for r in m.routes]
    for e in range(cfg.eval.n_sims):
        for a in range(n):
            line = lines[int(sc.route[e, a])]
            p = Point(sc.pos[e, a].double().numpy())
            assert line.distance(p) < 1e-5
            # The margins are whole center points (0.08 m apart) inward: 0.32 m from the start,
            # and from the end 0.24 m plus the route's last, shorter gap.
            assert 0.25 <= line.project(p) <= line.length - 0.24 + 1e-6
        d = torch.cdist(sc.pos[e], sc.pos[e]) + torch.eye(n) * 1e9
        assert float(d.min()) >= MIN_GAP - 1e-6
    _drive(env, td, cfg.eval.n_sims, n)
    moved = (sc.pos.double() - pos0).norm(dim=-1)
    assert torch.isfinite(sc.pos).all() and float(moved.median()) > 0.1
    env.close()


@pytest.mark.slow
@pytest.mark.parametrize("n", [30, 45])
def test_dense_cpm_spawns_and_drives(n):
    """CPM-30 and CPM-45 under the evaluation's protocol: n vehicles on the CPM map's seven
    loops in each of 32 simulations, MIN_GAP apart; then 20 steps at a constant action, with
    the respawns the collisions cause, run."""
    cfg = compose_config(["obs.noise=0", "threads=1"])
    assert (scenario(f"CPM-{n}").map, scenario(f"CPM-{n}").n_agents) == ("cpm", n)
    env = make_env(cfg, num_envs=cfg.eval.n_sims, n_agents=n, mode="test", max_steps=20,
                   map_cfg=compose_config(["map=cpm"]).map, seed=cfg.eval.seed)
    td = env.reset()
    sc = env.scenario
    d = torch.cdist(sc.pos, sc.pos) + torch.eye(n) * 1e9
    assert float(d.min()) >= MIN_GAP - 1e-6
    _drive(env, td, cfg.eval.n_sims, n)
    env.close()


# --- side-by-side lanes (the loader's new part) ------------------------------------------

def test_intersection_3_has_two_two_lane_one_way_roads():
    """By hand from its figure: westbound lane 1 has lanes 2 then 3 on its right (2 splits
    into 3 and the turn 7); eastbound lane 4 has 5 then 6 on its left (8 merges into 6).
    No other map has lanes side by side."""
    beside = {k: {i: (la.beside_left, la.beside_right) for i, la in roadmap(k).lanelets.items()
                  if la.beside_left or la.beside_right} for k in KEYS}
    assert beside.pop("intersection_3") == {1: ([], [2, 3]), 2: ([1], []), 3: ([1], []),
                                            4: ([5, 6], []), 5: ([], [4]), 6: ([], [4])}
    assert all(not b for b in beside.values())


def _hausdorff(a: np.ndarray, b) -> float:
    return LineString(a).hausdorff_distance(b)


def test_two_lane_corridors_against_shapely_offsets():
    """Each corridor boundary is the outer lane's center line offset by w/2 (shapely's
    offset_curve) to within 3 mm (junction normals are means of the meeting lanes')."""
    m = roadmap("intersection_3")
    w = m.lane_width
    c = {i: LineString(la.center) for i, la in m.lanelets.items()}
    chain23 = LineString(route_centerline(m, [2, 3]))
    chain56 = LineString(route_centerline(m, [5, 6]))
    expect = {  # route -> (left, right) as offsets of whole lanes (+: left, -: right)
        "1": (c[1].offset_curve(w / 2), chain23.offset_curve(-w / 2)),
        "2-3": (c[1].offset_curve(w / 2), chain23.offset_curve(-w / 2)),
        "4": (chain56.offset_curve(w / 2), c[4].offset_curve(-w / 2)),
        "5-6": (chain56.offset_curve(w / 2), c[4].offset_curve(-w / 2)),
    }
    for name, (left, right) in expect.items():
        r = m.route(name)
        assert _hausdorff(r.left.numpy()[:-1], left) < 3e-3, name
        assert _hausdorff(r.right.numpy()[:-1], right) < 3e-3, name
    # The turn 2-7: lane 1's left edge along 2, then 7's own; and 8-6: 8's own right, then 4's.
    r = m.route("2-7")
    lane1_left = c[1].offset_curve(w / 2)
    left = r.left.numpy()[:-1]
    along2 = left[left[:, 0] > m.lanelets[2].center[-1, 0] + 1e-3]
    assert len(along2) >= 3 and max(lane1_left.distance(Point(p)) for p in along2) < 3e-3
    assert max(c[7].distance(Point(p)) for p in left[-8:]) == pytest.approx(w / 2, abs=3e-3)
    r = m.route("8-6")
    right = r.right.numpy()[:-1]
    along6 = right[right[:, 0] > m.lanelets[6].center[0, 0] + 1e-3]
    assert max(c[4].offset_curve(-w / 2).distance(Point(p)) for p in along6) < 3e-3


def test_a_vehicle_in_the_other_lane_is_inside_the_corridor():
    """On the two-lane road the corridor spans both lanes: a vehicle on route 1 that changed
    into lane 3 is inside it, clear of both boundaries (before, the corridor was lane 1's)."""
    m = roadmap("intersection_3")
    r = m.route("1")
    corridor = Polygon(np.concatenate([r.left.numpy()[:-1], r.right.numpy()[:-1][::-1]]))
    assert corridor.is_valid
    lane3 = LineString(m.lanelets[3].center)
    p = np.array(lane3.interpolate(0.5, normalized=True).coords[0])
    vehicle = Polygon(np.array([[-0.08, -0.04], [0.08, -0.04], [0.08, 0.04], [-0.08, 0.04]]) + p)
    assert corridor.contains(vehicle)
    assert not any(vehicle.intersects(LineString(b.numpy())) for b in (r.left, r.right))
    w = m.lane_width
    assert corridor.area == pytest.approx(2 * w * LineString(m.lanelets[1].center).length, rel=0.05)


def test_three_lanes_one_split_by_hand(tmp_path):
    """Three eastbound lanes 0.2 m apart (y = 0, 0.2, 0.4; w = 0.2), the middle one drawn as
    two lanelets: every route's corridor runs from y = 0.5 (the left lane's left edge) to
    y = -0.1 (the right lane's right edge), whatever lane it drives in."""
    x = np.linspace(0.0, 2.0, 11)
    lane = {1: np.stack([x, 0 * x], -1), 2: np.stack([x[:6], 0.2 + 0 * x[:6]], -1),
            3: np.stack([x[5:], 0.2 + 0 * x[5:]], -1), 4: np.stack([x, 0.4 + 0 * x], -1)}
    m = load_osm(save_centerline_osm(lane, tmp_path / "three.osm"), lane_width=0.2)
    assert {i: (la.beside_left, la.beside_right) for i, la in m.lanelets.items()} == {
        1: ([2, 3], []), 2: ([4], [1]), 3: ([4], [1]), 4: ([], [2, 3])}
    assert [r.name for r in m.routes] == ["1", "2-3", "4"]
    shift = m.lanelets[1].center[0] - lane[1][0]  # the loader moves the lowest node to 1.2 w
    for r in m.routes:
        left, right = r.left.numpy()[:-1] - shift, r.right.numpy()[:-1] - shift
        np.testing.assert_allclose(left[:, 1], 0.5, atol=1e-9)
        np.testing.assert_allclose(right[:, 1], -0.1, atol=1e-9)
        assert left[0, 0] == pytest.approx(0.0) and left[-1, 0] == pytest.approx(2.0)
        np.testing.assert_allclose(r.entry.numpy() - shift, [[0.0, 0.5], [0.0, -0.1]], atol=1e-9)


def test_a_lane_beside_part_of_another_by_hand(tmp_path):
    """Lane 1 runs east along y = 0 from x = 0 to 2; lane 2 (a pocket, w = 0.2) runs beside
    it at y = 0.2 from x = 0.5 to 1.5 only. Route 1's left boundary is its own edge (y = 0.1),
    the pocket's left edge (y = 0.3) along the pocket, then its own edge again; route 2's
    right boundary is lane 1's right edge (y = -0.1), cut to the pocket's stretch."""
    x = np.linspace(0.0, 2.0, 11)
    pocket = np.linspace(0.5, 1.5, 6)
    lane = {1: np.stack([x, 0 * x], -1), 2: np.stack([pocket, 0.2 + 0 * pocket], -1)}
    m = load_osm(save_centerline_osm(lane, tmp_path / "pocket.osm"), lane_width=0.2)
    assert (m.lanelets[1].beside_left, m.lanelets[2].beside_right) == ([2], [1])
    shift = m.lanelets[1].center[0] - lane[1][0]
    left = LineString(m.route("1").left.numpy()[:-1] - shift)
    by_hand = LineString([(0, 0.1), (0.5, 0.1), (0.5, 0.3), (1.5, 0.3), (1.5, 0.1), (2, 0.1)])
    assert left.hausdorff_distance(by_hand) < 1e-9 and left.length == pytest.approx(by_hand.length, abs=1e-9)
    right = LineString(m.route("2").right.numpy()[:-1] - shift)
    assert right.hausdorff_distance(LineString([(0.5, -0.1), (1.5, -0.1)])) < 1e-9


def test_project_and_substring_agree_with_shapely():
    rng = np.random.default_rng(0)
    for _ in range(20):
        poly = np.cumsum(rng.normal(size=(rng.integers(2, 9), 2)), axis=0)
        line = LineString(poly)
        pts = rng.normal(size=(7, 2)) * 2
        d, s, _ = project(poly, pts)
        np.testing.assert_allclose(d, [line.distance(Point(p)) for p in pts], atol=1e-9)
        np.testing.assert_allclose(s, [line.project(Point(p)) for p in pts], atol=1e-9)
        s0, s1 = sorted(rng.uniform(0, line.length, 2))
        ours = LineString(substring(poly, s0, s1))
        theirs = ops.substring(line, s0, s1)
        assert ours.length == pytest.approx(theirs.length, abs=1e-9)
        assert ours.hausdorff_distance(theirs) < 1e-9
