"""Maps drawn in JOSM: OSM files in two dialects, and a Lanelet2 writer.

- Center-line ways (the SigmaRL style): each way tagged `lanes=<id>` is one lanelet's center
  line; boundaries are offset by half a lane width along the left normal.
- Standard Lanelet2: relations `type=lanelet` with `left`/`right` member ways.
Connectivity comes from shared end/start points, adjacency from shared boundaries. Routes
come from the caller, from `type=sigmarl_route` relations (written by `save_lanelet2_osm`),
or are enumerated from the lanelet graph.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from sigmarl.errors import MapError
from sigmarl.maps.model import Lanelet, RoadMap
from sigmarl.maps.routes import build_route, enumerate_routes, infer_adjacency

DEG_TO_M = 1e5  # 1e-5 degree = 1 m, no cosine correction (the SigmaRL convention)
_TOL = 1e-6


def _tags(el: ET.Element) -> dict[str, str]:
    return {t.attrib.get("k", ""): t.attrib.get("v", "") for t in el.findall("tag")}


def _parse(path: Path) -> ET.Element:
    try:
        return ET.parse(path).getroot()
    except FileNotFoundError as e:
        raise MapError(f"map file not found: {path}") from e
    except ET.ParseError as e:
        raise MapError(f"{path}: not well-formed XML ({e})") from e


def _nodes(root: ET.Element, path: Path, lane_width: float) -> dict[str, np.ndarray]:
    """Node id -> local (x, y): local_x/local_y tags when present, else scaled lat/lon."""
    raw: dict[str, tuple[dict[str, str], str | None, str | None]] = {}
    for n in root.findall("node"):
        nid = n.attrib.get("id")
        if nid is None:
            raise MapError(f"{path}: <node> without an id")
        raw[nid] = (_tags(n), n.attrib.get("lat"), n.attrib.get("lon"))
    lats, lons = [], []
    for nid, (_, lat, lon) in raw.items():
        if lat is not None and lon is not None:
            try:
                lats.append(float(lat))
                lons.append(float(lon))
            except ValueError as e:
                raise MapError(f"{path}: node {nid} has bad lat/lon {lat!r}/{lon!r}") from e
    lat0, lon0 = (min(lats), min(lons)) if lats else (0.0, 0.0)
    out = {}
    for nid, (tags, lat, lon) in raw.items():
        try:
            if "local_x" in tags and "local_y" in tags:
                out[nid] = np.array([float(tags["local_x"]), float(tags["local_y"])])
            elif lat is not None and lon is not None:
                out[nid] = np.array([(float(lat) - lat0) * DEG_TO_M + 1.2 * lane_width,
                                     (float(lon) - lon0) * DEG_TO_M + 1.2 * lane_width])
            else:
                raise MapError(f"{path}: node {nid} has no coordinates (lat/lon or local_x/local_y)")
        except ValueError as e:
            raise MapError(f"{path}: node {nid} has bad coordinates") from e
    return out


def _ways(root: ET.Element, nodes: dict[str, np.ndarray], path: Path) -> dict[str, tuple[list[str], dict]]:
    ways = {}
    for w in root.findall("way"):
        wid = w.attrib.get("id")
        refs = [nd.attrib.get("ref", "") for nd in w.findall("nd")]
        for r in refs:
            if r not in nodes:
                raise MapError(f"{path}: way {wid} refers to node {r!r}, which does not exist")
        ways[wid] = (refs, _tags(w))
    return ways


def _left_normals(points: np.ndarray) -> np.ndarray:
    """Unit left normals at each vertex: the mean of the adjacent segments' normals."""
    seg = np.diff(points, axis=0)
    seg = seg / np.linalg.norm(seg, axis=1, keepdims=True)
    tangent = np.concatenate([seg[:1], seg[:-1] + seg[1:], seg[-1:]])
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    return np.stack([-tangent[:, 1], tangent[:, 0]], axis=1)


def _center_line_dialect(ways, nodes, path: Path, lane_width: float) -> tuple[dict[int, Lanelet], dict]:
    lanelets: dict[int, Lanelet] = {}
    ends: dict[int, tuple[str, str]] = {}
    for wid, (refs, tags) in ways.items():
        if "lanes" not in tags:
            continue
        try:
            lid = int(tags["lanes"])
        except ValueError as e:
            raise MapError(f"{path}: way {wid} has lanes={tags['lanes']!r}, not an integer id") from e
        if len(refs) < 2:
            raise MapError(f"{path}: way {wid} (lanelet {lid}) needs at least 2 nodes")
        if lid in lanelets:
            raise MapError(f"{path}: lanelet id {lid} is used by two ways")
        center = np.stack([nodes[r] for r in refs])
        offset = _left_normals(center) * lane_width / 2
        lanelets[lid] = Lanelet(lid, center + offset, center - offset)
        ends[lid] = (refs[0], refs[-1])
    for a, (_, a_end) in ends.items():
        for b, (b_start, _) in ends.items():
            if a != b and a_end == b_start:
                lanelets[a].successors.append(b)
                lanelets[b].predecessors.append(a)
    return lanelets, {}


def _orient(left: np.ndarray, right: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Both boundaries in one direction: the one in which the `left` member lies on the left
    (the members' roles are authoritative; their stored directions are not)."""
    if np.linalg.norm(left[0] - right[-1]) + np.linalg.norm(left[-1] - right[0]) < np.linalg.norm(
        left[0] - right[0]
    ) + np.linalg.norm(left[-1] - right[-1]):
        left = left[::-1]
    direction = (right[-1] - right[0]) + (left[-1] - left[0])
    to_left = left.mean(0) - right.mean(0)
    if direction[0] * to_left[1] - direction[1] * to_left[0] < 0:
        left, right = left[::-1], right[::-1]
    return left, right


def _same_count(a: np.ndarray, n: int) -> np.ndarray:
    """A polyline resampled to n points at equal fractions of its length (unchanged if it has n)."""
    if len(a) == n:
        return a
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(a, axis=0), axis=1))])
    t = np.linspace(0.0, s[-1], n)
    return np.stack([np.interp(t, s, a[:, 0]), np.interp(t, s, a[:, 1])], axis=1)


def _lanelet2_dialect(root, ways, nodes, path: Path) -> tuple[dict[int, Lanelet], dict]:
    lanelets: dict[int, Lanelet] = {}
    routes: dict[str, tuple[list[int], bool]] = {}
    way_of: dict[int, dict[str, str]] = {}
    explicit: dict[int, dict[str, str]] = {}
    for rel in root.findall("relation"):
        tags = _tags(rel)
        rid = rel.attrib.get("id", "?")
        if tags.get("type") == "sigmarl_route":
            members = [m.attrib.get("ref", "") for m in rel.findall("member")]
            routes[tags.get("name", rid)] = ([int(m) for m in members], tags.get("loop") == "yes")
            continue
        if tags.get("type") != "lanelet":
            continue
        bounds, bound_ways = {}, {}
        for m in rel.findall("member"):
            role = m.attrib.get("role")
            if role in ("left", "right"):
                ref = m.attrib.get("ref", "")
                if ref not in ways:
                    raise MapError(f"{path}: lanelet relation {rid} refers to way {ref!r}, which does not exist")
                bounds[role] = np.stack([nodes[r] for r in ways[ref][0]])
                bound_ways[role] = ref
        if set(bounds) != {"left", "right"}:
            raise MapError(f"{path}: lanelet relation {rid} needs a 'left' and a 'right' member way")
        if min(len(b) for b in bounds.values()) < 2:
            raise MapError(f"{path}: lanelet relation {rid} has a boundary with fewer than 2 nodes")
        try:
            lid = int(rid)
        except ValueError as e:
            raise MapError(f"{path}: lanelet relation id {rid!r} is not an integer") from e
        left, right = _orient(bounds["left"], bounds["right"])
        n = max(len(left), len(right))
        lanelets[lid] = Lanelet(lid, _same_count(left, n), _same_count(right, n))
        way_of[lid] = bound_ways
        explicit[lid] = tags
    if any("sigmarl_successors" in t for t in explicit.values()):
        _explicit_graph(lanelets, explicit, path)
    else:
        _derived_graph(lanelets, way_of)
    return lanelets, routes


def _explicit_graph(lanelets: dict[int, Lanelet], tags: dict[int, dict], path: Path) -> None:
    """Successors and neighbours as `save_lanelet2_osm` recorded them (exact round trip)."""

    def ids(text: str) -> list[int]:
        return [int(x) for x in text.split(",") if x.strip()]

    for lid, t in tags.items():
        la = lanelets[lid]
        try:
            la.successors = ids(t.get("sigmarl_successors", ""))
            la.predecessors = ids(t.get("sigmarl_predecessors", ""))
            for side in ("left", "right"):
                if f"sigmarl_adj_{side}" in t:
                    setattr(la, f"adj_{side}", int(t[f"sigmarl_adj_{side}"]))
                    setattr(la, f"adj_{side}_same", t.get(f"sigmarl_adj_{side}_dir", "same") == "same")
        except ValueError as e:
            raise MapError(f"{path}: lanelet relation {lid} has a malformed sigmarl_* tag ({e})") from e


def _derived_graph(lanelets: dict[int, Lanelet], way_of: dict[int, dict[str, str]]) -> None:
    """Lanelet2's own conventions: a center line ending where another starts is a successor;
    lanelets sharing a boundary way are neighbours (same direction when one's left way is the
    other's right way, opposite when both use it as their left)."""
    for a in lanelets.values():
        for b in lanelets.values():
            if a.id != b.id and np.linalg.norm(a.center[-1] - b.center[0]) < _TOL:
                a.successors.append(b.id)
                b.predecessors.append(a.id)
    for a in lanelets.values():
        for b in lanelets.values():
            if a.id == b.id:
                continue
            if way_of[a.id]["left"] == way_of[b.id]["right"]:
                a.adj_left, a.adj_left_same = b.id, True
                b.adj_right, b.adj_right_same = a.id, True
            elif way_of[a.id]["left"] == way_of[b.id]["left"]:
                a.adj_left, a.adj_left_same = b.id, False


def load_osm(path: str | Path, lane_width: float = 0.20, routes=None, name: str | None = None) -> RoadMap:
    """A RoadMap from an OSM file of either dialect (detected from its content)."""
    path = Path(path)
    root = _parse(path)
    nodes = _nodes(root, path, lane_width)
    ways = _ways(root, nodes, path)
    is_lanelet2 = any(_tags(r).get("type") == "lanelet" for r in root.findall("relation"))
    if is_lanelet2:
        lanelets, stored = _lanelet2_dialect(root, ways, nodes, path)
    else:
        lanelets, stored = _center_line_dialect(ways, nodes, path, lane_width)
    if not lanelets:
        raise MapError(f"{path}: no lanelets (no `type=lanelet` relations and no ways tagged `lanes=<id>`)")
    infer_adjacency(lanelets)
    widths = np.concatenate([la.width for la in lanelets.values()])
    built = []
    if routes:
        for i, ids in enumerate(routes):
            ids = [int(x) for x in ids]
            loop = ids[0] in lanelets.get(ids[-1], Lanelet(-1, np.zeros((2, 2)), np.zeros((2, 2)))).successors
            built.append(build_route(f"route{i + 1}", ids, lanelets, loop=loop))
    elif stored:
        built = [build_route(n, ids, lanelets, loop=loop) for n, (ids, loop) in stored.items()]
    else:
        built = [build_route("-".join(map(str, ids)), ids, lanelets) for ids in enumerate_routes(lanelets)]
    if not built:
        raise MapError(f"{path}: no routes (the lanelet graph has no entry; give map.routes=[[ids...]])")
    return RoadMap(name=name or path.stem, lanelets=lanelets, routes=built,
                   lane_width=float(np.median(widths)), source=str(path))


def save_lanelet2_osm(road_map: RoadMap, path: str | Path) -> Path:
    """Write a map as standard Lanelet2 OSM (local_x/local_y at full precision) plus its routes."""
    path = Path(path)
    root = ET.Element("osm", version="0.6", generator="sigmarl")
    next_id = [0]

    def new_id() -> str:
        next_id[0] -= 1  # negative ids: new objects, as JOSM writes them
        return str(next_id[0])

    def tag(el: ET.Element, k: str, v: str) -> None:
        ET.SubElement(el, "tag", k=k, v=v)

    def way(points: np.ndarray, kind: str) -> str:
        refs = []
        for x, y in points:
            nid = new_id()
            n = ET.SubElement(root, "node", id=nid, lat=repr(float(x) / DEG_TO_M), lon=repr(float(y) / DEG_TO_M))
            tag(n, "local_x", repr(float(x)))
            tag(n, "local_y", repr(float(y)))
            refs.append(nid)
        wid = new_id()
        w = ET.SubElement(root, "way", id=wid)
        for r in refs:
            ET.SubElement(w, "nd", ref=r)
        tag(w, "type", kind)
        return wid

    relations = []
    for la in road_map.lanelets.values():
        left, right = way(la.left, "line_thin"), way(la.right, "line_thin")
        rel = ET.Element("relation", id=str(la.id))
        ET.SubElement(rel, "member", type="way", ref=left, role="left")
        ET.SubElement(rel, "member", type="way", ref=right, role="right")
        tag(rel, "type", "lanelet")
        tag(rel, "subtype", "road")
        # The graph as it is, so that a round trip needs no inference (Lanelet2 tools
        # ignore tags they do not know).
        tag(rel, "sigmarl_successors", ",".join(map(str, la.successors)))
        tag(rel, "sigmarl_predecessors", ",".join(map(str, la.predecessors)))
        for side in ("left", "right"):
            other = getattr(la, f"adj_{side}")
            if other is not None:
                tag(rel, f"sigmarl_adj_{side}", str(other))
                tag(rel, f"sigmarl_adj_{side}_dir", "same" if getattr(la, f"adj_{side}_same") else "opposite")
        relations.append(rel)
    for r in road_map.routes:
        rel = ET.Element("relation", id=new_id())
        for lid in r.lanelet_ids:
            ET.SubElement(rel, "member", type="relation", ref=str(lid), role="")
        tag(rel, "type", "sigmarl_route")
        tag(rel, "name", r.name)
        tag(rel, "loop", "yes" if r.is_loop else "no")
        relations.append(rel)
    root.extend(relations)
    ET.indent(root)
    path.parent.mkdir(parents=True, exist_ok=True)
    ET.ElementTree(root).write(path, encoding="utf-8", xml_declaration=True)
    return path
