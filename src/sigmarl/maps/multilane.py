"""Same-direction lanes side by side in center-line maps, and the corridors they make.

A center-line OSM file has no adjacency: two lanes of a one-way road are just two ways
drawn about a lane width apart. Lanelet M counts as *beside* lanelet L (on L's left or
right) when nearly all of M's center line runs 0.6..1.4 lane widths from L's, on one side,
heading the same way. The relation need not cover whole lanelets: a long lane can have
two shorter ones beside it, one after the other (a lane that splits off and one that goes
on), so each lanelet keeps a list of the lanelets beside it on each side.

A route's corridor then spans, along each of its lanelets, from the outer boundary of the
outermost lane beside it on the left to that on the right (the CPM rule: leftmost-left to
rightmost-right), cut to the stretch where they run beside it.
"""

from __future__ import annotations

import numpy as np

from sigmarl.maps.model import Lanelet

BESIDE_MIN, BESIDE_MAX = 0.6, 1.4  # center-line spacing, in lane widths
BESIDE_SHARE = 0.9  # share of M's center line that must run beside L
ALIGN_COS = np.cos(np.radians(20.0))  # same heading to within 20 degrees
_SAMPLE = 0.02  # m between the points tested along M
_TOL = 1e-6
# Lanes drawn side by side by hand start and end a few mm apart: a shorter stretch of a lane
# without its neighbour, at either end, is taken as covered.
_SNAP = 0.05  # m


def _arc(poly: np.ndarray) -> np.ndarray:
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(poly, axis=0), axis=-1))])


def project(poly: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Closest point of a polyline to each point: (distance, arc length there, segment index)."""
    a, seg = poly[:-1], np.diff(poly, axis=0)  # (m, 2)
    seg_len2 = np.maximum((seg**2).sum(-1), 1e-18)
    rel = points[:, None, :] - a[None]  # (n, m, 2)
    t = np.clip((rel * seg[None]).sum(-1) / seg_len2, 0.0, 1.0)
    d = np.linalg.norm(rel - t[..., None] * seg[None], axis=-1)
    i = d.argmin(-1)
    rows = np.arange(len(points))
    s = _arc(poly)[i] + t[rows, i] * np.sqrt(seg_len2[i])
    return d[rows, i], s, i


def point_at(poly: np.ndarray, s: float) -> np.ndarray:
    cum = _arc(poly)
    return np.stack([np.interp(s, cum, poly[:, 0]), np.interp(s, cum, poly[:, 1])])


def substring(poly: np.ndarray, s0: float, s1: float) -> np.ndarray:
    """The part of a polyline between arc lengths s0 < s1 (its vertices in between kept)."""
    cum = _arc(poly)
    inner = poly[(cum > s0 + _TOL) & (cum < s1 - _TOL)]
    return np.concatenate([point_at(poly, s0)[None], inner, point_at(poly, s1)[None]])


def densify(poly: np.ndarray, step: float = _SAMPLE) -> np.ndarray:
    cum = _arc(poly)
    s = np.linspace(0.0, cum[-1], max(int(np.ceil(cum[-1] / step)), 1) + 1)
    return np.stack([np.interp(s, cum, poly[:, 0]), np.interp(s, cum, poly[:, 1])], axis=-1)


def beside_side(lane: np.ndarray, other: np.ndarray, width: float) -> str | None:
    """'left' or 'right' if center line `other` runs beside center line `lane`, else None."""
    pts = densify(other)
    d, _, i = project(lane, pts)
    seg = np.diff(lane, axis=0)[i]
    seg = seg / np.linalg.norm(seg, axis=-1, keepdims=True)
    closest = lane[:-1][i] + ((pts - lane[:-1][i]) * seg).sum(-1, keepdims=True) * seg
    across = pts - closest
    cross = seg[:, 0] * across[:, 1] - seg[:, 1] * across[:, 0]
    heading = np.gradient(pts, axis=0)
    heading = heading / np.maximum(np.linalg.norm(heading, axis=-1, keepdims=True), 1e-12)
    near = (d >= BESIDE_MIN * width) & (d <= BESIDE_MAX * width) & ((heading * seg).sum(-1) >= ALIGN_COS)
    for side, sign in (("left", 1.0), ("right", -1.0)):
        if np.mean(near & (sign * cross > 0)) >= BESIDE_SHARE:
            return side
    return None


def find_side_by_side(lanelets: dict[int, Lanelet], width: float) -> None:
    """Fill `beside_left`/`beside_right` of every lanelet, each list in driving order."""
    for la in lanelets.values():
        la.beside_left, la.beside_right = [], []
    opposite = {"left": "right", "right": "left"}
    reach = BESIDE_MAX * width
    lanes = list(lanelets.values())
    centers = [la.center for la in lanes]
    lows, highs = np.stack([c.min(0) for c in centers]), np.stack([c.max(0) for c in centers])
    for k, lane in enumerate(lanes):
        # only lanes whose bounding boxes come within reach (a map of many lanelets stays fast)
        near = ~((highs < lows[k] - reach) | (lows > highs[k] + reach)).any(1)
        for j in np.flatnonzero(near):
            other = lanes[j]
            if other.id == lane.id or other.id in lane.successors or other.id in lane.predecessors:
                continue
            side = beside_side(centers[k], centers[j], width)
            if side is not None:
                getattr(lane, f"beside_{side}").append(other.id)
                # The shorter lane lies beside the longer one too: the relation is mutual.
                if lane.id not in getattr(other, f"beside_{opposite[side]}"):
                    getattr(other, f"beside_{opposite[side]}").append(lane.id)
    for lane in lanelets.values():
        for side in ("left", "right"):
            ids = sorted(set(getattr(lane, f"beside_{side}")),
                         key=lambda j: float(project(lane.center, lanelets[j].center[:1])[1][0]))
            setattr(lane, f"beside_{side}", ids)


def _own_boundary_between(lane: Lanelet, side: str, s0: float, s1: float) -> np.ndarray:
    """The lanelet's own boundary on `side` across from center-line arc lengths s0..s1.

    Boundary vertex k belongs to center vertex k, so an arc length on the center line maps
    to the same segment and fraction on the boundary."""
    bound = getattr(lane, side)
    cum = _arc(lane.center)
    index = np.arange(len(cum), dtype=np.float64)
    k0, k1 = np.interp(s0, cum, index), np.interp(s1, cum, index)
    ks = np.concatenate([[k0], np.arange(np.floor(k0) + 1, np.ceil(k1)), [k1]])
    return np.stack([np.interp(ks, index, bound[:, 0]), np.interp(ks, index, bound[:, 1])], axis=-1)


def corridor_side(lane: Lanelet, side: str, lanelets: dict[int, Lanelet], _seen: frozenset = frozenset()) -> np.ndarray:
    """The corridor's boundary on `side` along `lane`, in driving order.

    Where lanes run beside it on that side, the outer boundary of the outermost of them
    (cut to the stretch across from `lane`), elsewhere `lane`'s own boundary."""
    seen = _seen | {lane.id}
    beside = [j for j in getattr(lane, f"beside_{side}", []) if j not in seen]
    if not beside:
        return getattr(lane, side)
    length = _arc(lane.center)[-1]
    pieces, done = [], 0.0  # `done`: arc length of lane's center line covered so far
    for j in beside:
        other = lanelets[j]
        _, span, _ = project(lane.center, other.center[[0, -1]])
        a, b = max(float(span[0]), done), float(span[1])
        a = done if a - done < _SNAP else a
        b = length if length - b < _SNAP else b
        if b <= a + _TOL:
            continue
        if a > done + _TOL:
            pieces.append(_own_boundary_between(lane, side, done, a))
        outer = corridor_side(other, side, lanelets, seen)
        _, cut, _ = project(outer, np.stack([point_at(lane.center, a), point_at(lane.center, b)]))
        c0, c1, outer_len = float(cut[0]), float(cut[1]), float(_arc(outer)[-1])
        c0 = 0.0 if c0 < _SNAP else c0
        c1 = outer_len if outer_len - c1 < _SNAP else c1
        if c1 > c0 + _TOL:
            pieces.append(substring(outer, c0, c1))
        done = b
    if done < length - _TOL:
        pieces.append(_own_boundary_between(lane, side, done, length))
    out = [pieces[0]]
    for p in pieces[1:]:  # drop a point repeated where two pieces meet
        out.append(p[1:] if np.linalg.norm(out[-1][-1] - p[0]) < _TOL else p)
    return np.concatenate(out)


def side_by_side_spacing(lanelets: dict[int, Lanelet], width: float) -> list[tuple[int, int, float]]:
    """(L, M, median distance in m of M's center line from L's where it runs beside it) for each
    lanelet M found beside lanelet L on its left: the spacing that a lane width should match
    (boundaries then meet)."""
    out = []
    for lane in lanelets.values():
        for j in lane.beside_left:
            d, _, _ = project(lane.center, densify(lanelets[j].center))
            beside = d[(d >= BESIDE_MIN * width) & (d <= BESIDE_MAX * width)]
            out.append((lane.id, j, float(np.median(beside if len(beside) else d))))
    return out


def width_check(road_map) -> str:
    """One line on a map's lane width against its lanes drawn side by side (`maps show`)."""
    w = road_map.lane_width
    pairs = side_by_side_spacing(road_map.lanelets, w)
    found = "; ".join(f"{m} beside {lane} ({d:.3f} m apart, {d / w:.2f} widths)" for lane, m, d in pairs)
    return (f"lane width {w:.3f} m; same-direction lanes side by side (center lines {BESIDE_MIN}-{BESIDE_MAX} "
            f"widths apart): {found or 'none'}")
