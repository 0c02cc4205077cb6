"""Batched planar geometry kernels (pure torch).

Every function broadcasts over arbitrary leading dimensions and works in float32 and
float64; nothing loops over environments, agents or pairs. Conventions: angles in radians,
counter-clockwise positive; a local frame has x forward (along the heading) and y left.
Overlap tests are inclusive (touching counts) and use a tolerance of a few ulps of the
coordinates' magnitude, so that exactly touching shapes stay touching in float32.
"""

from __future__ import annotations

import math

import torch
from torch import Tensor

# Tolerance of the inclusive tests, in units of machine epsilon times the coordinate scale.
_TOL_ULPS = 32.0


def wrap_angle(a: Tensor) -> Tensor:
    """Wrap angles to (-pi, pi]."""
    r = torch.remainder(a + math.pi, 2 * math.pi) - math.pi
    # remainder() lands in [0, 2pi), so only exactly -pi needs moving to the closed end.
    return torch.where(r <= -math.pi, r + 2 * math.pi, r)


def rotate(vec: Tensor, angle: Tensor | float) -> Tensor:
    """Rotate vectors [..., 2] counter-clockwise by `angle` (broadcast against vec[..., 0])."""
    angle = torch.as_tensor(angle, dtype=vec.dtype, device=vec.device)
    c, s = torch.cos(angle), torch.sin(angle)
    x, y = vec[..., 0], vec[..., 1]
    return torch.stack((c * x - s * y, s * x + c * y), dim=-1)


def to_local(points: Tensor, origin: Tensor, heading: Tensor | float) -> Tensor:
    """World points [..., P, 2] into the frame at `origin` [..., 2] heading along `heading` [...]."""
    heading = torch.as_tensor(heading, dtype=points.dtype, device=points.device)
    return rotate(points - origin.unsqueeze(-2), -heading.unsqueeze(-1))


def to_world(points: Tensor, origin: Tensor, heading: Tensor | float) -> Tensor:
    """Inverse of `to_local`: local points [..., P, 2] back into world coordinates."""
    heading = torch.as_tensor(heading, dtype=points.dtype, device=points.device)
    return rotate(points, heading.unsqueeze(-1)) + origin.unsqueeze(-2)


def rect_corners(pos: Tensor, heading: Tensor | float, length: float, width: float) -> Tensor:
    """Corners [..., 4, 2] of rectangles centred at `pos`: front-left, front-right, rear-right, rear-left."""
    hl, hw = length / 2, width / 2
    local = torch.tensor(
        [[hl, hw], [hl, -hw], [-hl, -hw], [-hl, hw]], dtype=pos.dtype, device=pos.device
    )
    return to_world(local, pos, heading)
