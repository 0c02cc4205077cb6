"""Maps drawn by users in JOSM: two OSM dialects, detected automatically.

* Center-line ways (SigmaRL style): every `way` tagged `lanes=<int>` is one
  lanelet's center line, its `nd` refs in driving order; the integer is the
  lanelet id. Boundaries are offsets of ±w/2 along the per-vertex left normal
  (the normalised mean of the adjacent segments' normals; at a node where
  ways join, the mean over every segment that touches the node, so joined
  lanelets share their boundary end points). A way whose last node is
  another way's first node is that way's predecessor. Same-direction lanes
  drawn side by side are found from their geometry (`sigmarl.maps.multilane`).
* Standard Lanelet2: every `relation` tagged `type=lanelet` with `left` and
  `right` member ways. The bounds may be stored in either direction; they are
  oriented so that `left` lies left of the driving direction. A bound with
  fewer points is resampled at the other's arc-length fractions. Successors
  come from center lines whose end and start meet (1e-6 m); neighbours from
  shared bound ways or coinciding bounds, or from the optional relation tags
  `sigmarl:adjacent_left|right=<id>` with `sigmarl:adjacent_left|right_dir=same|opposite`
  (written by `osm_write.save_lanelet2_osm` for neighbours whose bounds are not shared).

Coordinates: `local_x`/`local_y` node tags when every node used has them,
else x = (lat - min lat)·1e5 + 1.2·w, y = (lon - min lon)·1e5 + 1.2·w over
the nodes used (1e-5 degree = 1 m, lat -> x, lon -> y).

Routes: lists of lanelet ids (a list whose last id repeats its first is a
loop), or every entry to every reachable exit when none are given.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sigmarl.errors import MapError
from sigmarl.maps.model import Lanelet, RoadMap, Route
from sigmarl.maps.multilane import find_side_by_side
from sigmarl.maps.osm_write import ADJACENT_TAG, DEG_TO_M
from sigmarl.maps.routes import build_route, enumerate_routes

_TOL = 1e-6  # points closer than this coincide


@dataclass
class _Osm:
    path: Path
    nodes: dict[int, ET.Element] = field(default_factory=dict)
    ways: dict[int, tuple[list[int], dict[str, str]]] = field(default_factory=dict)
    relations: dict[int, tuple[list[tuple[str, str, str]], dict[str, str]]] = field(default_factory=dict)


def _tags(el: ET.Element) -> dict[str, str]:
    return {t.get("k", ""): t.get("v", "") for t in el.findall("tag")}


def _int(value: str | None, what: str) -> int:
    try:
        return int(value)  # type: ignore[arg-type]
    except (TypeError, ValueError) as e:
        raise MapError(f"{what}: expected an integer, got {value!r}") from e


def _read(path: Path) -> _Osm:
    try:
        root = ET.parse(path).getroot()
    except FileNotFoundError as e:
        raise MapError(f"map file not found: {path}") from e
    except (IsADirectoryError, PermissionError) as e:
        raise MapError(f"{path}: cannot read the map file ({e.strerror})") from e
    except ET.ParseError as e:
        raise MapError(f"{path}: not well-formed XML ({e}); is the file truncated?") from e
    if root.tag != "osm":
        raise MapError(f"{path}: root element is <{root.tag}>, expected <osm>")
    osm = _Osm(path)
    for el in root.findall("node"):
        osm.nodes[_unique(el, osm.nodes, path)] = el
    for el in root.findall("way"):
        wid = _unique(el, osm.ways, path)
        refs = [_int(nd.get("ref"), f"{path}: way {wid} <nd> ref") for nd in el.findall("nd")]
        osm.ways[wid] = (refs, _tags(el))
    for el in root.findall("relation"):
        rid = _unique(el, osm.relations, path)
        members = [(m.get("type", ""), m.get("ref", ""), m.get("role", "")) for m in el.findall("member")]
        osm.relations[rid] = (members, _tags(el))
    return osm


def _unique(el: ET.Element, seen: dict[int, Any], path: Path) -> int:
    """The element's id, if no element of its kind had it before (else the last would silently win)."""
    eid = _int(el.get("id"), f"{path}: <{el.tag}> id")
    if eid in seen:
        raise MapError(f"{path}: {el.tag} id {eid} is given twice; each {el.tag} needs its own id")
    return eid


# lat/lon in degrees; local coordinates in m, within 10,000 km of their origin
_LIMITS = {"lat": 90.0, "lon": 180.0, "local_x": 1e7, "local_y": 1e7}


def _float(node: ET.Element, key: str, tags: dict[str, str], where: str) -> float:
    raw = tags[key] if key in tags else node.get(key)
    try:
        value = float(raw)  # type: ignore[arg-type]
    except (TypeError, ValueError) as e:
        raise MapError(f"{where}: {key}={raw!r} is not a number") from e
    if not np.isfinite(value):
        raise MapError(f"{where}: {key}={raw!r} is not finite")
    if abs(value) > _LIMITS[key]:  # finite, but its differences to the other nodes would not be
        raise MapError(f"{where}: {key}={raw!r} is outside [-{_LIMITS[key]:g}, {_LIMITS[key]:g}]")
    return value


def _coordinates(osm: _Osm, used: set[int], width: float) -> dict[int, np.ndarray]:
    """Local (x, y) of every used node: local_x/local_y tags if all have them, else lat/lon."""
    tags = {nid: _tags(osm.nodes[nid]) for nid in used}
    where = {nid: f"{osm.path}: node {nid}" for nid in used}
    if all("local_x" in t and "local_y" in t for t in tags.values()):
        return {
            nid: np.array([_float(osm.nodes[nid], "local_x", t, where[nid]), _float(osm.nodes[nid], "local_y", t, where[nid])])
            for nid, t in tags.items()
        }
    latlon = {}
    for nid in sorted(used):
        node = osm.nodes[nid]
        if node.get("lat") is None or node.get("lon") is None:
            raise MapError(f"{where[nid]} has no coordinates (needs lat/lon or local_x/local_y)")
        latlon[nid] = np.array([_float(node, "lat", {}, where[nid]), _float(node, "lon", {}, where[nid])])
    origin = np.min(np.stack(list(latlon.values())), axis=0)
    return {nid: (ll - origin) * DEG_TO_M + 1.2 * width for nid, ll in latlon.items()}


def _way_nodes(osm: _Osm, wid: int, owner: str) -> list[int]:
    if wid not in osm.ways:
        raise MapError(f"{osm.path}: {owner} refers to way {wid}, which does not exist")
    refs = osm.ways[wid][0]
    for nid in refs:
        if nid not in osm.nodes:
            raise MapError(f"{osm.path}: way {wid} refers to node {nid}, which does not exist")
    if len(refs) < 2:
        raise MapError(f"{osm.path}: way {wid} needs at least 2 nodes, has {len(refs)}")
    return refs


def _left_normals(points: np.ndarray) -> np.ndarray:
    """Unit left normal of each segment."""
    d = np.diff(points, axis=0)
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    return np.stack([-d[:, 1], d[:, 0]], axis=-1)


def _unit_or(v: np.ndarray, fallback: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v)
    return v / n if n > 1e-9 else fallback


def _centerline_lanelets(osm: _Osm, width: float) -> dict[int, Lanelet]:
    """Dialect (a): one lanelet per way tagged lanes=<id>."""
    owner: dict[int, int] = {}  # lanelet id -> way id
    refs: dict[int, list[int]] = {}
    for wid, (_, tags) in osm.ways.items():
        if "lanes" not in tags:
            continue
        lid = _int(tags["lanes"], f"{osm.path}: way {wid} tag lanes")
        if lid in owner:
            raise MapError(f"{osm.path}: ways {owner[lid]} and {wid} both have lanes={lid}; lanelet ids must be unique")
        owner[lid] = wid
        refs[lid] = _way_nodes(osm, wid, f"way {wid}")
    xy = _coordinates(osm, {n for r in refs.values() for n in r}, width)
    centers, segs = {}, {}
    for lid, r in refs.items():
        # Drop repeated nodes: a zero-length segment has no direction.
        keep = [r[0]] + [b for a, b in zip(r[:-1], r[1:], strict=True) if np.linalg.norm(xy[b] - xy[a]) > _TOL]
        if len(keep) < 2:
            raise MapError(f"{osm.path}: way {owner[lid]} (lanelet {lid}) has no length")
        refs[lid] = keep
        centers[lid] = np.stack([xy[n] for n in keep])
        segs[lid] = _left_normals(centers[lid])
    # Junction normals: the mean over every way segment that touches an end node.
    touching: dict[int, list[np.ndarray]] = {}
    for lid, r in refs.items():
        touching.setdefault(r[0], []).append(segs[lid][0])
        touching.setdefault(r[-1], []).append(segs[lid][-1])
    lanelets = {}
    for lid, r in refs.items():
        seg = segs[lid]
        normals = np.concatenate([seg[:1], seg[:-1] + seg[1:], seg[-1:]])
        normals[0] = np.sum(touching[r[0]], axis=0)
        normals[-1] = np.sum(touching[r[-1]], axis=0)
        fallback = np.concatenate([seg[:1], seg])
        normals = np.stack([_unit_or(v, f) for v, f in zip(normals, fallback, strict=True)])
        c = centers[lid]
        lanelets[lid] = Lanelet(lid, c + 0.5 * width * normals, c - 0.5 * width * normals)
    first: dict[int, list[int]] = {}
    for lid, r in refs.items():
        first.setdefault(r[0], []).append(lid)
    for lid, r in refs.items():
        for nxt in sorted(first.get(r[-1], [])):
            if nxt != lid:
                lanelets[lid].successors.append(nxt)
                lanelets[nxt].predecessors.append(lid)
    return lanelets


def _resample_like(points: np.ndarray, fractions: np.ndarray) -> np.ndarray:
    """Points at the given fractions of a polyline's arc length."""
    cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=-1))])
    s = fractions * cum[-1]
    return np.stack([np.interp(s, cum, points[:, 0]), np.interp(s, cum, points[:, 1])], axis=-1)


def _fractions(points: np.ndarray) -> np.ndarray:
    cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=-1))])
    return cum / cum[-1] if cum[-1] > 0 else np.linspace(0.0, 1.0, len(points))


def _orient(left: np.ndarray, right: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool, bool]:
    """Both bounds in driving order, with the same number of points; and whether each was reversed."""
    rev_r = (np.linalg.norm(left[0] - right[-1]) + np.linalg.norm(left[-1] - right[0])) < (
        np.linalg.norm(left[0] - right[0]) + np.linalg.norm(left[-1] - right[-1])
    )
    if rev_r:
        right = right[::-1]
    if len(left) > len(right):
        right = _resample_like(right, _fractions(left))
    elif len(right) > len(left):
        left = _resample_like(left, _fractions(right))
    center = 0.5 * (left + right)
    tangent = np.gradient(center, axis=0)
    across = left - right
    # The left bound must lie left of the driving direction.
    if np.sum(tangent[:, 0] * across[:, 1] - tangent[:, 1] * across[:, 0]) < 0:
        return left[::-1].copy(), right[::-1].copy(), True, not rev_r
    return left, right, False, bool(rev_r)


def _lanelet2_lanelets(osm: _Osm, width: float) -> tuple[dict[int, Lanelet], dict[int, tuple]]:
    """Dialect (b): one lanelet per relation type=lanelet; also each one's bound ways and tags."""
    bounds: dict[int, tuple[list[int], list[int], int, int, dict[str, str]]] = {}
    for rid, (members, tags) in osm.relations.items():
        if tags.get("type") != "lanelet":
            continue
        where = f"relation {rid} (lanelet)"
        if not members:
            raise MapError(f"{osm.path}: {where} has no member ways")
        found = {}
        for mtype, ref, role in members:
            if role in ("left", "right"):
                if mtype != "way":
                    raise MapError(f"{osm.path}: {where} member {role} is a {mtype or '?'}, expected a way")
                if role in found:
                    raise MapError(f"{osm.path}: {where} has more than one {role} member")
                found[role] = _int(ref, f"{osm.path}: {where} member {role} ref")
        for role in ("left", "right"):
            if role not in found:
                raise MapError(f"{osm.path}: {where} has no {role} member way")
        left_nodes = _way_nodes(osm, found["left"], where)
        right_nodes = _way_nodes(osm, found["right"], where)
        bounds[rid] = (left_nodes, right_nodes, found["left"], found["right"], tags)
    xy = _coordinates(osm, {n for b in bounds.values() for n in (*b[0], *b[1])}, width)
    lanelets, info = {}, {}
    for rid, (ln, rn, lw, rw, tags) in bounds.items():
        left, right, rev_l, rev_r = _orient(np.stack([xy[n] for n in ln]), np.stack([xy[n] for n in rn]))
        lanelets[rid] = Lanelet(rid, left, right)
        info[rid] = (lw, rev_l, rw, rev_r, tags)
    _link_by_points(lanelets)
    _adjacency(lanelets, info, osm.path)
    return lanelets, info


def _link_by_points(lanelets: dict[int, Lanelet]) -> None:
    """b follows a when a's center line ends where b's starts."""
    ids = sorted(lanelets)
    ends = np.stack([lanelets[i].center[-1] for i in ids])
    starts = np.stack([lanelets[i].center[0] for i in ids])
    close = np.linalg.norm(ends[:, None] - starts[None], axis=-1) < _TOL
    for a, b in zip(*np.nonzero(close), strict=True):
        if a != b:
            lanelets[ids[a]].successors.append(ids[b])
            lanelets[ids[b]].predecessors.append(ids[a])


def _same(p: np.ndarray, q: np.ndarray) -> bool:
    return p.shape == q.shape and float(np.abs(p - q).max()) < _TOL


def _adjacency(lanelets: dict[int, Lanelet], info: dict[int, tuple], path: Path) -> None:
    """Neighbours from shared bound ways or coinciding bounds; explicit tags override."""
    for a, la in lanelets.items():
        lw, rev_l, rw, rev_r, _ = info[a]
        for b, lb in lanelets.items():
            if a == b:
                continue
            blw, brev_l, brw, brev_r, _ = info[b]
            if la.adj_left is None:
                if (lw == brw and rev_l == brev_r) or _same(la.left, lb.right):
                    la.adj_left, la.adj_left_same = b, True
                elif (lw == blw and rev_l != brev_l) or _same(la.left, lb.left[::-1]):
                    la.adj_left, la.adj_left_same = b, False
            if la.adj_right is None:
                if (rw == blw and rev_r == brev_l) or _same(la.right, lb.left):
                    la.adj_right, la.adj_right_same = b, True
                elif (rw == brw and rev_r != brev_r) or _same(la.right, lb.right[::-1]):
                    la.adj_right, la.adj_right_same = b, False
    for a, la in lanelets.items():
        tags = info[a][4]
        for side in ("left", "right"):
            if ADJACENT_TAG + side not in tags:
                continue
            where = f"{path}: relation {a} tag {ADJACENT_TAG}{side}"
            other = _int(tags[ADJACENT_TAG + side], where)
            if other not in lanelets:
                raise MapError(f"{where}: lanelet {other} does not exist")
            direction = tags.get(f"{ADJACENT_TAG}{side}_dir", "same")
            if direction not in ("same", "opposite"):
                raise MapError(f"{where}_dir: expected same or opposite, got {direction!r}")
            setattr(la, f"adj_{side}", other)
            setattr(la, f"adj_{side}_same", direction == "same")


def _routes(path: Path, lanelets: dict[int, Lanelet], routes: Sequence | None) -> list[Route]:
    if not routes:
        try:
            seqs = enumerate_routes(lanelets)
        except MapError as e:
            raise MapError(f"{path}: {e}") from None
        if not seqs:
            raise MapError(f"{path}: no entry lanelets (every lanelet has a predecessor); list the routes explicitly")
        specs = [(ids, False) for ids in seqs]
    else:
        specs = []
        for i, r in enumerate(routes):
            try:
                ids = [int(x) for x in r]
            except (TypeError, ValueError) as e:
                raise MapError(f"{path}: route {i + 1} must be a list of lanelet ids, got {r!r}") from e
            loop = len(ids) > 1 and ids[0] == ids[-1]
            specs.append((ids[:-1] if loop else ids, loop))
    out, n_loops = [], 0
    for ids, loop in specs:
        n_loops += loop
        name = f"loop{n_loops}" if loop else "-".join(map(str, ids))
        try:
            out.append(build_route(name, ids, lanelets, loop=loop))
        except MapError as e:
            raise MapError(f"{path}: {e}") from e
    return out


def load_osm(
    path: str | Path, lane_width: float = 0.20, routes: Sequence[Sequence[int]] | None = None, name: str | None = None
) -> RoadMap:
    """A RoadMap from an OSM file in either dialect (see the module docstring)."""
    path = Path(path)
    osm = _read(path)
    if any(tags.get("type") == "lanelet" for _, tags in osm.relations.values()):
        lanelets, _ = _lanelet2_lanelets(osm, lane_width)
    elif any("lanes" in tags for _, tags in osm.ways.values()):
        lanelets = _centerline_lanelets(osm, lane_width)
        find_side_by_side(lanelets, lane_width)  # the dialect has no adjacency: geometry tells
    else:
        raise MapError(
            f"{path}: no lanelets found: expected relations tagged type=lanelet (Lanelet2) "
            "or ways tagged lanes=<id> (center lines)"
        )
    for la in lanelets.values():
        la.successors.sort()
        la.predecessors.sort()
    lanelets = dict(sorted(lanelets.items()))
    return RoadMap(
        name=name or path.stem,
        lanelets=lanelets,
        routes=_routes(path, lanelets, routes),
        lane_width=lane_width,
        source=str(path),
    )
