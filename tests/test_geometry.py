"""Geometry kernels against shapely, hand-worked values and hypothesis properties."""

from __future__ import annotations

import math

import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.geometry import LineString, Point, Polygon

from sigmarl.env.geometry import (
    rect_corners,
    rotate,
    to_local,
    to_world,
    wrap_angle,
)

F64 = torch.float64
SETTINGS = settings(max_examples=200, deadline=None)
FEW = settings(max_examples=100, deadline=None)  # checks that need no shapely oracle


# Rounded to 1e-9 m: hypothesis likes values such as 1e-252, whose squares underflow inside
# shapely (it then reports an infinite distance); ties and exact touching remain reachable.
def coords(lo: float, hi: float) -> st.SearchStrategy[float]:
    return st.floats(lo, hi).map(lambda v: round(v, 9))


coord = coords(-5.0, 5.0)
xy = st.tuples(coord, coord)
grid_xy = st.tuples(st.integers(-3, 3), st.integers(-3, 3))
polyline_st = st.lists(xy, min_size=2, max_size=8)
heading_st = st.floats(-math.pi, math.pi)
pose_st = st.tuples(xy, heading_st, st.floats(0.05, 1.0), st.floats(0.02, 0.5))
# Poses close together, so that random pairs overlap about as often as not.
near_pose_st = st.tuples(
    st.tuples(coords(-0.6, 0.6), coords(-0.6, 0.6)),
    heading_st,
    st.floats(0.05, 1.0),
    st.floats(0.02, 0.5),
)


def t64(x) -> torch.Tensor:
    return torch.tensor(x, dtype=F64)


def corners_of(pose, dtype=F64) -> torch.Tensor:
    (x, y), heading, length, width = pose
    return rect_corners(
        torch.tensor([x, y], dtype=dtype), torch.tensor(heading, dtype=dtype), length, width
    )


def poly(c: torch.Tensor) -> Polygon:
    return Polygon(c.double().tolist())


def shape(vertices):
    """Shapely geometry of a polyline; a zero-length one is a point (shapely treats a
    degenerate LineString as intersecting nothing)."""
    if all(tuple(v) == tuple(vertices[0]) for v in vertices):
        return Point(vertices[0])
    return LineString(vertices)


def ambiguous(a, b) -> bool:
    """Shapes that shapely calls disjoint by less than float noise (the test tolerance decides)."""
    return not a.intersects(b) and a.distance(b) < 1e-9


# ---------------------------------------------------------------- angles and frames


def test_wrap_angle_hand_values():
    a = t64([math.pi, -math.pi, 3 * math.pi, -3 * math.pi, 0.0, 2 * math.pi, 7.0])
    out = wrap_angle(a)
    expected = t64([math.pi, math.pi, math.pi, math.pi, 0.0, 0.0, 7.0 - 2 * math.pi])
    torch.testing.assert_close(out, expected, atol=1e-12, rtol=0)
    # The closed end is +pi: exactly -pi maps to exactly +pi.
    assert out[1].item() == math.pi


@FEW
@given(st.floats(-1e3, 1e3), st.sampled_from([torch.float32, F64]))
def test_wrap_angle_range_and_equivalence(a, dtype):
    x = torch.tensor(a, dtype=dtype)
    w = wrap_angle(x)
    pi = torch.tensor(math.pi, dtype=dtype)
    assert -pi < w <= pi
    k = (x.double() - w.double()) / (2 * math.pi)
    assert abs(k - torch.round(k)) < 1e-4


def test_rotate_hand_values():
    v = t64([[1.0, 0.0], [0.0, 2.0]])
    out = rotate(v, t64([math.pi / 2, math.pi / 2]))
    torch.testing.assert_close(out, t64([[0.0, 1.0], [-2.0, 0.0]]), atol=1e-12, rtol=0)


def test_to_local_hand_values():
    origin, heading = t64([1.0, 2.0]), t64(math.pi / 2)  # facing +y
    world = t64([[1.0, 3.0], [0.0, 2.0], [2.0, 1.0]])
    local = to_local(world, origin, heading)
    # 1 m ahead; 1 m to the left; 1 m behind and 1 m to the right.
    torch.testing.assert_close(
        local, t64([[1.0, 0.0], [0.0, 1.0], [-1.0, -1.0]]), atol=1e-12, rtol=0
    )
    torch.testing.assert_close(to_world(local, origin, heading), world, atol=1e-12, rtol=0)


def test_to_local_round_trip_batched():
    g = torch.Generator().manual_seed(0)
    pts = torch.randn(3, 4, 5, 2, generator=g, dtype=F64) * 3
    origin = torch.randn(3, 4, 2, generator=g, dtype=F64)
    heading = (torch.rand(3, 4, generator=g, dtype=F64) - 0.5) * 20
    local = to_local(pts, origin, heading)
    assert local.shape == pts.shape
    torch.testing.assert_close(to_world(local, origin, heading), pts, atol=1e-12, rtol=0)
    # Distances to the origin are preserved; the frame is a rigid motion.
    torch.testing.assert_close(
        local.norm(dim=-1), (pts - origin[..., None, :]).norm(dim=-1), atol=1e-12, rtol=0
    )
    # Element (1, 2) alone gives the same answer.
    single = to_local(pts[1, 2], origin[1, 2], heading[1, 2])
    torch.testing.assert_close(local[1, 2], single, atol=0, rtol=0)


def test_rect_corners_hand_values():
    c = rect_corners(t64([1.0, 2.0]), t64(math.pi / 2), 0.16, 0.08)
    # Facing +y: front is +y, left is -x. FL, FR, RR, RL.
    expected = t64([[0.96, 2.08], [1.04, 2.08], [1.04, 1.92], [0.96, 1.92]])
    torch.testing.assert_close(c, expected, atol=1e-12, rtol=0)
    c0 = rect_corners(t64([[0.0, 0.0]]), t64([0.0]), 2.0, 1.0)
    assert c0.shape == (1, 4, 2)
    torch.testing.assert_close(c0[0], t64([[1.0, 0.5], [1.0, -0.5], [-1.0, -0.5], [-1.0, 0.5]]))


# ---------------------------------------------------------------- point to polyline
