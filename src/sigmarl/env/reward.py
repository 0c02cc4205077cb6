"""The per-agent reward, term by term, batched over [E, A]."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import torch

from sigmarl.params import DT, REWARD, VEHICLE

if TYPE_CHECKING:
    from sigmarl.config.reward import RewardConfig


def decay(x: torch.Tensor, a: float, b: float) -> torch.Tensor:
    """g(x; a, b): 1 at x <= a, 0 at x >= b, exponential in between."""
    z = (x.clamp(a, b) - a) / (b - a)
    return (torch.exp(-z) - math.exp(-1)) / (1 - math.exp(-1))


@dataclass
class RewardInputs:
    pos: torch.Tensor  # [E, A, 2] after the step
    prev_pos: torch.Tensor  # [E, A, 2] before the step
    vel: torch.Tensor  # [E, A, 2] after the step
    prev_ref_points: torch.Tensor  # [E, A, 3, 2] reference points observed before the step
    d_boundary: torch.Tensor  # [E, A] smallest boundary distance (obs items 3.5/3.6, unscaled)
    distances: torch.Tensor  # [E, A, A] center-to-center, diagonal ignored
    d_center: torch.Tensor  # [E, A]
    steering: torch.Tensor  # [E, A]
    prev_steering: torch.Tensor  # [E, A]
    agent_collision: torch.Tensor  # [E, A] bool
    lane_collision: torch.Tensor  # [E, A] bool


def reward_terms(x: RewardInputs, w: RewardConfig, v_scale: float = VEHICLE.max_speed) -> dict[str, torch.Tensor]:
    """Each term of the reward (`env.reward.*`: the paper's by default) as an [E, A] tensor
    (before the clamp). The motion terms divide speeds by `v_scale`: our top speed, 0.8 m/s,
    or the paper's command limit, 1.0 m/s (`rules.reward_normaliser_one`)."""
    ref_w = x.pos.new_tensor(REWARD.ref_weights[: x.prev_ref_points.shape[-2]])
    r = x.prev_ref_points - x.prev_pos.unsqueeze(-2)  # [E, A, P, 2]
    step = (x.pos - x.prev_pos).unsqueeze(-2)
    progress = w.progress * ((step * r).sum(-1) * ref_w).sum(-1) / (v_scale * DT)
    v_bar = (x.vel.unsqueeze(-2) * r).sum(-1).mean(-1)
    speed = w.speed * v_bar / v_scale
    speed = torch.where(v_bar <= 0, 2 * speed, speed)
    moving = w.moving * torch.sign(v_bar) * x.vel.norm(dim=-1) / v_scale
    near_boundary = w.near_boundary * decay(x.d_boundary, 0.0, w.near_boundary_at)
    eye = torch.eye(x.distances.shape[-1], dtype=torch.bool, device=x.distances.device)
    near = decay(x.distances, w.near_agent_full_at, w.near_agent_zero_at).masked_fill(eye, 0.0)
    near_agents = w.near_agents * near.sum(-1)
    deviation = w.center_line_deviation * x.d_center / w.deviation_scale
    steer = w.steering_change * ((x.steering - x.prev_steering).abs() - w.steering_free).clamp(min=0) / w.steering_scale
    return {
        "progress": progress,
        "speed": speed,
        "moving": moving,
        "near_boundary": near_boundary,
        "near_agents": near_agents,
        "center_line_deviation": deviation,
        "steering_change": steer,
        "agent_collision": w.agent_collision * x.agent_collision.to(x.pos.dtype),
        "lane_collision": w.lane_collision * x.lane_collision.to(x.pos.dtype),
    }


def total_reward(terms: dict[str, torch.Tensor]) -> torch.Tensor:
    return torch.stack(list(terms.values())).sum(0).clamp(-1.0, 1.0)
