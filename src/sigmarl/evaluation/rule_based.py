"""A rule-based driver, the yardstick outside RL (`driver.kind=rule_based`): pure pursuit on the
route's center line for the steering, the intelligent driver model (IDM) behind the nearest
vehicle ahead on that line for the speed. It needs no training and reads the scenario's state,
not the observation, batched over environments and agents (no loop over either).

What it does not do: yield at crossings or merges (a vehicle crossing its path is not followed,
only one heading the path's way), negotiate right of way, change lanes, slow for curves, or
react to a vehicle behind it. Its collisions at crossings are the cost of those rules.

Pure pursuit: with the rear axle at r, heading psi, and the target point t on the center line
`driver.lookahead_m` ahead, alpha = angle(t - r) - psi and ld = |t - r|; the steering angle
delta = atan(2 L sin(alpha) / ld) puts the rear axle on the circle through t tangent to the
heading (L: the wheelbase). IDM: a = a_max (1 - (v / v0)^4 - (s* / s)^2), with the desired gap
s* = s0 + max(0, v T + v dv / (2 sqrt(a_max b))), s the bumper-to-bumper gap along the path and
dv the closing speed; the speed command is v + a dt.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import torch
from torch import Tensor

from sigmarl.config.driver import DriverConfig
from sigmarl.env.ego import LENGTH
from sigmarl.env.geometry import wrap_angle
from sigmarl.maps.model import RESAMPLE_STEP
from sigmarl.params import DT, VEHICLE

IDM_EXPONENT = 4  # IDM's free-road exponent (Treiber, Hennecke and Helbing 2000)
_MIN_GAP = 1e-3  # m: a gap at or below zero (touching) reads as this, so IDM brakes hard


def pure_pursuit_steering(rear: Tensor, heading: Tensor, target: Tensor,
                          wheelbase: float = VEHICLE.wheelbase) -> Tensor:
    """Steering angles [...] that carry the rear axles `rear` [..., 2] onto the target points
    [..., 2] on a circle tangent to the headings [...]."""
    d = target - rear
    ld = d.norm(dim=-1).clamp_min(1e-6)
    alpha = wrap_angle(torch.atan2(d[..., 1], d[..., 0]) - heading)
    return torch.atan(2 * wheelbase * torch.sin(alpha) / ld)


def idm_acceleration(speed: Tensor, gap: Tensor, closing: Tensor, p: DriverConfig) -> Tensor:
    """IDM's acceleration [...] at speed v, gap s (inf: no vehicle ahead) and closing speed dv."""
    desired = p.min_gap_m + (speed * p.time_headway
                             + speed * closing / (2 * math.sqrt(p.max_accel * p.comfortable_decel))).clamp_min(0)
    free = (speed.clamp_min(0) / p.desired_speed) ** IDM_EXPONENT
    return p.max_accel * (1 - free - (desired / gap.clamp_min(_MIN_GAP)) ** 2)


def leader_gap(pos: Tensor, vel: Tensor, heading: Tensor, speed: Tensor, path: Tensor, path_heading: Tensor,
               arc: Tensor, p: DriverConfig) -> tuple[Tensor, Tensor]:
    """Bumper-to-bumper gap [E, A] along each agent's path to the nearest other vehicle on it
    heading its way (inf where none), and the closing speed to it [E, A].

    pos, vel [E, A, 2]; heading, speed [E, A]; path [E, A, K, 2] the points ahead, path_heading
    [E, A, K] the line's heading there, arc [E, A, K] their distances along the line."""
    n = pos.shape[1]
    d = (path.unsqueeze(-2) - pos[:, None, None, :, :]).norm(dim=-1)  # [E, ego, K, other]
    turn = wrap_angle(heading[:, None, None, :] - path_heading.unsqueeze(-1)).abs()
    others = ~torch.eye(n, dtype=torch.bool, device=pos.device)[None, :, None, :]
    on = (d <= p.on_path_m) & (turn <= math.radians(p.aligned_deg)) & others
    along = torch.where(on, arc.unsqueeze(-1), torch.inf).flatten(-2)  # [E, ego, K * other]
    nearest, at = along.min(-1)
    k, other = at // n, at % n
    direction = torch.stack((path_heading.cos(), path_heading.sin()), -1).gather(
        -2, k[..., None, None].expand(-1, -1, 1, 2)).squeeze(-2)  # [E, A, 2]
    lead_vel = vel.gather(1, other.unsqueeze(-1).expand(-1, -1, 2))
    closing = speed - (lead_vel * direction).sum(-1)
    return nearest - LENGTH, torch.where(nearest.isfinite(), closing, torch.zeros_like(closing))


class RuleBasedDriver:
    """Pure pursuit and IDM with `driver.*`'s parameters, as a policy the rollout can run."""

    def __init__(self, params: DriverConfig) -> None:
        self.p = params

    def bind(self, sc) -> Callable[[Tensor], Tensor]:
        """The policy obs -> actions [E, A, 2] for the scenario `sc`; it reads `sc`'s state."""
        return lambda obs: self.action(sc)

    def action(self, sc) -> Tensor:
        """Speed command and steering angle [E, A, 2] of every agent in every environment."""
        p, bank = self.p, sc.bank
        step = RESAMPLE_STEP
        forward = torch.stack((sc.heading.cos(), sc.heading.sin()), -1)
        here = bank.center[sc.route, sc.index]
        past = ((sc.pos - here) * forward).sum(-1)  # how far the vehicle is past its center point
        horizon = max(1, math.ceil(p.horizon_m / step))
        ahead = torch.arange(1, horizon + 1, device=sc.pos.device)
        idx = bank.center_index(sc.route, sc.index.unsqueeze(-1) + ahead)  # [E, A, K]
        routes = sc.route.unsqueeze(-1).expand_as(idx)
        arc = ahead * step - past.unsqueeze(-1)
        lead = bank.center_index(sc.route, (sc.index + torch.round((p.lookahead_m + past) / step).long()
                                            .clamp_min(1)).unsqueeze(-1)).squeeze(-1)
        rear = sc.pos - VEHICLE.l_r * forward
        steer = pure_pursuit_steering(rear, sc.heading, bank.center[sc.route, lead])
        gap, closing = leader_gap(sc.pos, sc.vel, sc.heading, sc.speed, bank.center[routes, idx],
                                  bank.heading[routes, idx], arc, p)
        accel = idm_acceleration(sc.speed, gap, closing, p)
        speed = (sc.speed + accel * DT).clamp(0, min(sc.max_speed, sc.command_limit))
        return torch.stack((speed, steer.clamp(-sc.max_steer, sc.max_steer)), -1)
