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


def _segment_mask(n_segments: int, n_valid: Tensor | None, device: torch.device) -> Tensor | None:
    """[..., S] True for segments whose both end vertices are valid (index < n_valid)."""
    if n_valid is None:
        return None
    n_valid = torch.as_tensor(n_valid, device=device)
    idx = torch.arange(n_segments, device=device)
    return idx < (n_valid.unsqueeze(-1) - 1)


def point_polyline_distance(
    points: Tensor, polyline: Tensor, n_valid: Tensor | None = None
) -> tuple[Tensor, Tensor, Tensor, Tensor]:
    """Distance from points [..., P, 2] to a polyline [..., V, 2] (leading dims broadcast).

    Returns (dist [..., P], seg_idx [..., P] long, t [..., P] in [0, 1], proj [..., P, 2]):
    the closest segment (v_i, v_{i+1}), the projection parameter along it and the closest
    point. `n_valid` [...] counts the valid leading vertices of padded polylines; segments
    touching padding are ignored. With fewer than two valid vertices, dist is inf.
    """
    if polyline.shape[-2] < 2:
        raise ValueError(f"polyline needs at least 2 vertices, got shape {tuple(polyline.shape)}")
    a = polyline[..., :-1, :].unsqueeze(-3)  # [..., 1, S, 2]
    d = (polyline[..., 1:, :] - polyline[..., :-1, :]).unsqueeze(-3)
    p = points.unsqueeze(-2)  # [..., P, 1, 2]
    dd = (d * d).sum(-1)
    # Zero-length segments project onto their start point instead of dividing by zero.
    t = ((p - a) * d).sum(-1) / torch.where(dd > 0, dd, torch.ones_like(dd))
    t = t.clamp(0.0, 1.0)  # [..., P, S]
    proj = a + t.unsqueeze(-1) * d
    dist2 = ((p - proj) ** 2).sum(-1)
    mask = _segment_mask(polyline.shape[-2] - 1, n_valid, points.device)
    if mask is not None:
        dist2 = torch.where(mask.unsqueeze(-2), dist2, torch.full_like(dist2, math.inf))
    seg_idx = dist2.argmin(dim=-1, keepdim=True)  # [..., P, 1]
    t_best = t.gather(-1, seg_idx)
    proj_best = torch.gather(
        proj.expand(*t.shape, 2), -2, seg_idx.unsqueeze(-1).expand(*seg_idx.shape, 2)
    ).squeeze(-2)
    # Norm of the difference (not sqrt of the min) gives a finite gradient at zero distance.
    dist = torch.linalg.vector_norm(points - proj_best, dim=-1)
    if mask is not None:
        no_segment = ~mask.any(-1, keepdim=True)  # [..., 1], broadcasts over P
        dist = torch.where(no_segment, torch.full_like(dist, math.inf), dist)
    return dist, seg_idx.squeeze(-1), t_best.squeeze(-1), proj_best


def _unit(v: Tensor) -> Tensor:
    """Normalise vectors [..., 2]; zero vectors stay zero (a degenerate axis never separates)."""
    n = torch.linalg.vector_norm(v, dim=-1, keepdim=True)
    return v / torch.where(n > 0, n, torch.ones_like(n))


def _edge_normals(poly: Tensor) -> Tensor:
    """Unit normals [..., N, 2] of the closed polygon's edges (the polygon is [..., N, 2])."""
    e = torch.roll(poly, shifts=-1, dims=-2) - poly
    return _unit(torch.stack((-e[..., 1], e[..., 0]), dim=-1))


def _sat_overlap(axes: Tensor, pa: Tensor, pb: Tensor) -> Tensor:
    """Inclusive separating-axis test of point sets pa [..., Na, 2] and pb [..., Nb, 2].

    `axes` [..., K, 2] must contain every axis that can separate the two convex hulls;
    extra axes are harmless. Returns True where no axis separates them.
    """
    proj_a = (pa.unsqueeze(-3) * axes.unsqueeze(-2)).sum(-1)  # [..., K, Na]
    proj_b = (pb.unsqueeze(-3) * axes.unsqueeze(-2)).sum(-1)
    lo_a, hi_a = proj_a.amin(-1), proj_a.amax(-1)
    lo_b, hi_b = proj_b.amin(-1), proj_b.amax(-1)
    scale = torch.maximum(proj_a.abs().amax(-1), proj_b.abs().amax(-1))
    tol = _TOL_ULPS * torch.finfo(scale.dtype).eps * scale
    separated = (hi_a < lo_b - tol) | (hi_b < lo_a - tol)
    return ~separated.any(-1)


def _concat_axes(u: Tensor, v: Tensor) -> Tensor:
    """Concatenate axis lists [..., Ku, 2] and [..., Kv, 2] whose leading dims broadcast."""
    lead = torch.broadcast_shapes(u.shape[:-2], v.shape[:-2])
    return torch.cat((u.expand(*lead, *u.shape[-2:]), v.expand(*lead, *v.shape[-2:])), dim=-2)


def rect_overlap(a: Tensor, b: Tensor) -> Tensor:
    """Whether convex quadrilaterals a, b [..., 4, 2] overlap; touching and containment count."""
    axes = _concat_axes(_edge_normals(a), _edge_normals(b))
    return _sat_overlap(axes, a, b)


def pairwise_rect_overlap(corners: Tensor) -> Tensor:
    """All-pairs `rect_overlap` of corners [..., A, 4, 2] -> [..., A, A], symmetric, diagonal False."""
    n = corners.shape[-3]
    hit = rect_overlap(corners.unsqueeze(-3), corners.unsqueeze(-4))
    return hit & ~torch.eye(n, dtype=torch.bool, device=corners.device)


def _cross(u: Tensor, v: Tensor) -> Tensor:
    return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]


def segments_intersect(p1: Tensor, p2: Tensor, q1: Tensor, q2: Tensor) -> Tensor:
    """Whether segments p1p2 and q1q2 ([..., 2] each) share a point; touching and collinear
    overlap count, and degenerate (zero-length) segments act as points."""
    p1, p2, q1, q2 = torch.broadcast_tensors(p1, p2, q1, q2)
    pts = torch.stack((p1, p2, q1, q2), dim=-2)
    # Absolute tolerance on coordinates: a few ulps of the largest one involved.
    tol = (_TOL_ULPS * torch.finfo(pts.dtype).eps) * pts.abs().amax(dim=(-1, -2))

    def side(a: Tensor, b: Tensor, c: Tensor) -> Tensor:
        # Moving the points by `tol` changes the cross product by about tol * (|b-a| + |c-a|).
        u, v = b - a, c - a
        o = _cross(u, v)
        band = tol * (torch.linalg.vector_norm(u, dim=-1) + torch.linalg.vector_norm(v, dim=-1))
        return torch.where(o.abs() <= band, torch.zeros_like(o), torch.sign(o))

    def within(c: Tensor, a: Tensor, b: Tensor) -> Tensor:
        # c lies in the bounding box of ab (used only once c is known to be on line ab).
        t = tol.unsqueeze(-1)
        return ((c >= torch.minimum(a, b) - t) & (c <= torch.maximum(a, b) + t)).all(-1)

    s1, s2 = side(p1, p2, q1), side(p1, p2, q2)
    s3, s4 = side(q1, q2, p1), side(q1, q2, p2)
    proper = (s1 * s2 < 0) & (s3 * s4 < 0)
    touch = (
        ((s1 == 0) & within(q1, p1, p2))
        | ((s2 == 0) & within(q2, p1, p2))
        | ((s3 == 0) & within(p1, q1, q2))
        | ((s4 == 0) & within(p2, q1, q2))
    )
    return proper | touch


def polyline_rect_overlap(rect: Tensor, polyline: Tensor, n_valid: Tensor | None = None) -> Tensor:
    """Whether any valid segment of polyline [..., V, 2] touches or enters rect [..., 4, 2].

    Each segment is a degenerate polygon in a separating-axis test whose axes are the
    rectangle's edge normals and the segment's normal; a segment lying inside counts.
    """
    seg = torch.stack((polyline[..., :-1, :], polyline[..., 1:, :]), dim=-2)  # [..., S, 2, 2]
    d = seg[..., 1, :] - seg[..., 0, :]
    seg_normal = _unit(torch.stack((-d[..., 1], d[..., 0]), dim=-1)).unsqueeze(-2)
    rect_s = rect.unsqueeze(-3)  # [..., 1, 4, 2]
    rect_axes = _edge_normals(rect_s)
    axes = _concat_axes(rect_axes, seg_normal)
    hit = _sat_overlap(axes, rect_s, seg)  # [..., S]
    mask = _segment_mask(polyline.shape[-2] - 1, n_valid, polyline.device)
    if mask is not None:
        hit = hit & mask
    return hit.any(-1)
