"""The CPM Lab map, read from the CommonRoad XML that the installed `vmas` ships.

Two route sets: the 7 loops of the whole map (scenario "CPM") and the 24
routes of the central intersection (the training sub-map), derived from the
XML's `intersection` element and lanelet successors.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from sigmarl.errors import MapError
from sigmarl.maps.model import Lanelet, RoadMap
from sigmarl.maps.routes import build_route, corridor_members, infer_adjacency

if TYPE_CHECKING:
    from sigmarl.config import MapConfig

# The seven loops the paper drives on the whole map (lanelet sequences).
CPM_LOOPS: tuple[tuple[int, ...], ...] = (
    (4, 6, 8, 60, 58, 56, 54, 80, 82, 84, 86, 34, 32, 30, 28, 2),
    (1, 3, 23, 10, 12, 17, 43, 38, 36, 49, 29, 27),
    (64, 62, 75, 55, 53, 79, 81, 101, 88, 90, 95, 69),
    (40, 45, 97, 92, 94, 100, 83, 85, 33, 31, 48, 42),
    (5, 7, 59, 57, 74, 68, 66, 71, 19, 14, 16, 22),
    (41, 39, 20, 63, 61, 57, 55, 67, 65, 98, 37, 35, 31, 29),
    (3, 5, 9, 11, 72, 91, 93, 81, 83, 87, 89, 46, 13, 15),
)
CPM_LANE_WIDTH = 0.15


def cpm_xml_path() -> Path:
    """The CPM Lab XML inside the installed vmas package."""
    try:
        path = resources.files("vmas") / "scenarios_data" / "road_traffic" / "road_traffic_cpm_lab.xml"
    except ModuleNotFoundError as e:  # pragma: no cover - vmas is a hard dependency
        raise MapError("the CPM Lab map comes with the `vmas` package, which is not installed") from e
    return Path(str(path))


def _points(bound: ET.Element | None, where: str) -> np.ndarray:
    if bound is None:
        raise MapError(f"{where}: missing boundary")
    pts = []
    for p in bound.findall("point"):
        x, y = p.findtext("x"), p.findtext("y")
        try:
            pts.append((float(x), float(y)))  # type: ignore[arg-type]
        except (TypeError, ValueError) as e:
            raise MapError(f"{where}: point with bad coordinates x={x!r} y={y!r}") from e
    if len(pts) < 2:
        raise MapError(f"{where}: needs at least 2 points, has {len(pts)}")
    return np.asarray(pts, dtype=np.float64)


def _ref(el: ET.Element, where: str) -> int:
    try:
        return int(el.attrib["ref"])
    except (KeyError, ValueError) as e:
        raise MapError(f"{where}: <{el.tag}> without an integer 'ref'") from e


def parse_commonroad(path: Path) -> tuple[dict[int, Lanelet], ET.Element]:
    """Lanelets of a CommonRoad XML file, and its root (for the intersection element)."""
    try:
        root = ET.parse(path).getroot()
    except FileNotFoundError as e:
        raise MapError(f"map file not found: {path}") from e
    except ET.ParseError as e:
        raise MapError(f"{path}: not well-formed XML ({e})") from e
    lanelets: dict[int, Lanelet] = {}
    for el in root.findall("lanelet"):
        try:
            lid = int(el.attrib["id"])
        except (KeyError, ValueError) as e:
            raise MapError(f"{path}: <lanelet> without an integer 'id'") from e
        where = f"{path}: lanelet {lid}"
        left, right = _points(el.find("leftBound"), where + " leftBound"), _points(el.find("rightBound"), where + " rightBound")
        if len(left) != len(right):
            raise MapError(f"{where}: left and right boundaries have {len(left)} and {len(right)} points")
        la = Lanelet(
            lid,
            left,
            right,
            successors=[_ref(s, where) for s in el.findall("successor")],
            predecessors=[_ref(s, where) for s in el.findall("predecessor")],
        )
        for side in ("Left", "Right"):
            adj = el.find(f"adjacent{side}")
            if adj is not None:
                same = adj.attrib.get("drivingDir", "same") == "same"
                setattr(la, f"adj_{side.lower()}", _ref(adj, where))
                setattr(la, f"adj_{side.lower()}_same", same)
        lanelets[lid] = la
    if not lanelets:
        raise MapError(f"{path}: no <lanelet> elements")
    for la in lanelets.values():
        for other in [*la.successors, *la.predecessors]:
            if other not in lanelets:
                raise MapError(f"{path}: lanelet {la.id} refers to lanelet {other}, which does not exist")
    return lanelets, root


def intersection_routes(root: ET.Element, lanelets: dict[int, Lanelet], path: Path) -> list[list[int]]:
    """incoming lanelet + the turn's successor chain + the lanelet that leaves the intersection."""
    inter = root.find("intersection")
    if inter is None:
        raise MapError(f"{path}: no <intersection> element")
    routes = []
    for inc in inter.findall("incoming"):
        el = inc.find("incomingLanelet")
        if el is None:
            raise MapError(f"{path}: <incoming id={inc.attrib.get('id')}> has no <incomingLanelet>")
        start = _ref(el, f"{path}: incoming {inc.attrib.get('id')}")
        for turn in ("successorsRight", "successorsStraight", "successorsLeft"):
            chain = [_ref(s, f"{path}: incoming {start}") for s in inc.findall(turn)]
            if not chain:
                continue
            route = [start, *chain]
            after = lanelets[route[-1]].successors
            if len(after) != 1:
                raise MapError(f"{path}: lanelet {route[-1]} leaving the intersection has {len(after)} successors, expected 1")
            routes.append([*route, after[0]])
    return routes


def load_cpm(route_set: str = "loops", path: Path | None = None) -> RoadMap:
    """The whole CPM map with its loops ("loops") or the central intersection ("intersection")."""
    path = path or cpm_xml_path()
    lanelets, root = parse_commonroad(path)
    infer_adjacency(lanelets)
    if route_set == "loops":
        routes = [build_route(f"loop{i + 1}", ids, lanelets, loop=True) for i, ids in enumerate(CPM_LOOPS)]
        name = "cpm"
    elif route_set == "intersection":
        seqs = intersection_routes(root, lanelets, path)
        routes = [build_route("-".join(map(str, ids)), ids, lanelets) for ids in seqs]
        name = "cpm_intersection"
        # The sub-map holds only the lanelets its routes and their corridors use.
        keep = set()
        for ids in seqs:
            for lid in ids:
                keep.update((lid, *corridor_members(lanelets[lid], lanelets)))
        lanelets = {i: la for i, la in lanelets.items() if i in keep}
    else:
        raise MapError(f"unknown CPM route set {route_set!r}; choose 'loops' or 'intersection'")
    return RoadMap(name=name, lanelets=lanelets, routes=routes, lane_width=CPM_LANE_WIDTH, source=str(path))


def cpm_map(cfg: MapConfig) -> RoadMap:
    """The CPM Lab map of a MapConfig (kind cpm): its route set."""
    return load_cpm(cfg.route_set)
