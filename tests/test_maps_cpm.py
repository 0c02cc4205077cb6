"""The CPM Lab map against its known facts (lanelets, neighbours, routes, lengths), with shapely as the geometry oracle."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.geometry import LineString, Point, Polygon

from sigmarl.errors import MapError
from sigmarl.maps.cpm import CPM_LOOPS, cpm_xml_path, load_cpm, parse_commonroad
from sigmarl.maps.model import RESAMPLE_STEP, Lanelet
from sigmarl.maps.routes import build_route

SPEC_INTERSECTION = [
    [11, 25, 13], [11, 26, 52, 37], [11, 72, 91], [12, 18, 14], [12, 17, 43, 38], [12, 73, 92],
    [39, 51, 37], [39, 50, 102, 91], [39, 20, 63], [40, 44, 38], [40, 45, 97, 92], [40, 21, 64],
    [89, 103, 91], [89, 104, 78, 63], [89, 46, 13], [90, 96, 92], [90, 95, 69, 64], [90, 47, 14],
    [65, 77, 63], [65, 76, 24, 13], [65, 98, 37], [66, 70, 64], [66, 71, 19, 14], [66, 99, 38],
]
SPEC_GROUPS = [
    [4, 3, 22], [6, 5, 23], [11, 12], [25, 18], [26, 17], [52, 43], [72, 73], [51, 44], [50, 45],
    [102, 97], [20, 21], [103, 96], [104, 95], [78, 69], [46, 47], [77, 70], [76, 71], [24, 19],
    [98, 99],
]


@pytest.fixture(scope="module")
def cpm():
    return load_cpm("loops")


@pytest.fixture(scope="module")
def cpm_inter():
    return load_cpm("intersection")


def corridor_groups(lanelets: dict[int, Lanelet]) -> list[list[int]]:
    """All same-direction lane groups with more than one lanelet, each listed left to right."""
    groups = []
    for la in lanelets.values():
        if la.adj_left is not None and la.adj_left_same:
            continue  # not the leftmost
        group = [la.id]
        cur = la
        while cur.adj_right is not None and cur.adj_right_same and cur.adj_right not in group:
            cur = lanelets[cur.adj_right]
            group.append(cur.id)
        if len(group) > 1:
            groups.append(group)
    return groups


def test_xml_comes_from_installed_vmas():
    path = cpm_xml_path()
    assert path.is_file() and "vmas" in str(path)


def test_lanelets_width_and_extent(cpm):
    assert sorted(cpm.lanelets) == list(range(1, 105))
    widths = np.concatenate([la.width for la in cpm.lanelets.values()])
    assert np.all(np.abs(widths - 0.15) <= 1e-3)
    xmin, ymin, xmax, ymax = cpm.bounds
    assert 0 <= xmin and xmax <= 4.5 and 0 <= ymin and ymax <= 4.0


def test_loops_equal_spec(cpm):
    assert [list(r.lanelet_ids) for r in cpm.routes] == [list(x) for x in CPM_LOOPS]
    assert all(r.is_loop for r in cpm.routes)
    assert cpm.routes[0].length == pytest.approx(14.2, abs=0.05)  # loop 1 is about 14.2 m long


def test_intersection_routes_equal_spec(cpm_inter):
    got = [list(r.lanelet_ids) for r in cpm_inter.routes]
    assert sorted(got) == sorted(SPEC_INTERSECTION)
    for r in cpm_inter.routes:
        assert not r.is_loop
        assert 2.4 - 0.02 <= r.length <= 3.3 + 0.05


def test_corridor_groups_contain_spec(cpm):
    groups = corridor_groups(cpm.lanelets)
    for g in SPEC_GROUPS:
        assert g in groups, g


def _arc_positions(line: LineString, points: np.ndarray) -> np.ndarray:
    return np.array([line.project(Point(p)) for p in points])


@pytest.mark.parametrize("route_set", ["loops", "intersection"])
def test_resampled_center_is_uniform_in_arc_length(route_set, cpm, cpm_inter):
    road = cpm if route_set == "loops" else cpm_inter
    for r in road.routes:
        ids = r.lanelet_ids
        raw = np.concatenate([road.lanelets[i].center for i in ids])
        line = LineString(raw)
        pts = r.center.numpy()[: r.n_points]
        s = _arc_positions(line, pts)
        gaps = np.diff(s)
        # shapely's projection is the independent measure of arc length along the raw line.
        assert np.allclose(gaps[:-1], RESAMPLE_STEP, rtol=1e-6), r.name
        # Straight-line chords can only be shorter than the arc (by <1% on the tightest curves).
        chords = np.linalg.norm(np.diff(pts, axis=0), axis=1)[:-1]  # last gap: the remainder
        assert np.all(chords <= RESAMPLE_STEP + 1e-9) and np.all(chords > 0.99 * RESAMPLE_STEP)
        # The samples cover the whole route: length preserved within 1 mm.
        covered = s[-1] + (0 if not r.is_loop else line.length - s[-1])
        assert abs(covered - line.length) < 1e-3, r.name
        assert abs(r.length - line.length) < 1e-3


def test_non_loop_extension_is_straight(cpm_inter):
    r = cpm_inter.routes[0]
    ext = r.center.numpy()[r.n_points - 1 :]
    d = np.diff(ext, axis=0)
    cross = d[1:, 0] * d[:-1, 1] - d[1:, 1] * d[:-1, 0]
    assert np.allclose(cross, 0, atol=1e-9) and len(ext) * RESAMPLE_STEP >= 0.48


def test_two_lane_corridor_is_0_30_wide(cpm_inter):
    # Route 11-25-13 starts on lanelet 11, whose same-direction neighbour is 12: one 0.30 m corridor.
    r = next(r for r in cpm_inter.routes if r.lanelet_ids == (11, 25, 13))
    left, right = LineString(r.left.numpy()), LineString(r.right.numpy())
    p = r.center.numpy()[2]
    assert left.distance(Point(p)) + right.distance(Point(p)) == pytest.approx(0.30, abs=2e-3)


@settings(max_examples=60, deadline=None)
@given(route=st.integers(0, 23), frac=st.floats(0.02, 0.95), offset=st.floats(-0.06, 0.06))
def test_corridor_contains_center_line_points(cpm_inter, route, frac, offset):
    """Points near the center line lie in the corridor polygon (left + reversed right)."""
    r = cpm_inter.routes[route]
    poly = Polygon(np.concatenate([r.left.numpy(), r.right.numpy()[::-1]]))
    assert poly.is_valid
    i = 1 + int(frac * (r.n_points - 3))  # index 0 lies on the entry edge
    a, b = r.center.numpy()[i], r.center.numpy()[i + 1]
    t = (b - a) / np.linalg.norm(b - a)
    p = a + offset * np.array([-t[1], t[0]])
    inside = poly.contains(Point(p))
    # Own lane is 0.15 m wide: |offset| < 0.06 keeps a point inside the corridor.
    assert inside


def test_missing_file(tmp_path):
    with pytest.raises(MapError, match="not found"):
        parse_commonroad(tmp_path / "nope.xml")


def test_truncated_file(tmp_path):
    text = cpm_xml_path().read_text()
    bad = tmp_path / "cut.xml"
    bad.write_text(text[: len(text) // 2])
    with pytest.raises(MapError, match="cut.xml.*not well-formed"):
        parse_commonroad(bad)


def test_bad_point_names_lanelet(tmp_path):
    text = cpm_xml_path().read_text().replace("<x>2.250000000</x>", "<x>abc</x>", 1)
    bad = tmp_path / "bad.xml"
    bad.write_text(text)
    with pytest.raises(MapError, match="lanelet 1 leftBound"):
        parse_commonroad(bad)


def test_disconnected_route_names_the_link(cpm):
    with pytest.raises(MapError, match=r"route broken: lanelet 4 is not connected to lanelet 8"):
        build_route("broken", [4, 8], cpm.lanelets)
