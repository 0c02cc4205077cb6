"""Geometry kernels against shapely, hand-worked values and hypothesis properties."""

from __future__ import annotations

import math

import pytest
import torch
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from shapely.geometry import LineString, Point, Polygon

from sigmarl.env.geometry import (
    pairwise_rect_overlap,
    point_polyline_distance,
    polyline_rect_overlap,
    rect_corners,
    rect_overlap,
    rotate,
    segments_intersect,
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


@SETTINGS
@given(st.lists(xy, min_size=1, max_size=5), polyline_st)
def test_point_polyline_distance_matches_shapely(points, vertices):
    pts, pl = t64(points), t64(vertices)
    dist, seg, t, proj = point_polyline_distance(pts, pl)
    assert dist.shape == seg.shape == t.shape == (len(points),)
    assert proj.shape == (len(points), 2)
    assert seg.dtype == torch.long
    line = LineString(vertices)
    for i, p in enumerate(points):
        assert dist[i].item() == pytest.approx(line.distance(Point(p)), abs=1e-9)
    # The reported segment, parameter and closest point agree with one another.
    assert ((t >= 0) & (t <= 1)).all()
    on_seg = pl[seg] + t[:, None] * (pl[seg + 1] - pl[seg])
    torch.testing.assert_close(proj, on_seg, atol=1e-9, rtol=0)
    torch.testing.assert_close((pts - proj).norm(dim=-1), dist, atol=1e-9, rtol=0)
    # float32 agrees within float32 noise.
    d32 = point_polyline_distance(pts.float(), pl.float())[0]
    torch.testing.assert_close(d32.double(), dist, atol=1e-5, rtol=0)


def test_point_polyline_hand_values_and_zero_length_segments():
    pl = t64([[0.0, 0.0], [0.0, 0.0], [2.0, 0.0], [2.0, 0.0], [2.0, 2.0]])
    pts = t64([[1.0, 1.0], [3.0, 1.5], [-1.0, 0.0], [2.0, 0.0]])
    dist, seg, t, proj = point_polyline_distance(pts, pl)
    assert torch.isfinite(dist).all() and torch.isfinite(t).all() and torch.isfinite(proj).all()
    torch.testing.assert_close(dist, t64([1.0, 1.0, 1.0, 0.0]))
    assert seg[0].item() == 1 and t[0].item() == pytest.approx(0.5)
    assert seg[1].item() == 3 and t[1].item() == pytest.approx(0.75)
    torch.testing.assert_close(proj[:3], t64([[1.0, 0.0], [2.0, 1.5], [0.0, 0.0]]))


@FEW
@given(st.lists(xy, min_size=1, max_size=4), polyline_st, st.lists(xy, min_size=1, max_size=4))
def test_point_polyline_padding_is_ignored(points, vertices, padding):
    pts, pl = t64(points), t64(vertices)
    padded = torch.cat([pl, t64(padding)])
    ref = point_polyline_distance(pts, pl)
    got = point_polyline_distance(pts, padded, n_valid=torch.tensor(len(vertices)))
    for r, g in zip(ref, got, strict=True):
        torch.testing.assert_close(g, r, atol=0, rtol=0)


def test_point_polyline_batched_equals_per_element():
    g = torch.Generator().manual_seed(1)
    E, A, P, V = 3, 4, 5, 7
    pts = torch.rand(E, A, P, 2, generator=g, dtype=F64) * 4
    pl = torch.rand(E, A, V, 2, generator=g, dtype=F64) * 4
    n_valid = torch.randint(2, V + 1, (E, A), generator=g)
    dist, seg, t, proj = point_polyline_distance(pts, pl, n_valid)
    assert dist.shape == (E, A, P) and proj.shape == (E, A, P, 2)
    for e in range(E):
        for a in range(A):
            n = int(n_valid[e, a])
            ref = point_polyline_distance(pts[e, a], pl[e, a, :n])
            for r, b in zip(ref, (dist, seg, t, proj), strict=True):
                torch.testing.assert_close(b[e, a], r, atol=1e-12, rtol=0)
    # A polyline shared by every agent broadcasts against the points' leading dims.
    shared = point_polyline_distance(pts, pl[0, 0])
    ref = point_polyline_distance(pts.reshape(-1, 2), pl[0, 0])
    torch.testing.assert_close(shared[0], ref[0].reshape(E, A, P))


def test_point_polyline_without_valid_segment_is_inf():
    pl = t64([[0.0, 0.0], [1.0, 0.0], [9.0, 9.0]])
    dist = point_polyline_distance(t64([[[0.5, 1.0]], [[0.5, 1.0]]]), pl, torch.tensor([1, 2]))[0]
    assert math.isinf(dist[0, 0].item()) and dist[1, 0].item() == pytest.approx(1.0)


# ---------------------------------------------------------------- rectangle overlap


@SETTINGS
@given(near_pose_st, near_pose_st)
def test_rect_overlap_matches_shapely(pose_a, pose_b):
    a, b = corners_of(pose_a), corners_of(pose_b)
    pa, pb = poly(a), poly(b)
    assume(not ambiguous(pa, pb))
    expected = pa.intersects(pb)
    assert bool(rect_overlap(a, b)) == expected
    assert bool(rect_overlap(b, a)) == expected


def _placed(pose, local_offset, rel_heading, length, width):
    """Pose of a second rectangle placed in the first one's frame."""
    (x, y), heading, _, _ = pose
    off = rotate(t64(local_offset), t64(heading))
    return ((x + off[0].item(), y + off[1].item()), heading + rel_heading, length, width)


CASES = ["end_to_end", "side_by_side", "corner", "vertex_on_edge", "inside", "contains", "miss"]


@SETTINGS
@given(pose_st, st.sampled_from(CASES), st.floats(-0.9, 0.9), st.sampled_from([torch.float32, F64]))
def test_rect_overlap_constructed_cases(pose, case, frac, dtype):
    _, _, L, W = pose
    if case == "end_to_end":  # rear edge of b on the front edge of a
        other, expected = _placed(pose, (L, frac * W), 0.0, L, W), True
    elif case == "side_by_side":  # long edges touching
        other, expected = _placed(pose, (frac * L, W), 0.0, L, W), True
    elif case == "corner":  # only one corner in common
        other, expected = _placed(pose, (L, math.copysign(W, frac)), 0.0, L, W), True
    elif case == "vertex_on_edge":  # a square turned 45 deg, one vertex on a's front edge
        side = 0.5 * W
        other = _placed(pose, (L / 2 + side / math.sqrt(2), frac * W / 2), math.pi / 4, side, side)
        expected = True
    elif case == "inside":  # small and turned, well inside a
        s = 0.25 * min(L, W)
        other, expected = _placed(pose, (frac * L / 4, 0.0), frac * 3, s, s), True
    elif case == "contains":
        other, expected = _placed(pose, (0.0, 0.0), 0.3, 3 * L + W, 3 * L + W), True
    else:  # a gap of 1e-4 beyond the front edge
        other, expected = _placed(pose, (L + 1e-4, frac * W), 0.0, L, W), False
    a, b = corners_of(pose, dtype), corners_of(other, dtype)
    assert bool(rect_overlap(a, b)) == expected
    assert bool(rect_overlap(b, a)) == expected
    if case in ("inside", "contains", "miss"):  # unambiguous for shapely too
        assert poly(corners_of(pose)).intersects(poly(corners_of(other))) == expected


@pytest.mark.parametrize(
    ("center_b", "size_b", "expected"),
    [
        ((0.75, 0.25), (0.25, 0.125), True),  # edge to edge
        ((0.75, 0.375), (0.25, 0.125), True),  # corner to corner
        ((0.5, 0.25), (0.0625, 0.0625), True),  # inside
        ((0.5, 0.25), (2.0, 2.0), True),  # contains
        ((0.75 + 2**-13, 0.25), (0.25, 0.125), False),  # gap of 1.2e-4
        ((0.75, 0.375 + 2**-13), (0.25, 0.125), False),  # corners miss
    ],
)
@pytest.mark.parametrize("dtype", [torch.float32, F64])
def test_rect_overlap_exact_axis_aligned(center_b, size_b, expected, dtype):
    # Dyadic coordinates are exact in both dtypes and in shapely, so touching is truly touching.
    a = rect_corners(
        torch.tensor([0.5, 0.25], dtype=dtype), torch.tensor(0.0, dtype=dtype), 0.25, 0.125
    )
    b = rect_corners(torch.tensor(center_b, dtype=dtype), torch.tensor(0.0, dtype=dtype), *size_b)
    assert poly(a).intersects(poly(b)) == expected
    assert bool(rect_overlap(a, b)) == expected


def test_pairwise_rect_overlap_batched():
    g = torch.Generator().manual_seed(2)
    E, A = 4, 6
    pos = torch.rand(E, A, 2, generator=g, dtype=F64) * 0.5
    heading = (torch.rand(E, A, generator=g, dtype=F64) - 0.5) * 2 * math.pi
    corners = rect_corners(pos, heading, 0.16, 0.08)
    hit = pairwise_rect_overlap(corners)
    assert hit.shape == (E, A, A) and hit.dtype == torch.bool
    assert not hit.diagonal(dim1=-2, dim2=-1).any()
    assert torch.equal(hit, hit.transpose(-1, -2))
    for e in range(E):
        for i in range(A):
            for j in range(A):
                if i != j:
                    ref = poly(corners[e, i]).intersects(poly(corners[e, j]))
                    assert bool(hit[e, i, j]) == ref
                    assert bool(rect_overlap(corners[e, i], corners[e, j])) == ref
    assert hit.any() and not hit.all()  # the sample exercises both outcomes


# ---------------------------------------------------------------- segments


def _check_segments(p1, p2, q1, q2):
    got = bool(segments_intersect(t64(p1), t64(p2), t64(q1), t64(q2)))
    sa, sb = shape([p1, p2]), shape([q1, q2])
    assume(not ambiguous(sa, sb))
    assert got == sa.intersects(sb)
    # Symmetric in the two segments and in their end-point order.
    assert got == bool(segments_intersect(t64(q2), t64(q1), t64(p1), t64(p2)))


@SETTINGS
@given(grid_xy, grid_xy, grid_xy, grid_xy)
def test_segments_intersect_grid_matches_shapely(p1, p2, q1, q2):
    # Integer coordinates make touching, collinear and zero-length cases frequent and exact.
    _check_segments(p1, p2, q1, q2)


@SETTINGS
@given(xy, xy, xy, xy)
def test_segments_intersect_random_matches_shapely(p1, p2, q1, q2):
    _check_segments(p1, p2, q1, q2)


def test_segments_intersect_hand_cases_float32():
    f = torch.float32
    p1 = torch.tensor([[0.0, 0.0], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0], [0.1, 0.3]], dtype=f)
    p2 = torch.tensor([[1.0, 1.0], [2.0, 0.0], [1.0, 0.0], [1.0, 0.0], [0.7, 0.9]], dtype=f)
    q1 = torch.tensor([[0.0, 1.0], [1.0, 0.0], [1.0, 0.0], [1.0001, 0.0], [0.4, 0.6]], dtype=f)
    q2 = torch.tensor([[1.0, 0.0], [3.0, 0.0], [1.0, 1.0], [2.0, 0.0], [0.4, 0.6]], dtype=f)
    # crossing; collinear overlap; T-touch at an end point; collinear gap; point on segment
    got = segments_intersect(p1, p2, q1, q2)
    assert got.tolist() == [True, True, True, False, True]


# ---------------------------------------------------------------- polyline vs rectangle


@SETTINGS
@given(
    st.tuples(
        st.tuples(coords(-1, 1), coords(-1, 1)),
        heading_st,
        st.floats(0.1, 2),
        st.floats(0.1, 2),
    ),
    st.lists(st.tuples(coords(-2, 2), coords(-2, 2)), min_size=2, max_size=6),
)
def test_polyline_rect_overlap_matches_shapely(pose, vertices):
    rect = corners_of(pose)
    pr, line = poly(rect), shape(vertices)
    assume(not ambiguous(pr, line))
    assert bool(polyline_rect_overlap(rect, t64(vertices))) == line.intersects(pr)


@SETTINGS
@given(
    st.tuples(st.integers(-2, 2), st.integers(-2, 2)),
    st.integers(1, 3),
    st.integers(1, 3),
    st.lists(grid_xy, min_size=2, max_size=5),
    st.sampled_from([torch.float32, F64]),
)
def test_polyline_rect_overlap_grid_matches_shapely(corner, w, h, vertices, dtype):
    # Axis-aligned rectangle with integer corners: touching cases are exact everywhere.
    x0, y0 = corner
    rect = torch.tensor([[x0 + w, y0 + h], [x0 + w, y0], [x0, y0], [x0, y0 + h]], dtype=dtype)
    expected = shape(vertices).intersects(poly(rect))
    assert bool(polyline_rect_overlap(rect, torch.tensor(vertices, dtype=dtype))) == expected


def test_polyline_rect_overlap_hand_cases():
    rect = rect_corners(t64([0.0, 0.0]), t64(0.3), 0.16, 0.08)
    inside = t64([[-0.01, 0.0], [0.01, 0.0]])  # entirely within the rectangle
    far = t64([[1.0, 1.0], [2.0, 1.0]])
    through = t64([[-1.0, 0.0], [1.0, 0.0]])  # crosses without any vertex inside
    assert bool(polyline_rect_overlap(rect, inside))
    assert not bool(polyline_rect_overlap(rect, far))
    assert bool(polyline_rect_overlap(rect, through))


@FEW
@given(pose_st, polyline_st, st.lists(xy, min_size=1, max_size=4))
def test_polyline_rect_overlap_padding_is_ignored(pose, vertices, padding):
    rect = corners_of(pose)
    pl = t64(vertices)
    padded = torch.cat([pl, t64(padding)])
    ref = polyline_rect_overlap(rect, pl)
    assert bool(polyline_rect_overlap(rect, padded, torch.tensor(len(vertices)))) == bool(ref)


def test_polyline_rect_overlap_batched_equals_per_element():
    g = torch.Generator().manual_seed(3)
    E, A, V = 4, 5, 6
    pos = torch.rand(E, A, 2, generator=g, dtype=F64)
    heading = torch.rand(E, A, generator=g, dtype=F64) * 6
    rect = rect_corners(pos, heading, 0.3, 0.2)
    pl = torch.rand(E, A, V, 2, generator=g, dtype=F64)
    n_valid = torch.randint(2, V + 1, (E, A), generator=g)
    hit = polyline_rect_overlap(rect, pl, n_valid)
    assert hit.shape == (E, A)
    for e in range(E):
        for a in range(A):
            n = int(n_valid[e, a])
            ref = shape(pl[e, a, :n].tolist()).intersects(poly(rect[e, a]))
            assert bool(hit[e, a]) == ref
    assert hit.any() and not hit.all()
    # One polyline shared by all rectangles.
    shared = polyline_rect_overlap(rect, pl[0, 0])
    for e in range(E):
        for a in range(A):
            assert bool(shared[e, a]) == bool(polyline_rect_overlap(rect[e, a], pl[0, 0]))
