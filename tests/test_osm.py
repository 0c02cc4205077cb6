"""OSM maps: hand-made files of both dialects, round trips, malformed input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sigmarl.compose import map_config
from sigmarl.errors import MapError
from sigmarl.maps import load_map
from sigmarl.maps.cpm import load_cpm
from sigmarl.maps.osm import load_osm, save_lanelet2_osm

DATA = Path(__file__).parent / "data"


def test_center_line_dialect_by_hand():
    m = load_osm(DATA / "centerline_ways.osm")
    assert sorted(m.lanelets) == [1, 2, 3]
    # lanelet 1: center (0.24, 0.24) -> (1.24, 0.24); boundaries 0.10 m to either side
    np.testing.assert_allclose(m.lanelets[1].center, [[0.24, 0.24], [1.24, 0.24]], atol=1e-9)
    np.testing.assert_allclose(m.lanelets[1].left, [[0.24, 0.34], [1.24, 0.34]], atol=1e-9)
    np.testing.assert_allclose(m.lanelets[1].right, [[0.24, 0.14], [1.24, 0.14]], atol=1e-9)
    # lanelet 3 runs from (1.24, 0.24) to (2.24, 1.24), direction (1, 1)/sqrt(2): its left
    # normal is (-1, 1)/sqrt(2), so its left boundary ends at (2.24 - 0.0707, 1.24 + 0.0707)
    h = 0.1 / np.sqrt(2)
    np.testing.assert_allclose(m.lanelets[3].left[-1], [2.24 - h, 1.24 + h], atol=1e-9)
    assert sorted(m.lanelets[1].successors) == [2, 3]
    assert sorted(r.lanelet_ids for r in m.routes) == [(1, 2), (1, 3)]
    assert m.routes[0].length == pytest.approx(2.0)


def test_lanelet2_dialect_by_hand():
    m = load_osm(DATA / "lanelet2.osm")
    assert sorted(m.lanelets) == [10, 11, 12]
    # way 202 was stored backwards: lanelet 11's right boundary runs +x at y = -0.2
    np.testing.assert_allclose(m.lanelets[11].right, [[0, -0.2], [1, -0.2]], atol=1e-12)
    assert m.lanelets[10].successors == [12]
    assert (m.lanelets[10].adj_right, m.lanelets[10].adj_right_same) == (11, True)
    assert sorted(r.lanelet_ids for r in m.routes) == [(10, 12), (11,)]
    # route 10-12: on lanelet 10 the corridor spans both lanes (0.40 m), on 12 one lane
    r = next(r for r in m.routes if r.lanelet_ids == (10, 12))
    assert r.left[0].tolist() == pytest.approx([0.0, 0.2]) and r.right[0].tolist() == pytest.approx([0.0, -0.2])


def test_explicit_routes_are_validated():
    m = load_osm(DATA / "lanelet2.osm", routes=[[10, 12]])
    assert [r.lanelet_ids for r in m.routes] == [(10, 12)]
    with pytest.raises(MapError, match="lanelet 11 is not connected to lanelet 12"):
        load_osm(DATA / "lanelet2.osm", routes=[[11, 12]])


@pytest.mark.parametrize("name", ["intersection", "on_ramp", "roundabout", "cpm"])
def test_round_trip_keeps_geometry_and_routes(tmp_path, name):
    original = load_cpm("loops") if name == "cpm" else load_map(map_config(name))
    back = load_osm(save_lanelet2_osm(original, tmp_path / f"{name}.osm"))
    assert sorted(back.lanelets) == sorted(original.lanelets)
    for lid, la in original.lanelets.items():
        np.testing.assert_allclose(back.lanelets[lid].left, la.left, atol=1e-6)
        np.testing.assert_allclose(back.lanelets[lid].right, la.right, atol=1e-6)
    assert [r.lanelet_ids for r in back.routes] == [r.lanelet_ids for r in original.routes]
    for a, b in zip(original.routes, back.routes, strict=True):
        np.testing.assert_allclose(b.center.numpy(), a.center.numpy(), atol=1e-6)
        np.testing.assert_allclose(b.left.numpy(), a.left.numpy(), atol=1e-6)
        np.testing.assert_allclose(b.right.numpy(), a.right.numpy(), atol=1e-6)


def _write(tmp_path, text: str) -> Path:
    p = tmp_path / "bad.osm"
    p.write_text(text)
    return p


def test_missing_file(tmp_path):
    with pytest.raises(MapError, match="not found"):
        load_osm(tmp_path / "nope.osm")


def test_truncated_file(tmp_path):
    text = (DATA / "lanelet2.osm").read_text()
    with pytest.raises(MapError, match="bad.osm: not well-formed"):
        load_osm(_write(tmp_path, text[: len(text) // 2]))


def test_way_with_unknown_node(tmp_path):
    text = (DATA / "centerline_ways.osm").read_text().replace('<nd ref="3"/>', '<nd ref="99"/>')
    with pytest.raises(MapError, match="way 101 refers to node '99'"):
        load_osm(_write(tmp_path, text))


def test_node_without_coordinates(tmp_path):
    text = (DATA / "centerline_ways.osm").read_text().replace('<node id="4" lat="0.00002" lon="0.00001"/>', '<node id="4"/>')
    with pytest.raises(MapError, match="node 4 has no coordinates"):
        load_osm(_write(tmp_path, text))


def test_relation_without_right_way(tmp_path):
    text = (DATA / "lanelet2.osm").read_text().replace('<member type="way" ref="204" role="right"/>', "")
    with pytest.raises(MapError, match="lanelet relation 12 needs a 'left' and a 'right'"):
        load_osm(_write(tmp_path, text))


def test_file_without_lanelets(tmp_path):
    with pytest.raises(MapError, match="no lanelets"):
        load_osm(_write(tmp_path, '<osm version="0.6"><node id="1" lat="0" lon="0"/></osm>'))


def test_cli_loads_an_osm_file(tmp_path, capsys):
    from sigmarl.cli import main

    assert main(["maps", "show", str(DATA / "lanelet2.osm"), "--out", str(tmp_path / "m.png")]) == 0
    assert (tmp_path / "m.png").stat().st_size > 1000
