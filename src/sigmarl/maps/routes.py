"""Route construction: connectivity checks, corridors, resampling, extension.

Everything here runs once per map; the environment only indexes the results.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np
import torch

from sigmarl.errors import MapError
from sigmarl.maps.model import EXTENSION_LENGTH, RESAMPLE_STEP, Lanelet, Route
from sigmarl.maps.multilane import corridor_side

_JOIN_TOL = 1e-6  # consecutive polylines sharing an end point


def polyline_length(points: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(points, axis=0), axis=-1).sum())


def join_polylines(parts: Iterable[np.ndarray]) -> np.ndarray:
    """Concatenate polylines, dropping the duplicated point where one ends and the next starts."""
    out: list[np.ndarray] = []
    for part in parts:
        if out and np.linalg.norm(out[-1][-1] - part[0]) < _JOIN_TOL:
            part = part[1:]
        out.append(part)
    return np.concatenate(out)


def resample(points: np.ndarray, step: float = RESAMPLE_STEP, closed: bool = False) -> np.ndarray:
    """Points at uniform arc length `step` along a polyline, starting at its first point.

    Every point lies on the input polyline, at arc length k*step. An open
    polyline also keeps its end point (the last gap is shorter than `step`);
    a closed one stops before wrapping around to its start.
    """
    seg = np.diff(points, axis=0)
    seg_len = np.linalg.norm(seg, axis=-1)
    keep = seg_len > 0
    pts = np.concatenate([points[:1], points[1:][keep]])
    seg, seg_len = seg[keep], seg_len[keep]
    cum = np.concatenate([[0.0], np.cumsum(seg_len)])
    total = cum[-1]
    n = int(np.floor(total / step + 1e-9))
    s = np.arange(n + 1) * step
    if closed and total - s[-1] < 1e-9:
        s = s[:-1]  # the last sample would coincide with the first
    i = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(seg) - 1)
    t = (s - cum[i]) / seg_len[i]
    out = pts[i] + t[:, None] * seg[i]
    if not closed and total - s[-1] > 1e-9:
        out = np.concatenate([out, pts[-1:]])
    return out


def extend_straight(points: np.ndarray, length: float, step: float) -> np.ndarray:
    """Append points continuing the last segment's direction for `length` metres."""
    direction = points[-1] - points[-2]
    direction = direction / np.linalg.norm(direction)
    k = np.arange(1, int(np.ceil(length / step)) + 1)
    return np.concatenate([points, points[-1] + (k * step)[:, None] * direction])


def check_connected(name: str, ids: Sequence[int], lanelets: dict[int, Lanelet], loop: bool) -> None:
    """Raise MapError naming the route and the first broken link."""
    for lid in ids:
        if lid not in lanelets:
            raise MapError(f"route {name}: lanelet {lid} does not exist in the map")
    pairs = list(zip(ids[:-1], ids[1:], strict=True))
    if loop:
        pairs.append((ids[-1], ids[0]))
    for a, b in pairs:
        if b not in lanelets[a].successors:
            raise MapError(
                f"route {name}: lanelet {a} is not connected to lanelet {b} "
                f"(successors of {a}: {lanelets[a].successors or 'none'})"
            )


def corridor_members(lanelet: Lanelet, lanelets: dict[int, Lanelet]) -> tuple[int, int]:
    """Ids of the leftmost and rightmost same-direction neighbours (the lanelet itself if none)."""
    left = lanelet
    seen = {left.id}
    while left.adj_left is not None and left.adj_left_same and left.adj_left not in seen:
        left = lanelets[left.adj_left]
        seen.add(left.id)
    right = lanelet
    while right.adj_right is not None and right.adj_right_same and right.adj_right not in seen:
        right = lanelets[right.adj_right]
        seen.add(right.id)
    return left.id, right.id


def infer_adjacency(lanelets: dict[int, Lanelet], tol: float = 1e-3) -> None:
    """Add same-direction neighbours that a map file leaves implicit.

    A lane that splits off another or merges into it (CPM: 22 beside 3, 23 beside
    5) is often not marked adjacent. Two lanelets count as neighbours when they
    lead to the same lanelets or come from the same ones, and one's right boundary
    meets the other's left boundary at their start or end.
    """
    for a in lanelets.values():
        if a.adj_right is not None:
            continue
        for b in lanelets.values():
            if b.id == a.id or b.adj_left is not None:
                continue
            same_succ = a.successors and sorted(a.successors) == sorted(b.successors)
            same_pred = a.predecessors and sorted(a.predecessors) == sorted(b.predecessors)
            if not (same_succ or same_pred):
                continue
            touch = (np.linalg.norm(a.right[0] - b.left[0]) < tol
                     or np.linalg.norm(a.right[-1] - b.left[-1]) < tol)
            if touch:
                a.adj_right, a.adj_right_same = b.id, True
                b.adj_left, b.adj_left_same = a.id, True
                break


def build_route(
    name: str,
    ids: Sequence[int],
    lanelets: dict[int, Lanelet],
    loop: bool = False,
    step: float = RESAMPLE_STEP,
) -> Route:
    """Precompute one route's tensors from its lanelet sequence."""
    ids = tuple(int(i) for i in ids)
    if not ids:
        raise MapError(f"route {name}: no lanelets")
    check_connected(name, ids, lanelets, loop)
    center = join_polylines(lanelets[i].center for i in ids)
    lefts, rights = [], []
    for i in ids:
        la = lanelets[i]
        lm, rm = corridor_members(la, lanelets)
        lefts.append(corridor_side(la, "left", lanelets) if la.beside_left else lanelets[lm].left)
        rights.append(corridor_side(la, "right", lanelets) if la.beside_right else lanelets[rm].right)
    left, right = join_polylines(lefts), join_polylines(rights)
    if loop:
        center = join_polylines([center, center[:1]])
        left = join_polylines([left, left[:1]])
        right = join_polylines([right, right[:1]])
    length = polyline_length(center)
    c_res = resample(center, step, closed=loop)
    l_res = resample(left, step, closed=loop)
    r_res = resample(right, step, closed=loop)
    n_points = len(c_res)
    entry = np.stack([left[0], right[0]])
    exit_ = np.stack([left[-1], right[-1]])
    if not loop:
        c_res = extend_straight(c_res, EXTENSION_LENGTH, step)
        l_res = extend_straight(l_res, EXTENSION_LENGTH, step)
        r_res = extend_straight(r_res, EXTENSION_LENGTH, step)
        left = extend_straight(left, EXTENSION_LENGTH, EXTENSION_LENGTH)
        right = extend_straight(right, EXTENSION_LENGTH, EXTENSION_LENGTH)

    def t(a: np.ndarray) -> torch.Tensor:
        return torch.as_tensor(np.ascontiguousarray(a), dtype=torch.float64)

    return Route(
        name=name,
        lanelet_ids=ids,
        is_loop=loop,
        center=t(c_res),
        n_points=n_points,
        length=length,
        left=t(left),
        right=t(right),
        left_resampled=t(l_res),
        right_resampled=t(r_res),
        entry=t(entry),
        exit=t(exit_),
    )


# Bounds on enumerating a map's routes: a real map has tens of routes found in thousands of
# steps; forks that loop back without an exit have exponentially many partial paths.
MAX_ROUTES = 10_000
MAX_STEPS = 200_000  # path extensions: about a second of work


def enumerate_routes(lanelets: dict[int, Lanelet], entries: Sequence[int] | None = None,
                     max_routes: int | None = None, max_steps: int | None = None) -> list[list[int]]:
    """Every lanelet path from an entry (no predecessor) to an exit (no successor), no lanelet
    twice, depth first in the successors' order.

    Iterative (a chain of any length), and bounded: past `max_routes` routes or `max_steps`
    path extensions it stops with a MapError saying to list the routes."""
    if entries is None:
        entries = sorted(i for i, la in lanelets.items() if not la.predecessors)
    max_routes, max_steps = max_routes or MAX_ROUTES, max_steps or MAX_STEPS

    def successors(lid: int) -> list[int]:
        return [s for s in lanelets[lid].successors if s in lanelets]

    def too_many(what: str) -> MapError:
        return MapError(f"{what} while enumerating its routes: the lanelet graph is malformed (forks that loop "
                        "back?) or too large; list the routes in the map's config (routes: [[id, ...], ...])")

    paths: list[list[int]] = []
    steps = 0
    for entry in entries:
        path, on_path, pending = [entry], {entry}, [iter(successors(entry))]
        if not successors(entry):
            paths.append([entry])
        while pending:
            nxt = next(pending[-1], None)
            if nxt is None:  # every successor of the path's last lanelet tried: step back
                pending.pop()
                on_path.discard(path.pop())
                continue
            if nxt in on_path:
                continue
            steps += 1
            if steps > max_steps:
                raise too_many(f"more than {max_steps:,} steps and {len(paths)} routes")
            if not successors(nxt):
                paths.append([*path, nxt])
                if len(paths) > max_routes:
                    raise too_many(f"more than {max_routes:,} routes")
                continue
            path.append(nxt)
            on_path.add(nxt)
            pending.append(iter(successors(nxt)))
    return paths
