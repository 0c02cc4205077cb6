"""Observation: sizes of the six presets, every block's value on hand-placed agents,
neighbour ordering, noise, and torchrl's spec check.

Scene on the straight road of conftest (center line y = 0, boundaries y = +-0.075, center
points every 0.08 m at x = 0.08 k), four agents, obs.noise = 0:

    agent  x     y      heading  speed
    A0     1.01  0.01   0        0.4
    A1     1.41  -0.02  0.1      0.6
    A2     0.71  0.00   0        0.2
    A3     3.97  0.00   0        0.0

Vehicle 0.16 x 0.08, so corners are p + R(h) (+-0.08, +-0.04) in the order front-left,
front-right, rear-right, rear-left. Ego frame of an agent at p with heading h:
x' = cos h dx + sin h dy, y' = -sin h dx + cos h dy, (dx, dy) = q - p.

Center-to-center distances (hand):
    A0-A1 = sqrt(0.40^2 + 0.03^2) = 0.401123     A0-A2 = sqrt(0.30^2 + 0.01^2) = 0.300167
    A1-A2 = sqrt(0.70^2 + 0.02^2) = 0.700286     A0-A3 = sqrt(2.96^2 + 0.01^2) = 2.960017
    A1-A3 = sqrt(2.56^2 + 0.02^2) = 2.560078     A2-A3 = 3.26
so the two nearest others are: A0 -> [A2, A1], A1 -> [A0, A2], A3 -> [A1, A0]
(A0 sees A2 first although A1 has the lower index: nearest first).

Closest center point (no ties): A0 x=1.01 -> 1.04 (k=13; 0.96 is 0.05 away, 1.04 0.03);
A1 x=1.41 -> 1.44 (k=18); A3 x=3.97 -> 4.00 (k=50, the route's last real point).
Reference points at k+2, k+4, k+6: A0 -> x 1.20, 1.36, 1.52; A1 -> 1.60, 1.76, 1.92;
A3 -> 4.16, 4.32, 4.48 (on the straight extension), all at y = 0.
Nearest resampled boundary points have the same x as the closest center point; the five
boundary points are k-1 .. k+3: A0 -> x 0.96 .. 1.28, A1 -> 1.36 .. 1.68, A3 -> 3.92 .. 4.24
at y = +0.075 (left) and -0.075 (right).
"""

from __future__ import annotations

import math

import pytest
import torch
from torchrl.envs.utils import check_env_specs

from sigmarl.env.factory import make_env

EGO, SPEED, DIST, TWO_PI = 1.6, 0.8, 0.45, 2 * math.pi
WX, WY = 4.5, 4.0
HL, HW = 0.08, 0.04

STATE = [  # x, y, heading, speed
    (1.01, 0.01, 0.0, 0.4),
    (1.41, -0.02, 0.1, 0.6),
    (0.71, 0.00, 0.0, 0.2),
    (3.97, 0.00, 0.0, 0.0),
]
NEIGHBOURS = {0: [2, 1], 1: [0, 2], 3: [1, 0]}
REF_X = {0: [1.20, 1.36, 1.52], 1: [1.60, 1.76, 1.92], 3: [4.16, 4.32, 4.48]}
BOUNDARY_X = {
    0: [0.96, 1.04, 1.12, 1.20, 1.28],
    1: [1.36, 1.44, 1.52, 1.60, 1.68],
    3: [3.92, 4.00, 4.08, 4.16, 4.24],
}
C1, S1 = math.cos(0.1), math.sin(0.1)
# Distance to the center line y = 0: |y|.
DC = {0: 0.01, 1: 0.02, 3: 0.0}
# DB = min(dist(center, boundary) - 0.04, dist(each corner, boundary)):
#  A0 (y = 0.01, h = 0): left  min(0.065 - 0.04, 0.075 - 0.05) = 0.025
#                        right min(0.085 - 0.04, 0.075 - 0.03) = 0.045
#  A1 (y = -0.02, h = 0.1): highest corner (front-left) y = -0.02 + 0.08 sin .1 + 0.04 cos .1
#                        = 0.027787 -> left  min(0.095 - 0.04, 0.075 - 0.027787) = 0.047213
#        lowest corner (rear-right) y = -0.02 - 0.08 sin .1 - 0.04 cos .1 = -0.067787
#                        -> right min(0.055 - 0.04, 0.075 - 0.067787) = 0.007213 (a corner wins)
#  A3 (y = 0, h = 0): 0.075 - 0.04 = 0.035 both sides
DB = {
    0: (0.025, 0.045),
    1: (min(0.055, 0.075 - (-0.02 + 0.08 * S1 + 0.04 * C1)), min(0.015, 0.075 - (0.02 + 0.08 * S1 + 0.04 * C1))),
    3: (0.035, 0.035),
}


def corners(i):
    x, y, h, _ = STATE[i]
    c, s = math.cos(h), math.sin(h)
    return [(x + c * dx - s * dy, y + s * dx + c * dy) for dx, dy in ((HL, HW), (HL, -HW), (-HL, -HW), (-HL, HW))]


def to_ego(i, q):
    x, y, h, _ = STATE[i]
    dx, dy = q[0] - x, q[1] - y
    return (math.cos(h) * dx + math.sin(h) * dy, -math.sin(h) * dx + math.cos(h) * dy)


def vel(j):
    _, _, h, v = STATE[j]
    return (v * math.cos(h), v * math.sin(h))


def dist(i, j):
    return math.hypot(STATE[i][0] - STATE[j][0], STATE[i][1] - STATE[j][1])


def wrap(a):
    return (a + math.pi) % (2 * math.pi) - math.pi


def points(i, pts, ego):
    """Flattened points in agent i's frame / 1.6 (ego) or world / (4.5, 4.0)."""
    out = []
    for q in pts:
        if ego:
            e = to_ego(i, q)
            out += [e[0] / EGO, e[1] / EGO]
        else:
            out += [q[0] / WX, q[1] / WY]
    return out


def expected(i, E=True, V=True, DA=True, DB_=True, DC_=True):
    """Agent i's observation assembled block by block in the observation's block order (`sigmarl.env.observation`)."""
    x, y, h, v = STATE[i]
    o = []
    if not E:
        o += [x / WX, y / WY, h / TWO_PI]
    o += [v / SPEED] if E else [vel(i)[0] / SPEED, vel(i)[1] / SPEED]
    o += points(i, [(rx, 0.0) for rx in REF_X[i]], E)
    if DC_:
        o += [DC[i] / DIST]
    for side, yb in ((0, 0.075), (1, -0.075)):
        o += [DB[i][side] / DIST] if DB_ else points(i, [(bx, yb) for bx in BOUNDARY_X[i]], E)
    for j in NEIGHBOURS[i]:
        if V:
            o += points(i, corners(j), E)
        else:
            xj, yj, hj, _ = STATE[j]
            o += points(i, [(xj, yj)], E)
            o += [(wrap(hj - h) if E else hj) / TWO_PI, 0.16 / EGO, 0.08 / EGO]
        vj = vel(j)
        if E:  # rotate by -h
            o += [(math.cos(h) * vj[0] + math.sin(h) * vj[1]) / SPEED, (-math.sin(h) * vj[0] + math.cos(h) * vj[1]) / SPEED]
        else:
            o += [vj[0] / SPEED, vj[1] / SPEED]
        if DA:
            o += [dist(i, j) / DIST]
    return torch.tensor(o, dtype=torch.float32)


PRESETS = {
    "full": (32, {}),
    "no_ego_view": (36, {"E": False}),
    "no_vertices": (26, {"V": False}),
    "no_distance_to_agents": (30, {"DA": False}),
    "no_distance_to_boundaries": (50, {"DB_": False}),
    "no_distance_to_center_line": (31, {"DC_": False}),
}


def place_scene(drv):
    pos = torch.tensor([[s[0], s[1]] for s in STATE])
    heading = torch.tensor([s[2] for s in STATE])
    speed = torch.tensor([s[3] for s in STATE])
    return drv.place(pos, heading, speed)


def test_hand_expectations_are_self_consistent():
    """Sanity of the oracle itself: sizes from the table of block sizes and the neighbour order."""
    for name, (size, flags) in PRESETS.items():
        assert expected(0, **flags).numel() == size, name
    for i, nb in NEIGHBOURS.items():
        others = sorted((dist(i, j), j) for j in range(4) if j != i)
        assert [j for _, j in others[:2]] == nb


@pytest.mark.parametrize("preset", list(PRESETS))
def test_preset_size_and_specs_on_cpm_intersection(preset, kit):
    """D = 32, 36, 26, 30, 50, 31 with 4 agents, 2 neighbours, 3 reference points; the env's
    specs agree with what it produces (torchrl check_env_specs)."""
    cfg = kit.cfg((f"obs={preset}", "map=cpm_intersection", "env.n_agents=4"))
    assert cfg.obs.n_nearest == 2 and cfg.obs.n_ref_points == 3
    env = make_env(cfg, num_envs=2)
    td = env.reset()
    size = PRESETS[preset][0]
    assert td["agents", "observation"].shape == (2, 4, size)
    assert env.observation_spec["agents", "observation"].shape == (2, 4, size)
    check_env_specs(env, seed=0)


@pytest.mark.parametrize("preset", list(PRESETS))
def test_block_values_on_hand_placed_agents(preset, env_factory, straight_road):
    drv = env_factory([f"obs={preset}"], road_map=straight_road, num_envs=2, n_agents=4)
    obs = place_scene(drv)
    flags = PRESETS[preset][1]
    for i in (0, 1, 3):
        want = expected(i, **flags)
        for e in range(2):
            torch.testing.assert_close(obs[e, i], want, atol=2e-6, rtol=0, msg=f"{preset} agent {i}")
    # The same observation comes out of the torchrl env after a standing-still step.
    nxt = drv.step(torch.zeros(2))
    assert not nxt["agents", "info", "agent_collision"].any()
    assert not nxt["agents", "info", "lane_collision"].any()


def test_spot_values_full_preset(env_factory, straight_road):
    """A few entries of agent A0 written out as plain numbers (no helper arithmetic)."""
    drv = env_factory(["obs=full"], road_map=straight_road, num_envs=1, n_agents=4)
    o = place_scene(drv)[0, 0]
    assert o[0].item() == pytest.approx(0.5, abs=1e-6)  # 0.4 / 0.8
    # look-ahead (1.20-1.01, 0-0.01)/1.6, (1.36-1.01, .)/1.6, (1.52-1.01, .)/1.6
    want = [0.11875, -0.00625, 0.21875, -0.00625, 0.31875, -0.00625]
    assert o[1:7].tolist() == pytest.approx(want, abs=1e-6)
    assert o[7].item() == pytest.approx(0.01 / 0.45, abs=1e-6)  # DC 0.022222
    assert o[8].item() == pytest.approx(0.025 / 0.45, abs=1e-6)  # DB left 0.055556
    assert o[9].item() == pytest.approx(0.1, abs=1e-6)  # DB right 0.045 / 0.45
    # nearest neighbour A2: front-left corner (0.79, 0.04) - (1.01, 0.01) = (-0.22, 0.03) / 1.6
    assert o[10:12].tolist() == pytest.approx([-0.1375, 0.01875], abs=1e-6)
    # its rear-right corner (0.63, -0.04) - (1.01, 0.01) = (-0.38, -0.05) / 1.6
    assert o[14:16].tolist() == pytest.approx([-0.2375, -0.03125], abs=1e-6)
    assert o[18:20].tolist() == pytest.approx([0.25, 0.0], abs=1e-6)  # (0.2, 0) / 0.8
    assert o[20].item() == pytest.approx(0.300167 / 0.45, abs=2e-6)  # 0.667037
    assert o[31].item() == pytest.approx(0.401123 / 0.45, abs=2e-6)  # A1 second: 0.891385


def test_relative_heading_of_neighbour_is_wrapped(env_factory, straight_road):
    """no_vertices, ego view: A0 heading -3.1, A1 heading 3.1 -> relative heading
    wrap(3.1 - (-3.1)) = 6.2 - 2 pi = -0.083185 (and +0.083185 seen from A1); bird-eye view
    reports the absolute heading 3.1 / 2 pi."""
    pos = [[1.01, 0.0], [1.41, 0.0]]
    ego = env_factory(["obs=no_vertices"], road_map=straight_road, num_envs=1, n_agents=2)
    o = ego.place(pos, [-3.1, 3.1])[0]
    assert o.shape[-1] == 10 + 8  # K = min(2, N - 1) = 1 neighbour
    # own 10 = speed 1 + refs 6 + DC 1 + DB 2; then neighbour pos (2), heading (1)
    assert o[0, 12].item() == pytest.approx((6.2 - 2 * math.pi) / TWO_PI, abs=1e-6)
    assert o[1, 12].item() == pytest.approx((2 * math.pi - 6.2) / TWO_PI, abs=1e-6)
    # A1 seen from A0 (facing -x): dx = 0.4 -> ego x = cos(-3.1) * 0.4 = -0.399233, / 1.6
    assert o[0, 10].item() == pytest.approx(math.cos(-3.1) * 0.4 / 1.6, abs=1e-6)
    bird = env_factory(["obs=no_vertices", "obs.ego_view=false"], road_map=straight_road, num_envs=1, n_agents=2)
    ob = bird.place(pos, [-3.1, 3.1])[0]
    # own 3 + vel 2 + refs 6 + DC 1 + DB 2 = 14; neighbour x/4.5, y/4, heading/2pi
    assert ob[0, 14:17].tolist() == pytest.approx([1.41 / 4.5, 0.0, 3.1 / TWO_PI], abs=1e-6)
    assert ob[1, 2].item() == pytest.approx(3.1 / TWO_PI, abs=1e-6)


def test_noise_is_zero_mean_uniform_of_total_width(env_factory, straight_road):
    """obs.noise = 0.02: obs - noiseless obs in [-0.01, 0.01], mean ~ 0, both signs.
    8 envs x 4 agents x 32 entries = 1024 draws; the mean of U(-0.01, 0.01) has standard
    deviation 0.02 / sqrt(12) / sqrt(1024) = 1.8e-4, so |mean| < 1e-3 is > 5 sigma."""
    clean = env_factory(["obs=full"], road_map=straight_road, num_envs=8, n_agents=4)
    noisy = env_factory(["obs=full", "obs.noise=0.02"], road_map=straight_road, num_envs=8, n_agents=4)
    diff = place_scene(noisy) - place_scene(clean)
    assert diff.abs().max() <= 0.01 + 1e-6
    assert abs(diff.mean().item()) < 1e-3
    assert (diff > 0.005).any() and (diff < -0.005).any()
    assert diff.max() > 0.009 and diff.min() < -0.009  # the full width is used
    # The noise is also on observations the env returns after a step.
    d2 = noisy.step(torch.zeros(2))["agents", "observation"] - clean.step(torch.zeros(2))["agents", "observation"]
    assert d2.abs().max() <= 0.01 + 1e-6 and d2.abs().max() > 0.005
