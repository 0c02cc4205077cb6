"""The environment's specialised collision kernels against shapely."""

from __future__ import annotations

import math

import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.geometry import LineString, Polygon

from sigmarl.env.collision import pairwise_box_overlap, segment_table, segments_box_overlap
from sigmarl.env.geometry import rect_corners

L, W = 0.16, 0.08


def polyline_box_overlap(
    polyline: torch.Tensor, pos: torch.Tensor, heading: torch.Tensor, length: float, width: float
) -> torch.Tensor:
    """[...] True where any segment of the polyline [..., W, 2] touches the box at pos [..., 2]
    with heading [...]."""
    return segments_box_overlap(segment_table(polyline.unsqueeze(-3)), pos, heading, length, width)[..., 0]


def _poly(x, y, psi):
    c = rect_corners(torch.tensor([x, y], dtype=torch.float64), torch.tensor(psi, dtype=torch.float64), L, W)
    return Polygon(c.numpy())


coord = st.floats(-0.25, 0.25).map(lambda v: round(v, 9))  # shapely mishandles denormals
angle = st.floats(-math.pi, math.pi)


@settings(max_examples=400, deadline=None)
@given(x=coord, y=coord, psi_i=angle, psi_j=angle)
def test_pairwise_matches_shapely(x, y, psi_i, psi_j):
    pos = torch.tensor([[[0.0, 0.0], [x, y]]], dtype=torch.float64)
    heading = torch.tensor([[psi_i, psi_j]], dtype=torch.float64)
    hit = pairwise_box_overlap(pos, heading, L, W)
    expected = _poly(0, 0, psi_i).intersects(_poly(x, y, psi_j))
    # Within 1e-6 m of touching the two answers may legitimately differ (tolerance).
    gap = _poly(0, 0, psi_i).distance(_poly(x, y, psi_j))
    if expected or gap > 1e-5:
        assert bool(hit[0, 0, 1]) == expected and bool(hit[0, 1, 0]) == expected
    assert not hit[0, 0, 0] and not hit[0, 1, 1]


def test_pairwise_hand_cases():
    # Side by side, touching along the long edge (centers 0.08 apart): collision.
    # 1 mm further apart: none. One inside the other (same pose): collision.
    pos = torch.tensor([[[0, 0], [0, 0.08]], [[0, 0], [0, 0.081]], [[0, 0], [0, 0]]], dtype=torch.float64)
    heading = torch.zeros(3, 2, dtype=torch.float64)
    hit = pairwise_box_overlap(pos, heading, L, W)[:, 0, 1].tolist()
    assert hit == [True, False, True]
    # Corner to corner at 45 degrees rotated: touching at a single point.
    d = math.hypot(0.08, 0.04) * 2  # diagonal of the box; centers placed along it
    a = math.atan2(0.04, 0.08)
    pos = torch.tensor([[[0, 0], [d * math.cos(a), d * math.sin(a)]]], dtype=torch.float64)
    assert bool(pairwise_box_overlap(pos, torch.zeros(1, 2, dtype=torch.float64), L, W)[0, 0, 1])


@settings(max_examples=400, deadline=None)
@given(
    pts=st.lists(st.tuples(coord, coord), min_size=2, max_size=6),
    psi=angle,
)
def test_polyline_box_matches_shapely(pts, psi):
    line = torch.tensor([[pts]], dtype=torch.float64)
    hit = polyline_box_overlap(line, torch.zeros(1, 1, 2, dtype=torch.float64),
                               torch.tensor([[psi]], dtype=torch.float64), L, W)
    box = _poly(0, 0, psi)
    geom = LineString(pts) if len({tuple(p) for p in pts}) > 1 else None
    if geom is None:
        return
    expected = box.intersects(geom)
    if expected or box.distance(geom) > 1e-5:
        assert bool(hit[0, 0]) == expected


def test_polyline_box_segment_inside_and_touching():
    zero = torch.zeros(1, 1, 2, dtype=torch.float64)
    psi = torch.zeros(1, 1, dtype=torch.float64)
    inside = torch.tensor([[[[-0.01, 0.0], [0.01, 0.0]]]], dtype=torch.float64)
    touching = torch.tensor([[[[-0.2, 0.04], [0.2, 0.04]]]], dtype=torch.float64)  # along the left edge
    missing = torch.tensor([[[[-0.2, 0.041], [0.2, 0.041]]]], dtype=torch.float64)
    assert polyline_box_overlap(inside, zero, psi, L, W).item()
    assert polyline_box_overlap(touching, zero, psi, L, W).item()
    assert not polyline_box_overlap(missing, zero, psi, L, W).item()


@settings(max_examples=200, deadline=None)
@given(
    pts=st.lists(st.tuples(coord, coord), min_size=1, max_size=5),
    line=st.lists(st.tuples(coord, coord), min_size=3, max_size=3),
    line2=st.lists(st.tuples(coord, coord), min_size=3, max_size=3),
)
def test_nearest_on_segments_matches_shapely(pts, line, line2):
    from shapely.geometry import Point

    from sigmarl.env.collision import nearest_on_segments, segment_table

    p = torch.tensor(pts, dtype=torch.float64)
    lines = torch.tensor([line, line2], dtype=torch.float64)
    dist, seg = nearest_on_segments(p, segment_table(lines))
    for k, ln in enumerate((line, line2)):
        if len({tuple(q) for q in ln}) < 2:
            continue
        shp = LineString(ln)
        for j, q in enumerate(pts):
            assert float(dist[k, j]) == pytest.approx(shp.distance(Point(q)), abs=1e-9)
            s = int(seg[k, j])
            piece = LineString(ln[s : s + 2]) if ln[s] != ln[s + 1] else Point(ln[s])
            assert piece.distance(Point(q)) == pytest.approx(shp.distance(Point(q)), abs=1e-9)
