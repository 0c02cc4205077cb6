"""The observation vector: the declared strategies' blocks (`sigmarl.ablation.STRATEGIES`), constant normalisers.

Pure function of the batched state; every tensor is [E, A, ...].
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import torch

from sigmarl.ablation import OWN, layout
from sigmarl.env.geometry import rotate, to_local, wrap_angle
from sigmarl.params import NORMALISERS, VEHICLE

if TYPE_CHECKING:
    from sigmarl.config import ObsConfig

WORLD_SIZE = NORMALISERS.world
EGO_SCALE = NORMALISERS.ego
SPEED_SCALE = NORMALISERS.speed


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


@dataclass
class View:
    """What a block's builder (`sigmarl.ablation.Block.build`) reads: the inputs, the flags, the
    frame (ego or world) and the helpers that place points in it and gather neighbours."""

    x: ObsInputs
    flags: ObsConfig
    to_local = staticmethod(to_local)
    rotate = staticmethod(rotate)
    wrap_angle = staticmethod(wrap_angle)

    @property
    def ego(self) -> bool:
        return bool(self.flags.ego_view)

    def frame(self, points: torch.Tensor) -> torch.Tensor:
        return _frame(points, self.x, self.ego)

    def take(self, t: torch.Tensor) -> torch.Tensor:
        """[E, A, ...] -> [E, A, K, ...]: each agent's K nearest others' values."""
        nb = self.x.neighbours
        n_env, n_agents, k = nb.shape
        idx = nb.reshape(n_env, n_agents * k)
        idx = idx.view(n_env, n_agents * k, *([1] * (t.dim() - 2))).expand(-1, -1, *t.shape[2:])
        return t.gather(1, idx).view(n_env, n_agents, k, *t.shape[2:])


def build_observation(x: ObsInputs, flags: ObsConfig) -> torch.Tensor:
    """[E, A, D] observation for all agents at once: the declared blocks (`ablation.layout`) in
    order, the K nearest others' blocks side by side per neighbour."""
    view = View(x, flags)
    own: list[torch.Tensor] = []
    others: list[torch.Tensor] = []
    for _, block in layout():
        (own if block.part == OWN else others).extend(block.build(view))
    if x.neighbours.shape[-1] and others:
        own.append(torch.cat(others, dim=-1).flatten(-2))
    return torch.cat(own, dim=-1)
