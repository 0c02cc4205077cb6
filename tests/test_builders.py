"""The procedural test maps: lane width, size, connectivity, simple corridors, complete routes."""

from __future__ import annotations

import numpy as np
import pytest
from omegaconf import OmegaConf
from shapely.geometry import LineString

from sigmarl.compose import compose_config, map_config
from sigmarl.env import make_env
from sigmarl.maps import load_map

# name: (stated size in m (spec section 1.2), agents the study puts on it)
MAPS = {"intersection": ((2.9, 3.7), 6), "on_ramp": ((4.1, 1.8), 8), "roundabout": ((4.0, 2.3), 8)}


@pytest.fixture(scope="module", params=list(MAPS))
def built(request):
    return request.param, load_map(map_config(request.param))


def test_lane_width_is_0_20(built):
    _, m = built
    widths = np.concatenate([la.width for la in m.lanelets.values()])
    assert np.all(np.abs(widths - 0.20) <= 1e-3)


def test_fits_the_stated_size(built):
    name, m = built
    (w, h), _ = MAPS[name]
    mw, mh = m.size
    assert mw == pytest.approx(w, rel=0.15) and mh == pytest.approx(h, rel=0.15)


def test_route_lanelets_join(built):
    _, m = built
    for r in m.routes:
        for a, b in zip(r.lanelet_ids[:-1], r.lanelet_ids[1:], strict=True):
            assert b in m.lanelets[a].successors
            assert np.linalg.norm(m.lanelets[a].center[-1] - m.lanelets[b].center[0]) < 1e-6


def test_corridors_do_not_self_intersect(built):
    _, m = built
    for r in m.routes:
        start, end = r.center[0].numpy(), r.center[r.n_points - 1].numpy()
        if np.linalg.norm(start - end) < 0.25:
            # A U-turn (in and out by the same arm): its left boundary runs along the shared
            # median twice, so it touches itself by construction.
            continue
        n = len(r.left) - 1  # without the straight extension's far point
        assert LineString(r.left.numpy()[:n]).is_simple, r.name
        assert LineString(r.right.numpy()[:n]).is_simple, r.name


def _all_paths(lanelets) -> set[tuple[int, ...]]:
    """Independent oracle: depth-first search from every lanelet without predecessors."""
    out = set()
    stack = [(i,) for i, la in lanelets.items() if not la.predecessors]
    while stack:
        path = stack.pop()
        nxt = [s for s in lanelets[path[-1]].successors if s not in path]
        if not lanelets[path[-1]].successors:
            out.add(path)
        stack.extend(path + (s,) for s in nxt)
    return out


def test_routes_go_from_every_entry_to_every_reachable_exit(built):
    _, m = built
    assert {r.lanelet_ids for r in m.routes} == _all_paths(m.lanelets)
    entries = {i for i, la in m.lanelets.items() if not la.predecessors}
    assert {r.lanelet_ids[0] for r in m.routes} == entries


def test_holds_the_study_agents(built):
    name, m = built
    _, n_agents = MAPS[name]
    env = make_env(compose_config([]), num_envs=8, n_agents=n_agents, mode="test", road_map=m)
    pos = env.reset()["agents", "observation"]
    assert pos.shape[:2] == (8, n_agents)


def test_builder_parameters_make_variants():
    wide = load_map(OmegaConf.merge(map_config("intersection"), {"lane_width": 0.25}))
    widths = np.concatenate([la.width for la in wide.lanelets.values()])
    assert np.allclose(widths, 0.25, atol=1e-3)


@pytest.mark.parametrize("name", ["cpm", "intersection", "on_ramp", "roundabout"])
def test_maps_show_writes_a_png(tmp_path, name):
    from sigmarl.cli import main

    out = tmp_path / f"{name}.png"
    assert main(["maps", "show", name, "--out", str(out)]) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_maps_list_and_unknown_map(capsys):
    from sigmarl.cli import main

    assert main(["maps", "list"]) == 0
    listing = capsys.readouterr().out
    for name in ("cpm", "cpm_intersection", "intersection", "on_ramp", "roundabout"):
        assert name in listing
    assert main(["maps", "show", "nope"]) == 2
    assert "unknown map 'nope'" in capsys.readouterr().err
