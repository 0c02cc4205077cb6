"""The reward's weights and shaping scales as config keys (`env.reward.*`): the paper's values
by default, a changed weight changes the reward by the amount worked out by hand, and the
published runs keep their fingerprints."""

from __future__ import annotations

import math
import re

import pytest
import torch

from sigmarl.compose import compose_config
from sigmarl.errors import SigmarlError

OFF = "tracking.enabled=false"


def test_the_defaults_are_the_papers():
    r = compose_config([OFF]).env.reward
    assert (r.progress, r.speed, r.moving) == (0.10, 0.05, 0.05)
    assert (r.near_boundary, r.near_agents, r.center_line_deviation, r.steering_change) == (-0.2, -0.2, -0.02, -0.02)
    assert (r.agent_collision, r.lane_collision) == (-1.0, -1.0)
    # the lane 0.15 m wide, the vehicle 0.16 m x 0.08 m
    assert r.near_boundary_at == pytest.approx(0.9 * 0.035) and r.deviation_scale == pytest.approx(0.035)
    assert (r.near_agent_full_at, r.near_agent_zero_at) == pytest.approx((0.12, 0.24))
    assert (r.steering_free, r.steering_scale) == (math.radians(10), math.radians(50))


def test_a_weight_at_its_default_keeps_the_fingerprint_and_another_value_changes_it():
    base = compose_config([OFF]).fingerprint
    assert compose_config([OFF, "env.reward.near_agents=-0.2"]).fingerprint == base
    assert compose_config([OFF, "env.reward.near_agents=-0.4"]).fingerprint != base


@pytest.mark.parametrize(("override", "message"), [
    ("env.reward.deviation_scale=0", "env.reward.deviation_scale must be positive"),
    ("env.reward.near_agent_zero_at=0.1", "near_agent_zero_at (0.1) must be above"),
    ("env.reward.steering_free_deg=-1", "steering_free_deg must be >= 0"),
    ("env.reward.progress=nan", "env.reward.progress must be a finite number"),
])
def test_unusable_values_are_refused_at_composition(override, message):
    with pytest.raises(SigmarlError, match=re.escape(message)):
        compose_config([OFF, override])


def test_the_agent_penalty_weight_scales_the_term_worked_out_by_hand(env_factory, straight_road):
    """Three standing agents at x = 1.01, 1.21, 1.41 on the center line: distances 0.2, 0.2 and
    0.4. g(0.2; 0.12, 0.24) = (e^-(0.08/0.12) - e^-1)/(1 - e^-1) = 0.230237, g(0.4) = 0.
    At env.reward.near_agents=-0.4 the ends get -0.4 x 0.230237 = -0.0920948 and the middle
    twice that, -0.1841896 (the paper's -0.2: half of each); at 0 the reward is 0 (no other
    term is non-zero for agents standing on the center line)."""
    pos = torch.tensor([[1.01, 0.0], [1.21, 0.0], [1.41, 0.0]])
    rewards = {}
    for weight in (-0.4, -0.2, 0.0):
        drv = env_factory([f"env.reward.near_agents={weight}"], road_map=straight_road, num_envs=1, n_agents=3)
        drv.place(pos, torch.zeros(3))
        rewards[weight] = drv.step(torch.zeros(2))["agents", "reward"][0, :, 0].tolist()
    assert rewards[-0.4] == pytest.approx([-0.0920948, -0.1841896, -0.0920948], abs=2e-6)
    assert rewards[-0.2] == pytest.approx([-0.0460474, -0.0920948, -0.0460474], abs=2e-6)
    assert rewards[0.0] == pytest.approx([0.0, 0.0, 0.0], abs=1e-6)


def test_a_farther_reach_of_the_agent_penalty(env_factory, straight_road):
    """env.reward.near_agent_zero_at=0.48: g(0.2; 0.12, 0.48) = (e^-(0.08/0.36) - e^-1)/(1 - e^-1)
    = (0.800737 - 0.367879)/0.632121 = 0.684771 and g(0.4; 0.12, 0.48) = (e^-(0.28/0.36) - e^-1)
    /(1 - e^-1) = (0.459426 - 0.367879)/0.632121 = 0.144824. Ends: -0.2 x (0.684771 + 0.144824)
    = -0.165919; middle: -0.2 x 2 x 0.684771 = -0.273908."""
    drv = env_factory(["env.reward.near_agent_zero_at=0.48"], road_map=straight_road, num_envs=1, n_agents=3)
    drv.place(torch.tensor([[1.01, 0.0], [1.21, 0.0], [1.41, 0.0]]), torch.zeros(3))
    drv.step(torch.zeros(2))
    assert drv.sc.terms["near_agents"][0].tolist() == pytest.approx([-0.165919, -0.273908, -0.165919], abs=2e-6)
