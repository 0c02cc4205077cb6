"""Lane-boundary contacts are exact against the raw boundary polylines.

The oracle is shapely: the vehicle's box (a polygon) against the route's corridor boundaries
as the map gives them (LineStrings of their raw vertices). Two kinds of contact that a window
of resampled boundary points around the center-line index used to miss are pinned by hand:
a vehicle far off its center line on a CPM two-lane curve, and a corner grazing a sharp
boundary vertex.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely
import torch
from shapely.geometry import LineString, Polygon
from shapely.ops import nearest_points

from sigmarl.maps import load_map, map_config
from sigmarl.maps.model import Lanelet, RoadMap
from sigmarl.maps.routes import build_route, corridor_members

L, W = 0.16, 0.08


def box(x: float, y: float, psi: float) -> Polygon:
    c, s = math.cos(psi), math.sin(psi)
    pts = [(x + c * u - s * v, y + s * u + c * v) for u, v in [(L / 2, W / 2), (L / 2, -W / 2),
                                                                (-L / 2, -W / 2), (-L / 2, W / 2)]]
    return Polygon(pts)


def place(env_factory, road_map, route, pos, heading):
    """One agent per environment at the given poses; returns the scenario after set_state."""
    n = len(pos)
    drv = env_factory(road_map=road_map, num_envs=n, n_agents=1, mode="test")
    drv.place(torch.tensor(np.array(pos), dtype=torch.float32)[:, None], torch.tensor(heading, dtype=torch.float32)[:, None],
              route=torch.tensor(route)[:, None])
    return drv.sc


def boundaries(road_map, r, at=None):
    """Route r's corridor boundaries as LineStrings of the map's raw vertices: the whole route,
    or, with `at` (a point of the route's center line), the stretch that goes with it: the
    corridors of the lanelet holding that point and of the lanelets out to 1.2 m before and
    after it on the route (a loop can run close to another stretch of itself, whose boundary
    is not this stretch's)."""
    route = road_map.routes[r]
    if at is None:
        return LineString(route.left.numpy()), LineString(route.right.numpy())
    ids = list(route.lanelet_ids)
    lanelets = road_map.lanelets
    k = min(range(len(ids)), key=lambda j: LineString(lanelets[ids[j]].center).distance(shapely.Point(at)))
    lo = hi = k
    for step in (-1, 1):  # whole lanelets out to 1.2 m along the route on either side
        j, gone = k, 0.0
        while gone < 1.2 and hi - lo + 1 < len(ids):
            j += step
            if not route.is_loop and not 0 <= j < len(ids):
                break
            lo, hi = min(lo, j), max(hi, j)
            gone += LineString(lanelets[ids[j % len(ids)]].center).length
    # Each lanelet's corridor (leftmost neighbour's left, rightmost's right boundary), in route
    # order, joined where the corridor changes width (the join is boundary too).
    sides = [corridor_members(lanelets[ids[j % len(ids)]], lanelets) for j in range(lo, hi + 1)]
    return (LineString(np.concatenate([lanelets[lm].left for lm, _ in sides])),
            LineString(np.concatenate([lanelets[rm].right for _, rm in sides])))


def crosses_itself(road_map, r) -> bool:
    """Whether route r's center line crosses itself (where it does, the boundary of the other
    pass is not this stretch's; none of the maps here do, but a user's map may)."""
    route = road_map.routes[r]
    center = route.center.numpy()[: route.n_points]
    return not LineString(np.vstack([center, center[:1]]) if route.is_loop else center).is_simple


def test_far_off_center_line_on_a_cpm_two_lane_curve_is_flagged(env_factory):
    # On the whole CPM map, find curved stretches of two-lane corridors (a boundary at least
    # 0.2 m from the center line) and put a vehicle there, 0.2 m or more off its center line,
    # parallel to the boundary, its outer edge 1 mm past it or 2 mm short of it.
    road_map = load_map(map_config("cpm"))
    poses, routes, anchors = [], [], []
    for r, route in enumerate(road_map.routes):
        if crosses_itself(road_map, r):
            continue  # a route that crosses itself: the other pass is not this stretch
        center = route.center.numpy()[: route.n_points]
        for side in range(2):
            for i in range(6, len(center) - 6, 3):
                line = boundaries(road_map, r, center[i])[side]
                heading_a = math.atan2(*(center[i] - center[i - 4])[::-1])
                heading_b = math.atan2(*(center[i + 4] - center[i])[::-1])
                turn = abs((heading_b - heading_a + math.pi) % (2 * math.pi) - math.pi)
                p = shapely.Point(center[i])
                if turn < 0.25 or line.distance(p) < 0.2:
                    continue
                q = nearest_points(line, p)[0]  # nearest boundary point
                n = np.array([q.x - p.x, q.y - p.y]) / line.distance(p)  # toward the boundary
                edge = line.interpolate(line.project(q) + 0.01)
                psi = math.atan2(edge.y - q.y, edge.x - q.x)
                for gap in (-0.001, 0.002):
                    poses.append((np.array([q.x, q.y]) - n * (W / 2 + gap), psi))
                    routes.append(r)
                    anchors.append(center[i])
    sc = place(env_factory, road_map, routes, [p for p, _ in poses], [h for _, h in poses])
    oracle = [box(*p, h).intersects(shapely.union(*boundaries(road_map, r, at)))
              for (p, h), r, at in zip(poses, routes, anchors, strict=True)]
    assert sum(oracle) >= 10 and len(oracle) - sum(oracle) >= 5  # CPM has such curves
    assert sc.lane_collision[:, 0].tolist() == oracle
    # Among them, touching vehicles 0.2 m off their center line (the case the old side-of-segment rule got wrong).
    far = (sc.geo.d_center[:, 0] >= 0.19).tolist()
    assert sum(hit and off for hit, off in zip(oracle, far, strict=True)) >= 5


def test_a_corner_grazing_a_sharp_vertex_is_flagged(env_factory):
    # A straight road whose left boundary has a sharp spike pointing into the lane: vertices
    # (1.99, 0.075), (2.0, 0.0395), (2.01, 0.075). A vehicle at the origin-aligned pose
    # (2.0, 0) heading +x spans y in [-0.04, 0.04]: the spike's tip is 0.5 mm inside its box.
    # Resampling the boundary every 0.02 m would cut the tip off (its neighbours are 0.01 m
    # from it along x) and miss the contact.
    x = np.array([0.0, 0.5, 1.0, 1.5, 1.99, 2.0, 2.01, 2.5, 3.0, 3.5, 4.0])
    left_y = np.where(x == 2.0, 0.0395, 0.075)
    lanelet = Lanelet(1, left=np.stack([x, left_y], 1), right=np.stack([x, np.full_like(x, -0.075)], 1))
    lanelets = {1: lanelet}
    road_map = RoadMap("spike", lanelets, [build_route("spike", [1], lanelets)], lane_width=0.15)
    poses = [(2.0, 0.0), (2.0, -0.001), (1.5, 0.0)]  # grazing; 0.5 mm clear of the tip; far from it
    sc = place(env_factory, road_map, [0, 0, 0], poses, [0.0, 0.0, 0.0])
    oracle = [box(px, py, 0.0).intersects(LineString(lanelet.left)) for px, py in poses]
    assert oracle == [True, False, False]
    assert sc.lane_collision[:, 0].tolist() == oracle
    # The left boundary distance of the clear pose is the tip's: 0.0395 - 0.04 + 0.001 = 0.0005 m.
    assert float(sc.geo.d_side[1, 0, 0]) == pytest.approx(0.0005, abs=1e-6)


MAPS = ["cpm", "cpm_intersection", "paper_intersection", "paper_on_ramp", "paper_roundabout", "intersection",
        "on_ramp", "roundabout"]


@pytest.mark.parametrize("name", MAPS)
def test_shapely_agrees_on_random_poses_near_boundaries(env_factory, name):
    # Random poses whose box edge lies within +-3 cm of a boundary, headings off the route's by
    # up to +-0.4 rad, on every route whose boundaries do not cross themselves (on a route
    # that does, the other pass's boundary is not this stretch's; see RouteBank). Contact
    # flags must equal shapely's, and so must the observed boundary distances (DB).
    road_map = load_map(map_config(name))
    rng = np.random.default_rng(7)
    usable = [r for r in range(len(road_map.routes)) if not crosses_itself(road_map, r)]
    assert usable
    poses, headings, routes, anchors = [], [], [], []
    while len(poses) < 700:
        r = int(rng.choice(usable))
        route = road_map.routes[r]
        i = int(rng.integers(4, route.n_points - 4))
        c = route.center.numpy()[i]
        t = route.center.numpy()[i + 1] - c
        psi = math.atan2(t[1], t[0])
        normal = np.array([-math.sin(psi), math.cos(psi)])
        line = boundaries(road_map, r, c)[int(rng.integers(2))]
        p = shapely.Point(c)
        q = nearest_points(line, p)[0]
        toward = np.array([q.x, q.y]) - c
        d = float(np.linalg.norm(toward))
        sign = 1.0 if toward @ normal >= 0 else -1.0
        lateral = sign * (d - W / 2 + rng.uniform(-0.03, 0.03))
        poses.append(c + lateral * normal)
        headings.append(psi + rng.uniform(-0.4, 0.4))
        routes.append(r)
        anchors.append(c)
    sc = place(env_factory, road_map, routes, poses, headings)
    flags = sc.lane_collision[:, 0].tolist()
    d_side = sc.geo.d_side[:, 0].double().numpy()
    checked = hits = 0
    for k, (p, h, r, at) in enumerate(zip(poses, headings, routes, anchors, strict=True)):
        shape = box(*p, h)
        left, right = boundaries(road_map, r, at)
        corners = [shapely.Point(xy) for xy in list(shape.exterior.coords)[:4]]
        center = shapely.Point(p)
        for j, line in enumerate((left, right)):
            expected_db = min(line.distance(center) - W / 2, *(line.distance(c) for c in corners))
            assert d_side[k, j] == pytest.approx(expected_db, abs=2e-5), (name, k, r, j, list(p), h)
        if min(shape.distance(left), shape.distance(right)) < 1e-5 and not (
            shape.intersects(left) or shape.intersects(right)
        ):
            continue  # within float32 rounding of touching
        expected = shape.intersects(left) or shape.intersects(right)
        assert flags[k] == expected, (name, k, p, h, r)
        checked += 1
        hits += expected
    assert checked > 650 and 100 < hits < checked - 100  # both outcomes well represented


def test_beyond_a_boundary_exactly_where_the_center_leaves_the_corridor(env_factory):
    # A box clear of both boundaries counts as a contact iff its center lies outside the
    # corridor (a vehicle already across). Poses sweep the whole corridor and beyond at every
    # lanelet junction of the CPM loops: there the file's lanelets start 0.1 mm behind their
    # predecessors (a backtracking vertex) and two-lane corridors narrow in a step, which
    # turned a side test against the nearest segment inside out (false contacts, 0.9 % of
    # CPM's steps for M0). Oracle: shapely's polygon of the local corridor stretch.
    road_map = load_map(map_config("cpm"))
    lanelets = road_map.lanelets
    poses, headings, routes, inside = [], [], [], []
    for r, route in enumerate(road_map.routes):
        if crosses_itself(road_map, r):
            continue
        center = route.center.numpy()[: route.n_points]
        for lid in route.lanelet_ids:
            i = int(np.linalg.norm(center - lanelets[lid].center[0], axis=1).argmin())
            for k in (i - 1, i, i + 1):  # on the junction and one point (8 cm) either side
                c = center[k % len(center)]
                t = center[(k + 1) % len(center)] - c
                psi = math.atan2(t[1], t[0])
                normal = np.array([-math.sin(psi), math.cos(psi)])
                left, right = boundaries(road_map, r, c)
                corridor = Polygon(list(left.coords) + list(right.coords)[::-1])
                for lateral in np.arange(-0.40, 0.401, 0.02):
                    p = c + lateral * normal
                    shape = box(*p, psi)
                    if min(shape.distance(left), shape.distance(right)) < 0.002:
                        continue  # touching or nearly: the other tests' business
                    poses.append(p)
                    headings.append(psi)
                    routes.append(r)
                    inside.append(corridor.contains(shapely.Point(p)))
    sc = place(env_factory, road_map, routes, poses, headings)
    flags = sc.lane_collision[:, 0].tolist()
    assert sum(inside) > 500 and len(inside) - sum(inside) > 500
    wrong = [(routes[k], list(poses[k])) for k, (f, ok) in enumerate(zip(flags, inside, strict=True)) if f == ok]
    assert not wrong, f"{len(wrong)} of {len(flags)} poses disagree with shapely, e.g. {wrong[:3]}"
