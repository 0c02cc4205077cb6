"""Dynamics and collision detection, driven through the torchrl env.

Vehicles 0.16 x 0.08, l_f = l_r = 0.08, dt = 0.05. Maps from conftest: the straight road
(boundaries y = +-0.075) and the same road 2 m wide (boundaries y = +-1) for free driving.
"""

from __future__ import annotations

import math

import pytest
import torch
from shapely import affinity
from shapely.geometry import LineString, Polygon, box

DT, L = 0.05, 0.16
D35 = math.radians(35)


def wrapped(h: torch.Tensor) -> bool:
    return bool(((h > -math.pi) & (h <= math.pi)).all())


# ---------------------------------------------------------------- dynamics
def test_straight_driving_covers_v_dt_per_step(env_factory, wide_road):
    """delta = 0: each step moves v dt = 0.8 * 0.05 = 0.04 m along the heading; reversing at
    -0.5 m/s moves -0.025 m. env 0 heading 0, env 1 heading 0.3 rad:
    displacement per step = 0.04 (cos 0.3, sin 0.3) = (0.038213, 0.011821)."""
    drv = env_factory(road_map=wide_road, num_envs=2, n_agents=1)
    start = torch.tensor([[[1.01, 0.0]], [[1.01, -0.3]]])
    heading = torch.tensor([[0.0], [0.3]])
    drv.place(start, heading)
    direction = torch.stack([heading.cos(), heading.sin()], -1)  # [E, 1, 2]
    for t in range(1, 11):
        nxt = drv.step([0.8, 0.0])
        torch.testing.assert_close(drv.sc.pos, start + 0.04 * t * direction, atol=1e-5, rtol=0)
        torch.testing.assert_close(drv.sc.heading, heading, atol=1e-6, rtol=0)
        assert nxt["agents", "info", "speed"].flatten().tolist() == pytest.approx([0.8, 0.8], abs=1e-6)
        # info distance to the center line y = 0: |y| = 0 and |-0.3 + 0.011821 t|
        dc = nxt["agents", "info", "distance_to_center_line"].flatten().tolist()
        assert dc == pytest.approx([0.0, abs(-0.3 + 0.04 * math.sin(0.3) * t)], abs=1e-5)
    assert not nxt["done"].any()
    mid = start + 0.4 * direction  # 10 steps x 0.04
    for t in range(1, 5):
        nxt = drv.step([-0.5, 0.0])
        torch.testing.assert_close(drv.sc.pos, mid - 0.025 * t * direction, atol=1e-5, rtol=0)
    # Observed speed is signed (fix over the paper's |v|): -0.5 / 0.8 = -0.625; info is |v|.
    assert nxt["agents", "observation"][..., 0].flatten().tolist() == pytest.approx([-0.625, -0.625], abs=1e-6)
    assert nxt["agents", "info", "speed"].flatten().tolist() == pytest.approx([0.5, 0.5], abs=1e-6)


def test_constant_steering_drives_a_circle_of_radius_L_over_cos_beta_tan_delta(env_factory, wide_road):
    """delta = +-35 deg, v = 0.8:
    tan 35 = 0.700208, beta = atan(0.5 tan 35) = 0.336767, cos beta = 0.943828,
    R = 0.16 / (0.943828 * 0.700208) = 0.242103 m;
    yaw per step = v/L cos beta tan delta dt = 5 * 0.943828 * 0.700208 * 0.05 = 0.165219 rad.
    The CG starts on the circle moving along psi + beta, so the center is
    p0 + R_signed (-sin(psi0 + beta), cos(psi0 + beta)) (R_signed < 0 for delta < 0).
    60 steps turn 9.9 rad, so the heading wraps past +-pi at least once."""
    beta = math.atan(0.5 * math.tan(D35))
    radius = L / (math.cos(beta) * math.tan(D35))
    assert radius == pytest.approx(0.242, abs=5e-4)
    yaw = 0.8 / L * math.cos(beta) * math.tan(D35) * DT
    drv = env_factory(road_map=wide_road, num_envs=2, n_agents=1)
    p0 = [(2.0, -0.2), (2.0, 0.2)]
    drv.place(torch.tensor([[p0[0]], [p0[1]]]), torch.zeros(2, 1))
    centers = [
        (p0[0][0] - radius * math.sin(beta), p0[0][1] + radius * math.cos(beta)),  # left turn
        (p0[1][0] - radius * math.sin(beta), p0[1][1] - radius * math.cos(beta)),  # right turn
    ]
    action = torch.tensor([[[0.8, D35]], [[0.8, -D35]]])
    prev = drv.sc.heading.clone()
    for t in range(1, 61):
        nxt = drv.step(action)
        h = drv.sc.heading
        assert wrapped(h), h
        # heading increment, unwrapped, equals +-yaw
        dh = torch.remainder(h - prev + math.pi, 2 * math.pi) - math.pi
        assert dh.flatten().tolist() == pytest.approx([yaw, -yaw], abs=1e-5)
        want = [(t * yaw + math.pi) % (2 * math.pi) - math.pi, (-t * yaw + math.pi) % (2 * math.pi) - math.pi]
        assert h.flatten().tolist() == pytest.approx(want, abs=1e-4)
        prev = h.clone()
        for e in range(2):
            r = math.dist(drv.sc.pos[e, 0].tolist(), centers[e])
            assert r == pytest.approx(radius, abs=1e-4), (t, e)
        assert not nxt["done"].any()
        assert not nxt["agents", "info", "lane_collision"].any()
    # headings were near +pi and near -pi at some point (the wrap happened)
    assert 60 * yaw > 2 * math.pi


# ---------------------------------------------------------------- agent-agent collisions
def rect(x: float, y: float, h: float) -> Polygon:
    return affinity.rotate(box(x - 0.08, y - 0.04, x + 0.08, y + 0.04), h, origin=(x, y), use_radians=True)


# (agent 0 pose, agent 1 pose, expected overlap by hand)
CASES = [
    ((1.0, 0.0, 0.0), (1.10, 0.02, 0.0), True),  # plain overlap
    ((1.0, 0.0, 0.0), (1.0, 0.0, math.pi / 2), True),  # a cross: no corner inside the other
    ((1.0, 0.0, 0.0), (1.0, 0.0, 0.0), True),  # coincident (each contains the other)
    ((1.0, 0.0, 0.0), (1.0, 0.0, math.pi), True),  # coincident, opposite heading
    ((1.0, 0.0, 0.0), (1.16, 0.0, 0.0), True),  # front edge touches rear edge (x = 1.08)
    ((1.0, 0.0, 0.0), (1.0, 0.08, 0.0), True),  # side edges touch (y = 0.04)
    ((1.0, 0.0, 0.0), (1.16, 0.08, 0.0), True),  # corners touch at (1.08, 0.04)
    ((1.0, 0.0, 0.0), (1.1605, 0.0, 0.0), False),  # 0.0005 m gap
    ((1.0, 0.0, 0.0), (1.0, 0.0805, 0.0), False),  # 0.0005 m gap sideways
    # 45 deg, bounding boxes overlap (x 1.065 < 1.08, y 0.010 < 0.04) but 0.0084 m apart
    ((1.0, 0.0, 0.0), (1.15, 0.095, math.pi / 4), False),
    ((1.0, 0.0, 0.0), (1.5, 0.0, 0.0), False),  # far apart
]


def _random_cases(n: int, seed: int = 7):
    g = torch.Generator().manual_seed(seed)
    out = []
    while len(out) < n:
        u = torch.rand(4, generator=g).tolist()
        a = (1.0, 0.0, 0.0)
        b = (1.0 + (u[0] - 0.5) * 0.4, (u[1] - 0.5) * 0.3, (u[2] - 0.5) * 2 * math.pi)
        d = rect(*a).distance(rect(*b))
        inter = rect(*a).intersection(rect(*b)).area
        if 0 < d < 1e-4 or (d == 0 and inter < 1e-6):
            continue  # too close to touching for a float32-vs-float64 comparison
        out.append((a, b, d == 0))
    return out


def test_agent_collision_flags_agree_with_shapely(env_factory, wide_road):
    """One env per rectangle pair (agents 0 and 1), agent 2 parked far away at x = 3.
    Flags from set_state and from env info after a standing-still step match shapely
    (touching counts: intersects, distance 0) and are per agent."""
    cases = CASES + _random_cases(40)
    for a, b, hand in CASES:
        d = rect(*a).distance(rect(*b))
        assert (d < 1e-9) == hand, (a, b, d)  # shapely agrees with the hand labels
    (ax, ay, ah), (bx, by, bh) = CASES[9][0], CASES[9][1]
    ra, rb = rect(ax, ay, ah).bounds, rect(bx, by, bh).bounds
    assert ra[2] > rb[0] and ra[3] > rb[1]  # the 45 deg miss really has overlapping AABBs
    n = len(cases)
    pos = torch.tensor([[[a[0], a[1]], [b[0], b[1]], [3.0, 0.0]] for a, b, _ in cases])
    heading = torch.tensor([[a[2], b[2], 0.0] for a, b, _ in cases])
    drv = env_factory(road_map=wide_road, num_envs=n, n_agents=3)
    drv.place(pos, heading)
    want = torch.tensor([[hit, hit, False] for _, _, hit in cases])
    assert torch.equal(drv.sc.agent_collision, want), [
        (c, bool(g)) for c, g in zip(cases, drv.sc.agent_collision[:, 0], strict=True) if bool(g) != c[2]
    ]
    nxt = drv.step(torch.zeros(2))
    info = nxt["agents", "info", "agent_collision"].squeeze(-1).bool()
    assert torch.equal(info, want)
    assert not nxt["agents", "info", "lane_collision"].any()


# ---------------------------------------------------------------- boundary collisions
LANE_CASES = [  # (x, y, heading), hand: max corner |y| vs 0.075
    ((1.0, 0.0, 0.0), False),  # corners at +-0.04
    ((1.0, 0.03, 0.0), False),  # top corners at 0.07 (0.005 margin)
    ((1.0, -0.03, 0.0), False),
    ((1.0, 0.04, 0.0), True),  # 0.08 > 0.075
    ((1.0, -0.04, 0.0), True),
    ((1.0, 0.035, 0.0), True),  # 0.075: touching counts
    ((1.0, 0.0, 0.5), False),  # 0.08 sin .5 + 0.04 cos .5 = 0.038354 + 0.035103 = 0.073457
    ((1.0, 0.0, 0.55), True),  # 0.08 sin .55 + 0.04 cos .55 = 0.041815 + 0.034101 = 0.075916
    ((1.0, 0.0, -0.55), True),  # mirror image: the front-right corner at y = -0.075916
    ((1.0, 0.12, 0.0), True),  # entirely outside the corridor (y in [0.08, 0.16])
    ((1.0, -0.12, 0.0), True),
    ((2.0, 0.04, 0.0), True),  # across the lanelet joint at x = 2
    ((2.0, -0.03, 0.0), False),
]


def test_boundary_collision_when_a_corner_crosses_the_corridor(env_factory, straight_road):
    """Agent 0 of each env at the listed pose, agent 1 safely in the middle at x = 3.
    Oracle: shapely - the rectangle is not strictly inside the corridor polygon."""
    corridor = Polygon([(0, 0.075), (4, 0.075), (4, -0.075), (0, -0.075)])
    left, right = LineString([(0, 0.075), (4, 0.075)]), LineString([(0, -0.075), (4, -0.075)])
    for (x, y, h), hand in LANE_CASES:
        r = rect(x, y, h)
        shp = not corridor.contains_properly(r)
        assert shp == hand, (x, y, h)
        assert hand == (r.distance(left) < 1e-12 or r.distance(right) < 1e-12 or not corridor.contains(r))
    n = len(LANE_CASES)
    pos = torch.tensor([[[x, y], [3.0, 0.0]] for (x, y, _), _ in LANE_CASES])
    heading = torch.tensor([[h, 0.0] for (_, _, h), _ in LANE_CASES])
    drv = env_factory(road_map=straight_road, num_envs=n, n_agents=2)
    drv.place(pos, heading)
    want = torch.tensor([[hit, False] for _, hit in LANE_CASES])
    assert torch.equal(drv.sc.lane_collision, want), drv.sc.lane_collision[:, 0]
    nxt = drv.step(torch.zeros(2))
    assert torch.equal(nxt["agents", "info", "lane_collision"].squeeze(-1).bool(), want)
    assert not nxt["agents", "info", "agent_collision"].any()
