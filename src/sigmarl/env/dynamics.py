"""Kinematic single-track (bicycle) model with the centre of gravity at the geometric centre.

    beta = atan((l_r / L) tan(delta))
    x' = v cos(psi + beta),  y' = v sin(psi + beta),  psi' = (v / L) cos(beta) tan(delta)

With v and delta held over a step, beta is constant and the course angle psi + beta turns
at the constant rate omega, so the centre of gravity moves on a circular arc. The step
below integrates that arc in closed form (no integration error), batched over any
leading dimensions.
"""

from __future__ import annotations

import torch
from torch import Tensor

from sigmarl.env.geometry import wrap_angle
from sigmarl.params import DT, VEHICLE

L_R, WHEELBASE = VEHICLE.l_r, VEHICLE.wheelbase


def slip_angle(steering: Tensor, l_r: float = L_R, wheelbase: float = WHEELBASE) -> Tensor:
    """Side-slip angle beta of the centre of gravity for steering angle delta."""
    return torch.atan((l_r / wheelbase) * torch.tan(steering))


def bicycle_step(
    pos: Tensor,
    heading: Tensor,
    speed: Tensor,
    steering: Tensor,
    dt: float = DT,
    l_r: float = L_R,
    wheelbase: float = WHEELBASE,
    wrap: bool = True,
) -> tuple[Tensor, Tensor, Tensor]:
    """Advance the model by `dt` with speed and steering held (`wrap=False`: the heading is
    left unwrapped, as the paper's code did).

    pos [..., 2], heading/speed/steering [...] (broadcast). Returns (new_pos [..., 2],
    new_heading [...] wrapped to (-pi, pi], velocity [..., 2]), the velocity being the
    world-frame velocity vector at the end of the step.
    """
    beta = slip_angle(steering, l_r, wheelbase)
    omega = speed / wheelbase * torch.cos(beta) * torch.tan(steering)
    half_turn = 0.5 * omega * dt
    course_start = heading + beta
    # Chord of the arc: (v/omega)(sin(c + 2h) - sin c) = v dt sinc(h) cos(c + h), h = omega dt/2.
    # torch.sinc is sin(pi x)/(pi x) and is exact and smooth at 0, so straight driving needs no
    # special case.
    chord = speed * dt * torch.sinc(half_turn / torch.pi)
    mid_course = course_start + half_turn
    new_pos = pos + chord.unsqueeze(-1) * torch.stack(
        (torch.cos(mid_course), torch.sin(mid_course)), dim=-1
    )
    new_heading = wrap_angle(heading + omega * dt) if wrap else heading + omega * dt
    end_course = new_heading + beta
    velocity = speed.unsqueeze(-1) * torch.stack(
        (torch.cos(end_course), torch.sin(end_course)), dim=-1
    )
    return new_pos, new_heading, velocity
