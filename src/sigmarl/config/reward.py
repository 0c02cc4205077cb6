"""The reward as config keys (`env.reward.*`): each term's weight and the scales of its
shaping functions, the paper's values by default (`sigmarl.params.REWARD`), so that a
study can ablate them like any other setting. `sigmarl.env.reward` reads them."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

from sigmarl.config.ranges import ranged
from sigmarl.params import REWARD


@dataclass
class RewardConfig:
    """The per-agent reward's weights and shaping scales (the paper's by default; the terms' sum is clamped to [-1, 1])."""

    progress: float = REWARD.progress
    """weight of the progress towards the reference points, per step at full speed"""
    speed: float = REWARD.speed
    """weight of the speed along the reference path (doubled when it points backwards)"""
    moving: float = REWARD.moving
    """weight of the speed's magnitude, signed by its direction along the path"""
    near_boundary: float = REWARD.near_boundary
    """weight of the penalty for being close to a lane boundary (full at 0 m)"""
    near_agents: float = REWARD.near_agents
    """weight of the penalty for each other agent close by (full at near_agent_full_at)"""
    center_line_deviation: float = REWARD.center_line_deviation
    """weight of the distance to the center line, in units of deviation_scale"""
    steering_change: float = REWARD.steering_change
    """weight of a steering change beyond steering_free_deg, in units of steering_scale_deg"""
    agent_collision: float = REWARD.agent_collision
    """reward of a step in which the agent collides with another"""
    lane_collision: float = REWARD.lane_collision
    """reward of a step in which the agent leaves its lane"""
    near_boundary_at: float = ranged(REWARD.near_boundary_at, lo=0, lo_open=True)
    """m: the boundary penalty decays from full at 0 m to none at this distance"""
    deviation_scale: float = ranged(REWARD.deviation_scale, lo=0, lo_open=True)
    """m: the center-line distance that costs the full center_line_deviation weight"""
    near_agent_full_at: float = ranged(REWARD.near_agent_at[0], lo=0, lo_open=True)
    """m, center to center: another agent closer than this costs the full near_agents weight"""
    near_agent_zero_at: float = REWARD.near_agent_at[1]
    """m, center to center: another agent this far or farther costs nothing"""
    steering_free_deg: float = ranged(10.0, lo=0)
    """degrees of steering change per step that cost nothing"""
    steering_scale_deg: float = ranged(50.0, lo=0, lo_open=True)
    """degrees of steering change (beyond the free ones) that cost the full steering_change weight"""

    @property
    def steering_free(self) -> float:
        return math.radians(self.steering_free_deg)

    @property
    def steering_scale(self) -> float:
        return math.radians(self.steering_scale_deg)


# the keys as the fingerprint names them, at the value every earlier run trained with
ADDED_KEYS = {f"env.reward.{f.name}": f.default for f in fields(RewardConfig)}


def check_reward(reward: RewardConfig) -> None:
    """The agents' decay runs from near to far (each scale's own range is declared on its field)."""
    from sigmarl.errors import SigmarlError

    if reward.near_agent_zero_at <= reward.near_agent_full_at:
        raise SigmarlError(f"env.reward.near_agent_zero_at ({reward.near_agent_zero_at}) must be above "
                           f"env.reward.near_agent_full_at ({reward.near_agent_full_at})")
