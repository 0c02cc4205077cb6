"""Procedural test maps against shapely, hand-worked geometry and an independent BFS."""

from __future__ import annotations

import math
from collections import deque

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from shapely.geometry import LineString, Point

from sigmarl.compose import compose_config
from sigmarl.errors import MapError
from sigmarl.maps import load_map
from sigmarl.maps.builders import build_intersection, build_on_ramp, build_roundabout
from sigmarl.maps.model import RoadMap

STATED_SIZE = {"intersection": (2.9, 3.7), "on_ramp": (4.1, 1.8), "roundabout": (4.0, 2.3)}
AGENTS = {"intersection": 6, "on_ramp": 8, "roundabout": 8}
MIN_GAP = 1.2 * math.hypot(0.16, 0.08)  # spawn spacing: 1.2 vehicle diagonals
W = 0.20


@pytest.fixture(scope="module")
def maps() -> dict[str, RoadMap]:
    return {name: load_map(compose_config([f"map={name}"]).map) for name in STATED_SIZE}


def is_u_turn(m: RoadMap, ids) -> bool:
    """A route that leaves on the arm it came from: its left corridor runs twice along the divider."""
    first = m.lanelets[ids[0]]
    return first.adj_left == ids[-1] and not first.adj_left_same


def check_joined(m: RoadMap) -> None:
    for r in m.routes:
        for a, b in zip(r.lanelet_ids[:-1], r.lanelet_ids[1:], strict=True):
            la, lb = m.lanelets[a], m.lanelets[b]
            assert b in la.successors and a in lb.predecessors
            for side in ("left", "right"):
                gap = np.linalg.norm(getattr(la, side)[-1] - getattr(lb, side)[0])
                assert gap < 1e-6, f"{m.name} route {r.name}: {side} bounds of {a} and {b} are {gap} apart"


def check_corridors_simple(m: RoadMap) -> None:
    w = m.lane_width
    for r in m.routes:
        left, right = r.left.numpy(), r.right.numpy()
        if is_u_turn(m, r.lanelet_ids):
            # Only the shared divider repeats: without the entry lanelet the left corridor is simple.
            left = left[len(m.lanelets[r.lanelet_ids[0]].left):]
        assert LineString(left).is_simple, f"{m.name} route {r.name}: left corridor crosses itself"
        assert LineString(right).is_simple, f"{m.name} route {r.name}: right corridor crosses itself"
        gap = LineString(r.left.numpy()).distance(LineString(right))
        assert gap == pytest.approx(w, abs=1e-3), f"{m.name} route {r.name}: corridor {gap} wide"


def check_width(m: RoadMap) -> None:
    w = m.lane_width
    for la in m.lanelets.values():
        assert la.left.shape == la.right.shape
        assert np.allclose(la.center, 0.5 * (la.left + la.right))
        np.testing.assert_allclose(la.width, w, atol=1e-3)
        # Independent of the vertex pairing: each vertex to the other bound's polyline.
        for a, b in ((la.left, la.right), (la.right, la.left)):
            line = LineString(b)
            d = np.array([line.distance(Point(p)) for p in a])
            np.testing.assert_allclose(d, w, atol=1e-3, err_msg=f"{m.name} lanelet {la.id}")


def bfs_pairs(m: RoadMap) -> set[tuple[int, int]]:
    """(entry, exit) pairs connected in the lanelet graph, by breadth-first search."""
    entries = [i for i, la in m.lanelets.items() if not la.predecessors]
    pairs = set()
    for e in entries:
        seen, todo = {e}, deque([e])
        while todo:
            cur = todo.popleft()
            succ = m.lanelets[cur].successors
            if not succ:
                pairs.add((e, cur))
            for s in succ:
                if s not in seen:
                    seen.add(s)
                    todo.append(s)
    return pairs


def test_consecutive_lanelets_join(maps):
    for m in maps.values():
        check_joined(m)


def test_corridors_do_not_cross_themselves(maps):
    for m in maps.values():
        check_corridors_simple(m)
    assert sum(is_u_turn(maps["roundabout"], r.lanelet_ids) for r in maps["roundabout"].routes) == 4
    assert not any(is_u_turn(m, r.lanelet_ids) for n, m in maps.items() if n != "roundabout" for r in m.routes)


def test_lane_width_is_020_everywhere(maps):
    for m in maps.values():
        assert m.lane_width == W
        check_width(m)


def test_vertex_spacing(maps):
    for m in maps.values():
        for la in m.lanelets.values():
            for b in (la.left, la.right, la.center):
                step = np.linalg.norm(np.diff(b, axis=0), axis=-1)
                assert step.max() <= 0.1 + 1e-9 and step.min() >= 0.02, (m.name, la.id)


def test_size_near_the_papers_maps(maps):
    for name, m in maps.items():
        (w, h), (sw, sh) = m.size, STATED_SIZE[name]
        assert abs(w - sw) <= 0.15 * sw and abs(h - sh) <= 0.15 * sh, (name, m.size)
        xmin, ymin, xmax, ymax = m.bounds
        assert 0 <= xmin and xmax <= 4.5 and 0 <= ymin and ymax <= 4.0  # inside the training world


def test_routes_are_every_entry_to_every_reachable_exit(maps):
    counts = {"intersection": 12, "on_ramp": 3, "roundabout": 16}  # 4x3 turns; 3 entries; 4x4 arms
    for name, m in maps.items():
        ends = [(r.lanelet_ids[0], r.lanelet_ids[-1]) for r in m.routes]
        assert set(ends) == bfs_pairs(m)
        assert len(ends) == len(set(ends)) == counts[name]  # one path per pair on these maps
        for r in m.routes:
            assert len(set(r.lanelet_ids)) == len(r.lanelet_ids) and not r.is_loop
            assert r.length > 2.0


def test_on_ramp_exit_is_common(maps):
    m = maps["on_ramp"]
    assert len({r.lanelet_ids[-1] for r in m.routes}) == 1
    merges = [la for la in m.lanelets.values() if len(la.predecessors) == 2]
    assert len(merges) == 2  # n_ramps: a ramp and the main road share each merge's successor


def greedy_capacity(m: RoadMap, margin: float = 0.25) -> int:
    """How many agents fit MIN_GAP apart on the routes' center lines (the spawn zone)."""
    pts = []
    for r in m.routes:
        c = r.center[: r.n_points].numpy()
        k = int(round(margin / 0.08))
        pts.extend(c[k : len(c) - k])
    placed: list[np.ndarray] = []
    for p in pts:
        if all(np.linalg.norm(p - q) >= MIN_GAP for q in placed):
            placed.append(p)
    return len(placed)


def test_room_for_the_papers_agent_counts(maps):
    for name, m in maps.items():
        assert greedy_capacity(m) >= 2 * AGENTS[name], name


def test_intersection_turns_by_hand(maps):
    m = maps["intersection"]
    xmin, ymin, xmax, ymax = m.bounds
    o = np.array([(xmin + xmax) / 2, (ymin + ymax) / 2])  # junction center
    c = 0.45  # junction_offset
    # Arm 0 (east) incoming = 1; its turns 9, 10, 11 lead north (6), west (7), south (8).
    assert m.lanelets[1].successors == [9, 10, 11]
    assert [m.lanelets[i].successors for i in (9, 10, 11)] == [[6], [7], [8]]
    right = np.linalg.norm(m.lanelets[9].center - (o + [c, c]), axis=-1)
    left = np.linalg.norm(m.lanelets[11].center - (o + [c, -c]), axis=-1)
    np.testing.assert_allclose(right, c - W / 2, atol=1e-9)  # right turn radius 0.35
    np.testing.assert_allclose(left, c + W / 2, atol=1e-9)  # left turn radius 0.55
    np.testing.assert_allclose(m.lanelets[10].center[:, 1], o[1] + W / 2, atol=1e-9)  # straight
    assert m.lanelets[1].adj_left == 5 and not m.lanelets[1].adj_left_same
    assert m.lanelets[10].adj_left is not None and not m.lanelets[10].adj_left_same


def test_roundabout_ring_by_hand(maps):
    m = maps["roundabout"]
    xmin, ymin, xmax, ymax = m.bounds
    o = np.array([(xmin + xmax) / 2, (ymin + ymax) / 2])
    ring = [la for la in m.lanelets.values() if la.id > 16]
    total = 0.0
    for la in ring:
        np.testing.assert_allclose(np.linalg.norm(la.center - o, axis=-1), 0.55, atol=1e-9)
        total += LineString(la.center).length
    assert total == pytest.approx(2 * math.pi * 0.55, abs=2e-3)
    # The ring is one loop: following the ring successors visits all 8 pieces once.
    ids = {la.id for la in ring}
    cur, seen = 17, []
    while cur not in seen:
        seen.append(cur)
        cur = next(s for s in m.lanelets[cur].successors if s in ids)
    assert sorted(seen) == sorted(ids) and cur == 17


def test_on_ramp_by_hand(maps):
    m = maps["on_ramp"]
    main = [m.lanelets[i] for i in (1, 2, 3)]
    y = main[0].center[0, 1]
    assert all(np.allclose(la.center[:, 1], y) for la in main)
    assert sum(LineString(la.center).length for la in main) == pytest.approx(4.1, abs=1e-9)
    for ramp in (m.lanelets[4], m.lanelets[5]):
        assert ramp.center[0, 1] == pytest.approx(y - 1.63, abs=1e-9)  # ramp_drop
        start = np.diff(ramp.center[:2], axis=0)[0]
        assert math.degrees(math.atan2(start[1], start[0])) == pytest.approx(45.0, abs=1e-6)


@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    w=st.floats(0.15, 0.25), n=st.integers(3, 5), c=st.floats(0.5, 0.8),
    arms=st.lists(st.floats(0.5, 2.0), min_size=1, max_size=4),
)
def test_intersection_variants(w, n, c, arms):
    m = build_intersection("x", w, n, arms, c)
    assert len(m.lanelets) == 2 * n + n * (n - 1) and len(m.routes) == n * (n - 1)
    check_joined(m)
    check_corridors_simple(m)
    np.testing.assert_allclose(np.concatenate([la.width for la in m.lanelets.values()]), w, atol=1e-9)


@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(w=st.floats(0.15, 0.25), n=st.integers(3, 4), radius=st.floats(0.5, 0.9), rho=st.floats(0.3, 0.5))
def test_roundabout_variants(w, n, radius, rho):
    m = build_roundabout("r", w, n, [1.0, 0.5], radius, rho)
    assert len(m.routes) == n * n and set((r.lanelet_ids[0], r.lanelet_ids[-1]) for r in m.routes) == bfs_pairs(m)
    check_joined(m)
    check_corridors_simple(m)


@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(w=st.floats(0.15, 0.25), n=st.integers(1, 3), length=st.floats(4.5, 6.0), angle=st.floats(40, 60))
def test_on_ramp_variants(w, n, length, angle):
    m = build_on_ramp("o", w, n, length, 1.6, angle, 0.8)
    assert len(m.routes) == n + 1 and len({r.lanelet_ids[-1] for r in m.routes}) == 1
    check_joined(m)
    check_corridors_simple(m)
    # Ramps never touch each other.
    ramps = [LineString(m.lanelets[i].center) for i in range(n + 2, 2 * n + 2)]
    for i in range(n - 1):
        assert ramps[i].distance(ramps[i + 1]) > w


@pytest.mark.parametrize(
    "make, words",
    [
        (lambda: build_intersection("x", 0.2, 7, [1.0], 0.45), "n_arms"),
        (lambda: build_intersection("x", 0.2, 4, [1.0], 0.2), "junction_offset"),
        (lambda: build_on_ramp("o", 0.2, 2, 2.0), "main_length"),
        (lambda: build_on_ramp("o", 0.2, 9, 4.1), "fewer"),
        (lambda: build_roundabout("r", 0.2, 6, [1.0], 0.55, 0.35), "fewer"),
    ],
)
def test_impossible_parameters_raise_map_error(make, words):
    with pytest.raises(MapError, match=f"map [xor]: .*{words}"):
        make()


def test_config_overrides_reach_the_builder():
    m = load_map(compose_config(["map=intersection", "map.n_arms=3", "map.lane_width=0.25"]).map)
    assert len(m.lanelets) == 12 and m.lane_width == 0.25
    assert sorted(LineString(m.lanelets[i].center).length for i in (1, 2, 3)) == pytest.approx([1.0, 1.0, 1.4])
