"""The observation vector: five switchable strategies, constant normalisers.

Pure function of the batched state; every tensor is [E, A, ...].
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import torch

from sigmarl.env.geometry import rotate, to_local, wrap_angle
from sigmarl.env.params import NORMALISERS, VEHICLE

if TYPE_CHECKING:
    from sigmarl.config import ObsConfig

WORLD_SIZE = NORMALISERS.world
EGO_SCALE = NORMALISERS.ego
SPEED_SCALE = NORMALISERS.speed
DIST_SCALE = NORMALISERS.distance
HEADING_SCALE = NORMALISERS.heading


@dataclass
class ObsInputs:
    """Everything the observation reads, batched [E, A, ...] in world coordinates."""

    pos: torch.Tensor  # [E, A, 2]
    heading: torch.Tensor  # [E, A]
    speed: torch.Tensor  # [E, A] signed forward speed
    vel: torch.Tensor  # [E, A, 2]
    ref_points: torch.Tensor  # [E, A, P, 2]
    d_center: torch.Tensor  # [E, A] distance to own center line
    d_left: torch.Tensor  # [E, A] DB value, left
    d_right: torch.Tensor  # [E, A]
    left_points: torch.Tensor  # [E, A, 5, 2] corridor points around the agent
    right_points: torch.Tensor  # [E, A, 5, 2]
    corners: torch.Tensor  # [E, A, 4, 2]
    neighbours: torch.Tensor  # [E, A, K] indices of the K nearest others, nearest first
    distances: torch.Tensor  # [E, A, A] center-to-center
    length: float = VEHICLE.length
    width: float = VEHICLE.width
    # the paper's rules (`rules.*`) can change these; ours are the defaults
    world: tuple[float, float] = WORLD_SIZE  # bird's-eye view scale
    speed_scale: float = SPEED_SCALE
    wrap_headings: bool = True  # relative headings wrapped to (-pi, pi]


def _frame(points: torch.Tensor, x: ObsInputs, ego: bool) -> torch.Tensor:
    """Points [E, A, P, 2] in the agent's ego frame (/1.6 m) or the world (/world size), flattened."""
    if ego:
        out = to_local(points, x.pos, x.heading) / EGO_SCALE
    else:
        out = points / points.new_tensor(x.world)
    return out.flatten(-2)


def build_observation(x: ObsInputs, flags: ObsConfig) -> torch.Tensor:
    """[E, A, D] observation for all agents at once."""
    e = flags.ego_view
    parts: list[torch.Tensor] = []
    if not e:
        parts += [x.pos / x.pos.new_tensor(x.world), (x.heading / HEADING_SCALE).unsqueeze(-1)]
    parts.append(x.speed.unsqueeze(-1) / x.speed_scale if e else x.vel / x.speed_scale)
    parts.append(_frame(x.ref_points, x, e))
    if flags.distance_to_center_line:
        parts.append(x.d_center.unsqueeze(-1) / DIST_SCALE)
    for d, pts in ((x.d_left, x.left_points), (x.d_right, x.right_points)):
        parts.append(d.unsqueeze(-1) / DIST_SCALE if flags.distance_to_boundaries else _frame(pts, x, e))

    k = x.neighbours.shape[-1]
    if k:
        parts.append(_others(x, flags).flatten(-2))
    return torch.cat(parts, dim=-1)


def _others(x: ObsInputs, flags: ObsConfig) -> torch.Tensor:
    """[E, A, K, per_other] block for the K nearest other agents."""
    e = flags.ego_view
    nb = x.neighbours  # [E, A, K]
    n_env, n_agents, k = nb.shape

    def take(t: torch.Tensor) -> torch.Tensor:  # [E, A, ...] -> [E, A, K, ...] of neighbours
        idx = nb.reshape(n_env, n_agents * k)
        idx = idx.view(n_env, n_agents * k, *([1] * (t.dim() - 2))).expand(-1, -1, *t.shape[2:])
        return t.gather(1, idx).view(n_env, n_agents, k, *t.shape[2:])

    blocks: list[torch.Tensor] = []
    if flags.vertices:
        corners = take(x.corners)  # [E, A, K, 4, 2]
        blocks.append(_frame(corners.flatten(2, 3), x, e).view(n_env, n_agents, k, 8))
    else:
        pos = take(x.pos)  # [E, A, K, 2]
        heading = take(x.heading)
        if e:
            pos = to_local(pos, x.pos, x.heading) / EGO_SCALE
            heading = heading - x.heading.unsqueeze(-1)
            heading = wrap_angle(heading) if x.wrap_headings else heading
        else:
            pos = pos / pos.new_tensor(x.world)
        size = pos.new_tensor([x.length / EGO_SCALE, x.width / EGO_SCALE]).expand(n_env, n_agents, k, 2)
        blocks += [pos, (heading / HEADING_SCALE).unsqueeze(-1), size]
    vel = take(x.vel)
    if e:
        vel = rotate(vel, -x.heading.unsqueeze(-1))
    blocks.append(vel / x.speed_scale)
    if flags.distance_to_agents:
        blocks.append((x.distances.gather(2, nb) / DIST_SCALE).unsqueeze(-1))
    return torch.cat(blocks, dim=-1)
