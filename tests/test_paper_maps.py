"""The paper's three hand-drawn test maps against the measured facts.

tests/data/paper_test_maps.json is a verbatim copy of the reference facts (center lines,
successors, evaluated routes with their lengths along the original center lines, agent
counts). The maps under test are the shipped OSM files, loaded through the normal path
(conf/map/paper_*.yaml -> load_map -> load_osm -> build_route); shapely is the oracle for
lengths and geometry.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch
from map_facts import assert_lanelets_are_the_facts
from shapely.geometry import LineString, Point, Polygon

from sigmarl.compose import compose_config
from sigmarl.env.spawn import MIN_GAP
from sigmarl.maps import load_map
from sigmarl.maps.paper import PAPER_MAPS, package_map_path, write_paper_maps
from sigmarl.maps.routes import enumerate_routes
from sigmarl.scenarios import PAPER_SCENARIOS, scenario, scenario_names

DATA = Path(__file__).parent / "data"
FACTS = json.loads((DATA / "paper_test_maps.json").read_text())["maps"]
TABLE_I_NAMES = {"intersection": "Intersection", "on_ramp": "On-Ramp", "roundabout": "Roundabout"}


@pytest.fixture(scope="module", params=list(PAPER_MAPS))
def paper(request):
    """(facts of one map, the RoadMap built from conf/map/<name>.yaml)."""
    key = request.param
    return key, FACTS[key], load_map(compose_config([f"map={PAPER_MAPS[key]}"]).map)


def route_centerline(m, ids) -> np.ndarray:
    """The route's center line from the loaded map's lanelets, joints not repeated."""
    parts = [m.lanelets[ids[0]].center] + [m.lanelets[i].center[1:] for i in ids[1:]]
    return np.concatenate(parts)


def test_shipped_files_are_the_facts_converted(tmp_path):
    for path in write_paper_maps(DATA / "paper_test_maps.json", tmp_path):
        shipped = package_map_path(f"package:maps/{path.name}")
        assert shipped.read_bytes() == path.read_bytes(), path.name


def test_center_lines_and_successors_are_the_facts(paper):
    _, facts, m = paper
    assert_lanelets_are_the_facts(m, facts)
    assert m.lane_width == facts["lane_width"] == 0.20


def test_route_lengths_match_the_paper_to_1mm(paper):
    _, facts, m = paper
    assert [list(r.lanelet_ids) for r in m.routes] == [r["lanelets"] for r in facts["routes"]]
    for r, fact in zip(m.routes, facts["routes"], strict=True):
        line = LineString(route_centerline(m, r.lanelet_ids))
        assert abs(line.length - fact["length_m"]) <= 1e-3, (r.name, line.length, fact["length_m"])
        assert r.length == pytest.approx(line.length, abs=1e-9)
        # The resampled center line lies on it, 0.08 m of arc apart, up to its end.
        res = r.center[: r.n_points].numpy()
        assert max(line.distance(Point(p)) for p in res) < 1e-9
        arc = [line.project(Point(p)) for p in res]
        np.testing.assert_allclose(np.diff(arc)[:-1], 0.08, atol=1e-9)
        assert 0 < np.diff(arc)[-1] <= 0.08 + 1e-9 and arc[-1] == pytest.approx(line.length, abs=1e-9)


def test_lanelet_graph_enumerates_exactly_the_papers_routes(paper):
    _, facts, m = paper
    found = enumerate_routes(m.lanelets)
    assert sorted(found) == sorted(r["lanelets"] for r in facts["routes"])
    assert len(found) == {"intersection": 6, "on_ramp": 4, "roundabout": 5}[paper[0]]


def test_routes_merge_into_one_exit_lane(paper):
    """By hand from the paper's figures: which lanelets lanes merge into, and how many routes
    end on each exit lanelet."""
    key, _, m = paper
    merges = sorted(la.id for la in m.lanelets.values() if len(la.predecessors) >= 2)
    assert merges == {"intersection": [10, 11], "on_ramp": [3, 5, 7], "roundabout": [7, 8, 9]}[key]
    ends: dict[int, int] = {}
    for r in m.routes:
        ends[r.lanelet_ids[-1]] = ends.get(r.lanelet_ids[-1], 0) + 1
    assert ends == {"intersection": {10: 2, 11: 2, 3: 1, 4: 1}, "on_ramp": {7: 4}, "roundabout": {9: 5}}[key]


def test_corridors_entry_exit_and_extension(paper):
    _, _, m = paper
    w = m.lane_width
    for r in m.routes:
        center = route_centerline(m, r.lanelet_ids)
        left, right = r.left.numpy(), r.right.numpy()
        # No adjacency on these maps: the corridor is the route's own lane, joined without gaps.
        for a, b in zip(r.lanelet_ids[:-1], r.lanelet_ids[1:], strict=True):
            la, lb = m.lanelets[a], m.lanelets[b]
            np.testing.assert_allclose([la.left[-1], la.right[-1]], [lb.left[0], lb.right[0]], atol=1e-12)
        n_raw = sum(len(m.lanelets[i].left) for i in r.lanelet_ids) - (len(r.lanelet_ids) - 1)
        assert len(left) == len(right) == n_raw + 1  # shared joints once, plus the extension's point
        raw = LineString(center)
        for b in (left[:-1], right[:-1]):  # the last point is the straight extension's
            line = LineString(b)
            assert line.is_simple
            # Every boundary vertex is w/2 from the center line, except where lanes split or merge:
            # there the shared node's normal is the mean of the joining lanes' (at most 14 mm less).
            d = np.array([raw.distance(Point(p)) for p in b])
            assert d.max() <= w / 2 + 1e-9 and d.min() >= w / 2 - 0.015
        # Entry and exit segments: w long, across the route's first and last direction.
        for seg, pts in ((r.entry.numpy(), center[:2]), (r.exit.numpy(), center[-2:])):
            across, along = seg[1] - seg[0], pts[1] - pts[0]
            assert np.linalg.norm(across) == pytest.approx(w, abs=1e-9)
            cos = abs(across @ along) / (np.linalg.norm(across) * np.linalg.norm(along))
            assert cos < 0.2
        # The extension continues the last segment straight, 0.08 m apart.
        ext = r.center[r.n_points - 1 :].numpy()
        d = np.diff(ext, axis=0)
        np.testing.assert_allclose(np.linalg.norm(d, axis=-1), 0.08, atol=1e-9)
        direction = center[-1] - center[-2]
        assert np.allclose(np.cross(d, direction), 0, atol=1e-9) and np.all(d @ direction > 0)


def test_a_vehicle_on_the_center_line_touches_no_boundary(paper):
    """The narrowing at splits leaves room: a vehicle on the center line, heading along it, is
    clear of both boundaries everywhere (the environment would otherwise flag it)."""
    _, _, m = paper
    box = np.array([[-0.08, -0.04], [0.08, -0.04], [0.08, 0.04], [-0.08, 0.04]])
    for r in m.routes:
        c = r.center.numpy()
        bounds = [LineString(r.left.numpy()), LineString(r.right.numpy())]
        for i in range(r.n_points):
            d = c[min(i + 1, len(c) - 1)] - c[max(i - 1, 0)]
            h = np.arctan2(d[1], d[0])
            rot = np.array([[np.cos(h), -np.sin(h)], [np.sin(h), np.cos(h)]])
            poly = Polygon(box @ rot.T + c[i])
            assert not any(poly.intersects(b) for b in bounds), (r.name, i)


def test_study_scenarios_are_the_papers_maps():
    assert PAPER_SCENARIOS == ("CPM", "Intersection", "On-Ramp", "Roundabout")
    assert compose_config([]).eval.scenarios == list(PAPER_SCENARIOS)
    for key, name in PAPER_MAPS.items():
        s = scenario(TABLE_I_NAMES[key])
        assert (s.map, s.n_agents, s.paper) == (name, FACTS[key]["n_agents"], True)
    assert [FACTS[k]["n_agents"] for k in PAPER_MAPS] == [6, 8, 8]
    # The procedural builders stay, under names that do not look like Table I's.
    procedural = {s: (scenario(s).map, scenario(s).n_agents) for s in scenario_names() if s.startswith("Proc-")}
    assert procedural == {"Proc-Intersection": ("intersection", 6), "Proc-On-Ramp": ("on_ramp", 8),
                          "Proc-Roundabout": ("roundabout", 8)}
    assert not any(scenario(s).paper for s in procedural)
    assert compose_config(["study=extended"]).eval.scenarios == [*PAPER_SCENARIOS, *procedural]


@pytest.mark.parametrize("key", list(PAPER_MAPS))
def test_env_spawns_the_papers_agent_counts(env_factory, key):
    """Test mode, the paper's agent count, 16 simulations: every vehicle starts on its route's
    center line, heading along it, MIN_GAP from all others; then 40 random steps (with the
    respawns that collisions cause) run without error."""
    n_agents = FACTS[key]["n_agents"]
    m = load_map(compose_config([f"map={PAPER_MAPS[key]}"]).map)
    drv = env_factory(num_envs=16, n_agents=n_agents, mode="test", max_steps=50,
                      road_map=m, seed=7)
    sc = drv.sc
    assert sc.pos.shape == (16, n_agents, 2)
    lines = [LineString(r.center[: r.n_points].numpy()) for r in m.routes]
    for e in range(16):
        for a in range(n_agents):
            p = sc.pos[e, a].double().numpy()
            assert lines[int(sc.route[e, a])].distance(Point(p)) < 1e-5
        d = torch.cdist(sc.pos[e], sc.pos[e]) + torch.eye(n_agents) * 1e9
        assert float(d.min()) >= MIN_GAP - 1e-6
    # Spawns use every route over the 16 simulations.
    assert set(sc.route.flatten().tolist()) == set(range(len(m.routes)))
    gen = torch.Generator().manual_seed(0)
    for _ in range(40):
        action = torch.stack([torch.rand(16, n_agents, generator=gen) * 0.8,
                              (torch.rand(16, n_agents, generator=gen) - 0.5) * 0.6], -1)
        nxt = drv.step(action)
        assert torch.isfinite(nxt["agents", "observation"]).all()
    assert torch.isfinite(sc.pos).all()


def test_evaluation_key_names_the_maps(monkeypatch, tmp_path):
    """Rows evaluated under Table I's names on other maps (the procedural ones, before the
    paper's maps existed, or a user's file of the same name) are never taken for the paper's:
    the evaluation key holds the maps."""
    from sigmarl.eval_key import eval_key

    eval_cfg = compose_config([]).eval
    key = eval_key(eval_cfg)
    (tmp_path / "scenario").mkdir()
    shadow = tmp_path / "scenario" / "Intersection.yaml"
    shadow.write_text("map: intersection\nn_agents: 6\n")
    monkeypatch.setenv("SIGMARL_CONFIG_PATH", str(tmp_path))
    assert scenario("Intersection").map == "intersection"
    assert eval_key(eval_cfg) != key
    shadow.write_text("map: paper_intersection\nn_agents: 6\n")
    monkeypatch.setenv("SIGMARL_CONFIG_PATH", str(tmp_path / "scenario"))  # a folder without scenario/
    assert eval_key(eval_cfg) == key


def test_the_evaluation_key_keeps_the_stored_rows_whatever_the_metric_columns(monkeypatch):
    """The committed runs' rows keep their key; a metric column declared since leaves it as it
    is (the key is the protocol: rows without the column read "not measured")."""
    from sigmarl import eval_key as key_module
    from sigmarl import metrics

    run = Path(__file__).resolve().parents[1] / "results/paper-budget/M0/seed0"
    stored = json.loads((run / "evaluation.json").read_text())["eval_key"]
    eval_cfg = compose_config([]).eval
    assert key_module.eval_key(eval_cfg) == stored == "e91834283d7e"
    monkeypatch.setattr(metrics, "METRIC_COLUMNS", [*metrics.METRIC_COLUMNS, "TTC"])
    monkeypatch.setattr(metrics, "MEASURED", [*metrics.MEASURED, "TTC"])
    assert key_module.eval_key(eval_cfg) == stored
