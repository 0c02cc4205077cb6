"""Per-step kernels specialised to the environment: every vehicle is the same rectangle.

The generic separating-axis kernels in `geometry` project every corner on every
axis. Here the axes and projections follow in closed form from the poses, which
makes the per-step tests a few elementwise operations on [E, A, A] or [E, A, W].
Both are inclusive: touching counts as a collision.
"""

from __future__ import annotations

import torch

_EPS = 1e-6  # m, so that exactly touching rectangles count in float32


def pairwise_box_overlap(pos: torch.Tensor, heading: torch.Tensor, length: float, width: float) -> torch.Tensor:
    """[E, A, A] True where vehicle i and vehicle j (i != j) overlap or touch.

    Oriented-box test on the four candidate axes (two per box): the boxes are
    apart iff the distance between centers, projected on some axis, exceeds the
    sum of the two half-extents projected on it.
    """
    hl, hw = length / 2, width / 2
    dpsi = heading.unsqueeze(-2) - heading.unsqueeze(-1)  # [E, i, j]: psi_j - psi_i
    c, s = dpsi.cos().abs(), dpsi.sin().abs()
    rel = pos.unsqueeze(-3) - pos.unsqueeze(-2)  # [E, i, j, 2]: p_j - p_i
    ci, si = heading.cos().unsqueeze(-1), heading.sin().unsqueeze(-1)
    cj, sj = heading.cos().unsqueeze(-2), heading.sin().unsqueeze(-2)
    # Projections of the center offset on i's axes and on j's axes.
    xi = rel[..., 0] * ci + rel[..., 1] * si
    yi = -rel[..., 0] * si + rel[..., 1] * ci
    xj = rel[..., 0] * cj + rel[..., 1] * sj
    yj = -rel[..., 0] * sj + rel[..., 1] * cj
    r_long = hl + hl * c + hw * s  # extent along a long axis (same for i's and j's by symmetry)
    r_lat = hw + hl * s + hw * c
    hit = (xi.abs() <= r_long + _EPS) & (yi.abs() <= r_lat + _EPS)
    hit &= (xj.abs() <= r_long + _EPS) & (yj.abs() <= r_lat + _EPS)
    eye = torch.eye(pos.shape[-2], dtype=torch.bool, device=pos.device)
    return hit & ~eye


def segments_box_overlap(
    table: torch.Tensor, pos: torch.Tensor, heading: torch.Tensor, length: float, width: float
) -> torch.Tensor:
    """[..., C] True where any segment of the `segment_table` rows [..., 5, C, S] touches the
    box at pos [..., 2] with heading [...].

    In the vehicle frame the box is axis-aligned: a segment misses it iff its bounding
    interval misses the box on x or y, or the box lies entirely on one side of the segment's
    line.
    """
    hl, hw = length / 2, width / 2
    c = heading.cos()[..., None, None]
    s = heading.sin()[..., None, None]
    rx = table[..., 0, :, :] - pos[..., 0, None, None]  # [..., C, S]
    ry = table[..., 1, :, :] - pos[..., 1, None, None]
    dx, dy = table[..., 2, :, :], table[..., 3, :, :]
    ax, ay = rx * c + ry * s, ry * c - rx * s  # segment start and direction in the vehicle frame
    ux, uy = dx * c + dy * s, dy * c - dx * s
    bx, by = ax + ux, ay + uy
    in_x = (torch.minimum(ax, bx) <= hl + _EPS) & (torch.maximum(ax, bx) >= -hl - _EPS)
    in_y = (torch.minimum(ay, by) <= hw + _EPS) & (torch.maximum(ay, by) >= -hw - _EPS)
    # Distance of the box center from the segment's line, and the box's half-extent along
    # the line's normal, both scaled by |d| (so zero-length segments reduce to a point test).
    side = (ux * ay - uy * ax).abs()
    reach = hl * uy.abs() + hw * ux.abs()
    across = side <= reach + _EPS * torch.hypot(ux, uy)
    return (in_x & in_y & across).any(-1)


def crossings_odd(start: torch.Tensor, end: torch.Tensor, table: torch.Tensor) -> torch.Tensor:
    """[..., C] True where the segment start -> end ([..., 2] each) crosses the polylines of a
    `segment_table` [..., 5, C, S] an odd number of times.

    With `start` inside a region bounded by the polylines, an odd count puts `end` outside it,
    whatever the boundary's shape (steps where a corridor narrows, backtracking vertices).
    Each segment counts its start point but not its end, so a crossing through a shared
    vertex counts once.
    """
    sx = start[..., 0, None, None]
    sy = start[..., 1, None, None]
    ex = end[..., 0, None, None] - sx
    ey = end[..., 1, None, None] - sy
    ax, ay = table[..., 0, :, :] - sx, table[..., 1, :, :] - sy  # [..., C, S]
    dx, dy = table[..., 2, :, :], table[..., 3, :, :]
    denom = ex * dy - ey * dx  # zero for parallel or zero-length segments: never a crossing
    u = (ax * dy - ay * dx) / denom  # along start -> end
    t = (ax * ey - ay * ex) / denom  # along the boundary segment
    hit = (denom != 0) & (u >= 0) & (u <= 1) & (t >= 0) & (t < 1)
    return hit.sum(-1) % 2 == 1


def segment_table(lines: torch.Tensor) -> torch.Tensor:
    """What `nearest_on_segments` needs of polylines [..., L, W, 2], precomputed once per map:
    [..., 5, L, W - 1] = segment start x, start y, dx, dy and 1 / |d|^2 (0 for zero-length
    segments, which then project onto their start)."""
    a, d = lines[..., :-1, :], lines[..., 1:, :] - lines[..., :-1, :]
    dd = (d * d).sum(-1)
    inv = torch.where(dd > 0, 1.0 / torch.where(dd > 0, dd, torch.ones_like(dd)), torch.zeros_like(dd))
    return torch.stack([a[..., 0], a[..., 1], d[..., 0], d[..., 1], inv], dim=-3).contiguous()


def nearest_on_segments(points: torch.Tensor, table: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Distance from points [..., P, 2] to the polylines of a `segment_table` [..., 5, L, S],
    and the closest segment: both [..., L, P].

    For the step's hot path: no padding masks, no projected points, and x and y kept apart (reductions over a last dimension of
    size 2 cost more than the arithmetic).
    """
    px = points[..., 0].unsqueeze(-2).unsqueeze(-1)  # [..., 1, P, 1]
    py = points[..., 1].unsqueeze(-2).unsqueeze(-1)
    ax, ay, dx, dy, inv = (t.unsqueeze(-2) for t in table.unbind(-3))  # [..., L, 1, S]
    apx, apy = px - ax, py - ay  # [..., L, P, S]
    t = ((apx * dx + apy * dy) * inv).clamp(0.0, 1.0)
    ex, ey = apx - t * dx, apy - t * dy
    dist2, seg = (ex * ex + ey * ey).min(-1)
    return dist2.sqrt(), seg
