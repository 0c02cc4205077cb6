"""Reward: each term on a constructed state equals its formula worked out by hand;
the total is the clamped sum.

Straight road of conftest (center line y = 0, boundaries +-0.075, center points every 0.08 m),
dt = 0.05, weights w = (1, 0.6, 0.2) / 1.8,
g(x; a, b) = (exp(-(clamp(x, a, b) - a) / (b - a)) - e^-1) / (1 - e^-1).
An agent at x = 1.01 has its closest center point at x = 1.04 (k = 13), so the reference
points it observed before the step are x = 1.20, 1.36, 1.52 on y = 0.
"""

from __future__ import annotations

import math

import pytest
import torch

E1 = math.exp(-1)
W = (1 / 1.8, 0.6 / 1.8, 0.2 / 1.8)
TERMS = ("progress", "speed", "moving", "near_boundary", "near_agents", "center_line_deviation",
         "steering_change", "agent_collision", "lane_collision")


def g(x, a, b):
    z = (min(max(x, a), b) - a) / (b - a)
    return (math.exp(-z) - E1) / (1 - E1)


def zero_terms():
    return dict.fromkeys(TERMS, 0.0)


# One agent per env, each env a case: (pos, heading, prev steering, action, hand terms)
def single_agent_cases():
    cases = []

    # A: forward at 0.8 m/s, 0.01 m left of the center line.
    # prev pos (1.01, 0.01), new pos (1.05, 0.01); r_k = (0.19, -0.01), (0.35, -0.01), (0.51, -0.01)
    # progress = 0.1 * sum_k w_k <(0.04, 0), r_k> / (0.8 * 0.05)
    #          = 0.1 * (0.19 + 0.6 * 0.35 + 0.2 * 0.51) / 1.8 = 0.1 * 0.502 / 1.8 = 0.0278889
    # v_bar = mean(0.8 * 0.19, 0.8 * 0.35, 0.8 * 0.51) = 0.28 -> speed = 0.05 * 0.28 / 0.8 = 0.0175
    # moving = 0.05 * 1 * 0.8 / 0.8 = 0.05
    # d_b = left DB = min(0.065 - 0.04, 0.075 - 0.05) = 0.025
    #   -> near boundary = -0.2 g(0.025; 0, 0.0315) = -0.2 * (0.452191 - 0.367879)/0.632121 = -0.0266758
    # deviation = -0.02 * 0.01 / 0.035 = -0.0057143
    t = zero_terms()
    t.update(progress=0.1 * 0.502 / 1.8, speed=0.0175, moving=0.05,
             near_boundary=-0.2 * g(0.025, 0, 0.0315), center_line_deviation=-0.02 * 0.01 / 0.035)
    assert t["near_boundary"] == pytest.approx(-0.0266758, abs=1e-6)
    cases.append(((1.01, 0.01), 0.0, 0.0, (0.8, 0.0), t))

    # B: reversing at -0.4 m/s on the center line: step (-0.02, 0), r_k = (0.19, 0), (0.35, 0), (0.51, 0)
    # progress = 0.1 * (-0.02) * 0.502 / 1.8 / 0.04 = -0.0139444
    # v_bar = -0.4 * 1.05 / 3 = -0.14 <= 0 -> speed doubled: 2 * 0.05 * (-0.14) / 0.8 = -0.0175
    # moving = 0.05 * sign(-0.14) * 0.4 / 0.8 = -0.025
    # d_b = 0.075 - 0.04 = 0.035 >= 0.0315 -> 0; deviation 0
    t = zero_terms()
    t.update(progress=-0.0139444, speed=-0.0175, moving=-0.025)
    cases.append(((1.01, 0.0), 0.0, 0.0, (-0.4, 0.0), t))

    # C: standing, steering from -20 deg to +25 deg: -0.02 * (45 - 10) / 50 = -0.014
    # v = 0 -> progress 0, v_bar = 0 -> speed 2 * 0 = 0, moving sign(0) * 0 = 0
    t = zero_terms()
    t.update(steering_change=-0.014)
    cases.append(((1.01, 0.0), 0.0, math.radians(-20), (0.0, math.radians(25)), t))

    # D: standing, steering change 8 deg < 10 deg free band -> 0: every term 0
    cases.append(((1.01, 0.0), 0.0, math.radians(5), (0.0, math.radians(13)), zero_terms()))

    # E: heading 0.2 rad off the road direction, 0.8 m/s, on the center line at x = 2.01
    # (closest point 2.00, k = 25; refs x = 2.16, 2.32, 2.48, r_k = (0.15, 0), (0.31, 0), (0.47, 0)).
    # step = 0.04 (cos 0.2, sin 0.2) = (0.0392027, 0.0079468), v = 0.8 (cos .2, sin .2)
    # progress = 0.1 * cos .2 * (0.15 + 0.6 * 0.31 + 0.2 * 0.47) / 1.8 = 0.1 * 0.980067 * 0.43 / 1.8
    # v_bar = 0.8 cos .2 * (0.15 + 0.31 + 0.47) / 3 = 0.8 * 0.980067 * 0.31 -> speed = 0.05 * v_bar / 0.8
    # new center (2.0492027, 0.0079468): deviation = -0.02 * 0.0079468 / 0.035
    # d_b: highest corner of the new pose y = 0.0079468 + 0.08 sin .2 + 0.04 cos .2 = 0.0634088
    #   -> left DB = min(0.075 - 0.0079468 - 0.04, 0.075 - 0.0634088) = 0.0115912
    c2, s2 = math.cos(0.2), math.sin(0.2)
    y_new = 0.04 * s2
    t = zero_terms()
    t.update(progress=0.1 * c2 * 0.43 / 1.8, speed=0.05 * (0.8 * c2 * 0.31) / 0.8, moving=0.05,
             center_line_deviation=-0.02 * y_new / 0.035,
             near_boundary=-0.2 * g(0.075 - (y_new + 0.08 * s2 + 0.04 * c2), 0, 0.0315))
    cases.append(((2.01, 0.0), 0.2, 0.0, (0.8, 0.0), t))
    return cases


def test_single_agent_terms_equal_hand_formulas(env_factory, straight_road):
    cases = single_agent_cases()
    n = len(cases)
    drv = env_factory(road_map=straight_road, num_envs=n, n_agents=1)
    drv.place(
        torch.tensor([[c[0]] for c in cases]),
        torch.tensor([[c[1]] for c in cases]),
        steering=torch.tensor([[c[2]] for c in cases]),
    )
    nxt = drv.step(torch.tensor([[c[3]] for c in cases]))
    terms = drv.sc.terms
    assert set(terms) == set(TERMS)
    for e, (*_, want) in enumerate(cases):
        got = {k: terms[k][e, 0].item() for k in TERMS}
        assert got == pytest.approx(want, abs=2e-6), f"case {'ABCDE'[e]}"
        total = max(-1.0, min(1.0, sum(want.values())))
        assert nxt["agents", "reward"][e, 0, 0].item() == pytest.approx(total, abs=1e-5)
    # case A total written out: 0.0278889 + 0.0175 + 0.05 - 0.0266758 - 0.0057143 = 0.0629988
    assert nxt["agents", "reward"][0, 0, 0].item() == pytest.approx(0.0629988, abs=1e-5)


def test_near_agents_sums_over_all_others(env_factory, straight_road):
    """Three standing agents at x = 1.01, 1.21, 1.41 (y = 0): distances 0.2, 0.2 and 0.4.
    g(0.2; 0.12, 0.24) = (e^-(0.08/0.12) - e^-1)/(1 - e^-1) = (0.513417 - 0.367879)/0.632121
    = 0.230237, g(0.4) = 0 -> ends: -0.2 * 0.230237 = -0.0460474, middle: twice, -0.0920947.
    Everything else is 0 (standing on the center line, 0.035 m from each boundary)."""
    drv = env_factory(road_map=straight_road, num_envs=1, n_agents=3)
    drv.place(torch.tensor([[1.01, 0.0], [1.21, 0.0], [1.41, 0.0]]), torch.zeros(3))
    nxt = drv.step(torch.zeros(2))
    gg = g(0.2, 0.12, 0.24)
    assert gg == pytest.approx(0.230237, abs=1e-6)
    near = drv.sc.terms["near_agents"][0].tolist()
    assert near == pytest.approx([-0.0460474, -0.0920947, -0.0460474], abs=2e-6)
    for k in TERMS:
        if k != "near_agents":
            assert drv.sc.terms[k].abs().max().item() < 1e-6, k
    assert nxt["agents", "reward"][0, :, 0].tolist() == pytest.approx(near, abs=1e-6)


def test_collision_terms_and_total_clamped_to_minus_one(env_factory, straight_road):
    """A0 at (1.0, 0.04): its left corners at y = 0.08 cross the boundary; A1 at (1.05, 0)
    overlaps it (0.05 m apart along x, 0.04 across). Standing still.
    A0: agent -1, lane -1, near agents -0.2 g(0.064; ...) = -0.2 (0.064 < 0.12),
        near boundary: left DB = min(0.035 - 0.04, |0.075 - 0.08|) = -0.005 <= 0 -> -0.2,
        deviation -0.02 * 0.04 / 0.035 = -0.0228571; sum -2.4228571 -> total -1.
    A1: agent -1, lane 0 (corners at +-0.04), near -0.2, boundary 0.035 -> 0; sum -1.2 -> -1."""
    drv = env_factory(road_map=straight_road, num_envs=1, n_agents=2)
    drv.place(torch.tensor([[1.0, 0.04], [1.05, 0.0]]), torch.zeros(2))
    nxt = drv.step(torch.zeros(2))
    t = {k: v[0].tolist() for k, v in drv.sc.terms.items()}
    assert t["agent_collision"] == [-1.0, -1.0]
    assert t["lane_collision"] == [-1.0, 0.0]
    assert t["near_agents"] == pytest.approx([-0.2, -0.2], abs=1e-6)
    assert t["near_boundary"] == pytest.approx([-0.2, 0.0], abs=1e-6)
    assert t["center_line_deviation"] == pytest.approx([-0.0228571, 0.0], abs=1e-6)
    sums = [sum(t[k][i] for k in TERMS) for i in range(2)]
    assert sums == pytest.approx([-2.4228571, -1.2], abs=1e-5)
    assert nxt["agents", "reward"][0, :, 0].tolist() == [-1.0, -1.0]
