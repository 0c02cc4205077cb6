"""Maps written as OSM in the two dialects `sigmarl.maps.osm` reads: Lanelet2 relations
(any map) and SigmaRL-style center-line ways (how the paper's maps are shipped)."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from sigmarl.maps.model import RoadMap

DEG_TO_M = 1e5  # lat/lon carry x/y at 1e-5 degree per metre
ADJACENT_TAG = "sigmarl:adjacent_"  # a relation's neighbour whose bounds are not shared


def save_lanelet2_osm(roadmap: RoadMap, path: str | Path) -> Path:
    """Write a map as Lanelet2 OSM: local_x/local_y at full precision, bounds shared where equal.

    Nodes at the same point (to 1e-9 m) and bounds with the same nodes (in
    either direction) are written once, as JOSM users draw them. lat/lon
    carry x/y at 1e-5 degree per metre.
    """
    path = Path(path)
    root = ET.Element("osm", version="0.6", generator="sigmarl")
    nodes: list[ET.Element] = []
    ways: list[ET.Element] = []
    node_ids: dict[tuple[float, float], int] = {}
    way_ids: dict[tuple[int, ...], int] = {}

    def node(p: np.ndarray) -> int:
        key = (round(float(p[0]), 9), round(float(p[1]), 9))
        if key not in node_ids:
            nid = node_ids[key] = len(node_ids) + 1
            x, y = float(p[0]), float(p[1])
            el = ET.Element("node", id=str(nid), lat=repr(x / DEG_TO_M), lon=repr(y / DEG_TO_M))
            nodes.append(el)
            ET.SubElement(el, "tag", k="local_x", v=repr(x))
            ET.SubElement(el, "tag", k="local_y", v=repr(y))
        return node_ids[key]

    def way(points: np.ndarray) -> int:
        refs = tuple(node(p) for p in points)
        for key in (refs, refs[::-1]):
            if key in way_ids:
                return way_ids[key]
        wid = way_ids[refs] = len(way_ids) + 1
        el = ET.Element("way", id=str(wid))
        ways.append(el)
        for r in refs:
            ET.SubElement(el, "nd", ref=str(r))
        ET.SubElement(el, "tag", k="type", v="line_thin")
        ET.SubElement(el, "tag", k="subtype", v="solid")
        return wid

    relations = []
    for la in roadmap.lanelets.values():
        rel = ET.Element("relation", id=str(la.id))
        ET.SubElement(rel, "member", type="way", ref=str(way(la.left)), role="left")
        ET.SubElement(rel, "member", type="way", ref=str(way(la.right)), role="right")
        for k, v in (("type", "lanelet"), ("subtype", "road"), ("location", "urban"), ("one_way", "yes")):
            ET.SubElement(rel, "tag", k=k, v=v)
        for side in ("left", "right"):
            other = getattr(la, f"adj_{side}")
            if other is not None:
                same = getattr(la, f"adj_{side}_same")
                ET.SubElement(rel, "tag", k=ADJACENT_TAG + side, v=str(other))
                ET.SubElement(rel, "tag", k=f"{ADJACENT_TAG}{side}_dir", v="same" if same else "opposite")
        relations.append(rel)
    root.extend([*nodes, *ways, *relations])  # OSM order: nodes, ways, relations
    tree = ET.ElementTree(root)
    ET.indent(tree)
    path.parent.mkdir(parents=True, exist_ok=True)
    tree.write(path, encoding="utf-8", xml_declaration=True)
    return path


def save_centerline_osm(centers: dict[int, np.ndarray], path: str | Path) -> Path:
    """Write center lines as SigmaRL-style OSM: one way tagged `lanes=<id>` per lanelet.

    Points equal to 1e-9 m become one node, so lanelets that meet share their end node
    (that is how the loader finds successors). lat/lon carry x/y at 1e-5 degree per metre;
    `load_osm` shifts the lowest node to 1.2 lane widths, as the dialect prescribes.
    """
    path = Path(path)
    root = ET.Element("osm", version="0.6", generator="sigmarl")
    nodes: list[ET.Element] = []
    node_ids: dict[tuple[float, float], int] = {}
    ways: list[ET.Element] = []
    for lid, points in centers.items():
        way = ET.Element("way", id=str(lid))
        for p in np.asarray(points, dtype=np.float64):
            key = (round(float(p[0]), 9), round(float(p[1]), 9))
            if key not in node_ids:
                node_ids[key] = len(node_ids) + 1
                nodes.append(ET.Element("node", id=str(node_ids[key]), lat=repr(float(p[0]) / DEG_TO_M),
                                        lon=repr(float(p[1]) / DEG_TO_M), version="1", visible="true"))
            ET.SubElement(way, "nd", ref=str(node_ids[key]))
        ET.SubElement(way, "tag", k="lanes", v=str(int(lid)))
        ways.append(way)
    root.extend([*nodes, *ways])
    tree = ET.ElementTree(root)
    ET.indent(tree)
    path.parent.mkdir(parents=True, exist_ok=True)
    tree.write(path, encoding="utf-8", xml_declaration=True)
    return path
