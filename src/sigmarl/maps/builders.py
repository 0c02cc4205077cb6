"""Procedural test maps: a four-arm intersection, an on-ramp and a roundabout.

The paper's test maps were drawn by hand in JOSM; these builders draw maps of
the same scale from a few parameters (MapConfig), so users can vary them.
Every lanelet is drawn as a center line made of straight and circular pieces
with an exact heading at each vertex; both boundaries are offsets of ±w/2
along the left normal, so the lane width is w at every vertex, the center is
the mean of the boundaries, and lanelets that meet with the same pose share
their boundary end points.

Traffic drives on the right. Every map is translated so that its bounding
box starts at (MARGIN, MARGIN): all three then lie inside the 4.5 m x 4.0 m
training world.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from sigmarl.errors import MapError
from sigmarl.maps.model import Lanelet, RoadMap
from sigmarl.maps.routes import build_route, enumerate_routes

if TYPE_CHECKING:
    from sigmarl.config import MapConfig

STRAIGHT_STEP = 0.1  # vertex spacing on straight lanes
ARC_STEP = 0.05  # center-line vertex spacing on curves (boundaries: ~0.035-0.065 m)
# Largest angle between arc vertices: keeps the polyline bounds w apart to 0.2% on tight turns.
ARC_ANGLE = 0.1
MARGIN = 0.1  # bounding box of a built map starts here
MERGE_TAIL = 0.9  # main road kept after the last on-ramp merge
_GAP = 0.05  # clearance between lanes that must not touch


class _Pen:
    """Draws one center line from straight and circular pieces, keeping the exact heading."""

    def __init__(self, point: Sequence[float], heading: float) -> None:
        self.points = [np.asarray(point, dtype=np.float64)]
        self.headings = [float(heading)]

    @property
    def point(self) -> np.ndarray:
        return self.points[-1]

    @property
    def heading(self) -> float:
        return self.headings[-1]

    def straight(self, length: float) -> _Pen:
        p, h = self.point, self.heading
        n = max(1, math.ceil(length / STRAIGHT_STEP - 1e-9))
        direction = np.array([math.cos(h), math.sin(h)])
        for i in range(1, n + 1):
            self.points.append(p + (length * i / n) * direction)
            self.headings.append(h)
        return self

    def turn(self, angle: float, radius: float) -> _Pen:
        """A circular arc turning the heading by `angle` (positive: left)."""
        p, h = self.point, self.heading
        s = 1.0 if angle > 0 else -1.0
        center = p + s * radius * np.array([-math.sin(h), math.cos(h)])
        n = max(2, math.ceil(radius * abs(angle) / ARC_STEP - 1e-9), math.ceil(abs(angle) / ARC_ANGLE - 1e-9))
        for i in range(1, n + 1):
            hi = h + angle * i / n
            self.points.append(center + s * radius * np.array([math.sin(hi), -math.cos(hi)]))
            self.headings.append(hi)
        return self

    def lanelet(self, lid: int, width: float) -> Lanelet:
        pts, h = np.stack(self.points), np.asarray(self.headings)
        normal = np.stack([-np.sin(h), np.cos(h)], axis=-1)
        return Lanelet(lid, pts + 0.5 * width * normal, pts - 0.5 * width * normal)


def _unit(angle: float) -> np.ndarray:
    return np.array([math.cos(angle), math.sin(angle)])


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2 * math.pi) - math.pi


def _connect(lanelets: dict[int, Lanelet], a: int, b: int) -> None:
    lanelets[a].successors.append(b)
    lanelets[b].predecessors.append(a)


def _two_way(lanelets: dict[int, Lanelet], a: int, b: int) -> None:
    """a and b share their left boundary and drive in opposite directions."""
    lanelets[a].adj_left, lanelets[a].adj_left_same = b, False
    lanelets[b].adj_left, lanelets[b].adj_left_same = a, False


def _arm_lengths(name: str, n_arms: int, arm_lengths: Sequence[float]) -> list[float]:
    if not arm_lengths:
        raise MapError(f"map {name}: arm_lengths is empty")
    lengths = [float(arm_lengths[k % len(arm_lengths)]) for k in range(n_arms)]
    if min(lengths) <= 0:
        raise MapError(f"map {name}: arm lengths must be positive, got {lengths}")
    return lengths


def _finish(name: str, lanelets: dict[int, Lanelet], width: float) -> RoadMap:
    """Translate into place, sort the links and enumerate the routes."""
    pts = np.concatenate([np.concatenate([la.left, la.right]) for la in lanelets.values()])
    shift = MARGIN - pts.min(0)
    lanelets = dict(sorted(lanelets.items()))
    for la in lanelets.values():
        la.left, la.right = la.left + shift, la.right + shift
        la.successors.sort()
        la.predecessors.sort()
    routes = [build_route("-".join(map(str, ids)), ids, lanelets) for ids in enumerate_routes(lanelets)]
    return RoadMap(name=name, lanelets=lanelets, routes=routes, lane_width=width, source=f"builder:{name}")


def build_intersection(
    name: str = "intersection",
    lane_width: float = 0.20,
    n_arms: int = 4,
    arm_lengths: Sequence[float] = (1.0, 1.4),
    junction_offset: float = 0.45,
) -> RoadMap:
    """Arms at angles 2πk/n (k=0 east, counter-clockwise), one lane per direction.

    Each arm is an incoming and an outgoing straight lane of length
    arm_lengths[k % len] starting `junction_offset` from the junction center.
    Every incoming lane connects to every other arm's outgoing lane by one turn
    lanelet: a circular arc tangent to both (a straight line for opposite
    arms). With 4 arms the right turns have radius junction_offset - w/2 and
    the left turns junction_offset + w/2.

    Ids: incoming lanes 1..n, outgoing n+1..2n, turns from 2n+1 ordered by
    (from arm, to arm).
    """
    w, c = lane_width, junction_offset
    if not 3 <= n_arms <= 6:
        raise MapError(f"map {name}: n_arms must be between 3 and 6, got {n_arms}")
    lengths = _arm_lengths(name, n_arms, arm_lengths)
    # Neighbouring arms' roads (each 2w wide) must not overlap where the arms start.
    if c * math.tan(math.pi / n_arms) < w + _GAP:
        raise MapError(f"map {name}: junction_offset {c} is too small for {n_arms} arms of lane width {w}")
    theta = [2 * math.pi * k / n_arms for k in range(n_arms)]
    u = [_unit(t) for t in theta]
    nrm = [_unit(t + math.pi / 2) for t in theta]
    lanelets: dict[int, Lanelet] = {}
    ends, starts = [], []  # pose where incoming lanes end / outgoing lanes start
    for k in range(n_arms):
        inc_start = (c + lengths[k]) * u[k] + 0.5 * w * nrm[k]
        pen = _Pen(inc_start, theta[k] + math.pi).straight(lengths[k])
        lanelets[k + 1] = pen.lanelet(k + 1, w)
        ends.append(pen.point)
        starts.append(c * u[k] - 0.5 * w * nrm[k])
        out = _Pen(starts[k], theta[k]).straight(lengths[k]).lanelet(n_arms + k + 1, w)
        lanelets[n_arms + k + 1] = out
        _two_way(lanelets, k + 1, n_arms + k + 1)
    lid = 2 * n_arms
    turn_of: dict[tuple[int, int], int] = {}
    for k in range(n_arms):
        for j in range(n_arms):
            if j == k:
                continue
            lid += 1
            pen = _junction_turn(name, (k, j), ends[k], starts[j], theta, u, w)
            assert np.linalg.norm(pen.point - starts[j]) < 1e-9, "turn misses the outgoing lane"
            lanelets[lid] = pen.lanelet(lid, w)
            _connect(lanelets, k + 1, lid)
            _connect(lanelets, lid, n_arms + j + 1)
            turn_of[k, j] = lid
    for k in range(n_arms):
        for j in range(k + 1, n_arms):
            if abs(_wrap(theta[j] - theta[k] - math.pi)) < 1e-9:  # opposite arms: two-way straight
                _two_way(lanelets, turn_of[k, j], turn_of[j, k])
    return _finish(name, lanelets, w)


def _junction_turn(name: str, arms: tuple[int, int], end: np.ndarray, start: np.ndarray,
                   theta: list[float], u: list[np.ndarray], w: float) -> _Pen:
    """The pen drawn from arm k's incoming lane's end to arm j's outgoing lane's start: a
    straight line between opposite arms, else a circular arc tangent to both lanes."""
    k, j = arms
    pen = _Pen(end, theta[k] + math.pi)
    delta = _wrap(theta[j] - (theta[k] + math.pi))
    if abs(delta) < 1e-9:
        return pen.straight(float(np.linalg.norm(start - end)))
    # Tangent length from the end of the incoming lane to where its line meets
    # the outgoing lane's line; equal on both sides by symmetry.
    a, _ = np.linalg.solve(np.stack([-u[k], u[j]], axis=1), start - end)
    radius = a / math.tan(abs(delta) / 2)
    if a <= 0 or radius < 0.5 * w + _GAP:
        raise MapError(
            f"map {name}: turn from arm {k} to arm {j} does not fit "
            f"(radius {radius:.3f} m); increase junction_offset"
        )
    pen.turn(delta, radius)
    return pen


def build_on_ramp(
    name: str = "on_ramp",
    lane_width: float = 0.20,
    n_ramps: int = 2,
    main_length: float = 4.1,
    ramp_drop: float = 1.63,
    ramp_angle: float = 45.0,
    ramp_radius: float = 0.8,
) -> RoadMap:
    """A one-lane main road along +x with `n_ramps` ramps merging into it from the right.

    Each ramp starts `ramp_drop` below the main road's center line, climbs at
    `ramp_angle` degrees and bends onto the main road with radius
    `ramp_radius`, joining it tangentially. The main road is split at the merge
    points, so a ramp and the main-road lanelet before it share their successor.
    Merges are spread evenly between the first point a ramp can reach and
    MERGE_TAIL before the end.

    Ids: main-road lanelets 1..n+1 in driving order, ramps n+2..2n+1.
    """
    w, r = lane_width, ramp_radius
    if n_ramps < 1:
        raise MapError(f"map {name}: n_ramps must be at least 1, got {n_ramps}")
    if not 10.0 <= ramp_angle <= 80.0:
        raise MapError(f"map {name}: ramp_angle must be between 10 and 80 degrees, got {ramp_angle}")
    phi = math.radians(ramp_angle)
    if r < 0.5 * w + _GAP:
        raise MapError(f"map {name}: ramp_radius {r} is too small for lane width {w}")
    diagonal = (ramp_drop - r * (1 - math.cos(phi))) / math.sin(phi)
    if diagonal <= 0:
        raise MapError(f"map {name}: ramp_drop {ramp_drop} is too small for ramp_radius {r}")
    run = r * math.sin(phi) + diagonal * math.cos(phi)  # x distance from ramp start to merge
    first, last = run + 0.5 * w * math.sin(phi) + _GAP, main_length - MERGE_TAIL
    if first > last:
        raise MapError(f"map {name}: main_length {main_length} is too short for a ramp ({first + MERGE_TAIL:.2f} m needed)")
    merges = [last] if n_ramps == 1 else list(np.linspace(first, last, n_ramps))
    if n_ramps > 1 and (merges[1] - merges[0]) * math.sin(phi) < w + _GAP:
        raise MapError(f"map {name}: {n_ramps} ramps do not fit on a {main_length} m main road; use fewer")
    lanelets: dict[int, Lanelet] = {}
    cuts = [0.0, *merges, main_length]
    pen = _Pen((0.0, 0.0), 0.0)
    for i in range(n_ramps + 1):
        pen = _Pen(pen.point, 0.0).straight(cuts[i + 1] - cuts[i])
        lanelets[i + 1] = pen.lanelet(i + 1, w)
        if i:
            _connect(lanelets, i, i + 1)
    for i, m in enumerate(merges):
        lid = n_ramps + 2 + i
        bend_start = np.array([m - r * math.sin(phi), -r + r * math.cos(phi)])
        pen = _Pen(bend_start - diagonal * _unit(phi), phi).straight(diagonal).turn(-phi, r)
        assert np.linalg.norm(pen.point - (m, 0.0)) < 1e-9, "ramp misses its merge point"
        lanelets[lid] = pen.lanelet(lid, w)
        _connect(lanelets, lid, i + 2)
    return _finish(name, lanelets, w)


def build_roundabout(
    name: str = "roundabout",
    lane_width: float = 0.20,
    n_arms: int = 4,
    arm_lengths: Sequence[float] = (1.22, 0.37),
    radius: float = 0.55,
    entry_radius: float = 0.35,
) -> RoadMap:
    """A circular one-lane ring (counter-clockwise) with two-way arms at angles 2πk/n.

    `radius` is the ring's center-line radius. Each arm has an incoming and
    an outgoing straight lane of length arm_lengths[k % len]; they join the
    ring through arcs of radius `entry_radius` tangent to the lane and to the
    ring, which is split where they meet it. Long east/west and short
    north/south arms give the paper's elongated footprint.

    Ids: incoming lanes 1..n, outgoing n+1..2n, entry arcs 2n+1..3n, exit arcs
    3n+1..4n, ring lanelets from 4n+1 counter-clockwise starting at arm 0's exit.
    """
    w, big_r, rho = lane_width, radius, entry_radius
    if not 3 <= n_arms <= 6:
        raise MapError(f"map {name}: n_arms must be between 3 and 6, got {n_arms}")
    if big_r < 0.5 * w + _GAP or rho < 0.5 * w + _GAP:
        raise MapError(f"map {name}: radius {big_r} and entry_radius {rho} must exceed half the lane width {w / 2}")
    lengths = _arm_lengths(name, n_arms, arm_lengths)
    # Entry arc center C = (x_c, w/2 + rho) in the arm's frame, at distance radius + rho from O.
    x_c = math.sqrt((big_r + rho) ** 2 - (0.5 * w + rho) ** 2)
    beta = math.atan2(0.5 * w + rho, x_c)  # ring angle of the entry point, measured from the arm
    ring_gap = 2 * math.pi / n_arms - 2 * beta
    if ring_gap * big_r < STRAIGHT_STEP:
        raise MapError(f"map {name}: {n_arms} arms do not fit around a ring of radius {big_r}; use fewer")
    theta = [2 * math.pi * k / n_arms for k in range(n_arms)]
    lanelets: dict[int, Lanelet] = {}

    def ring_point(angle: float) -> np.ndarray:
        return big_r * _unit(angle)

    n = n_arms
    for k in range(n):
        u, nrm = _unit(theta[k]), _unit(theta[k] + math.pi / 2)
        pen = _Pen((x_c + lengths[k]) * u + 0.5 * w * nrm, theta[k] + math.pi).straight(lengths[k])
        lanelets[k + 1] = pen.lanelet(k + 1, w)
        pen = _Pen(pen.point, pen.heading).turn(beta - math.pi / 2, rho)
        assert np.linalg.norm(pen.point - ring_point(theta[k] + beta)) < 1e-9, "entry misses the ring"
        lanelets[2 * n + k + 1] = pen.lanelet(2 * n + k + 1, w)
        exit_angle = theta[k] - beta
        pen = _Pen(ring_point(exit_angle), exit_angle + math.pi / 2).turn(beta - math.pi / 2, rho)
        lanelets[3 * n + k + 1] = pen.lanelet(3 * n + k + 1, w)
        pen = _Pen(pen.point, theta[k]).straight(lengths[k])
        lanelets[n + k + 1] = pen.lanelet(n + k + 1, w)
        _two_way(lanelets, k + 1, n + k + 1)
        _connect(lanelets, k + 1, 2 * n + k + 1)
        _connect(lanelets, 3 * n + k + 1, n + k + 1)
    ring_ids = _ring(lanelets, theta, (beta, ring_gap), big_r, w)
    for k in range(n):
        _connect(lanelets, 2 * n + k + 1, ring_ids[2 * k + 1])  # entry joins where the ring's 2nd piece starts
        _connect(lanelets, ring_ids[2 * k - 1], 3 * n + k + 1)  # exit leaves where the 1st piece starts
    return _finish(name, lanelets, w)


def _ring(lanelets: dict[int, Lanelet], theta: list[float], gaps: tuple[float, float], big_r: float,
          w: float) -> list[int]:
    """The ring's lanelets, ids from 4n+1: for each arm, exit point -> entry point (2 beta) ->
    the next arm's exit point (the ring gap), each joined to the next."""
    beta, ring_gap = gaps
    n = len(theta)
    ring_ids = []
    for k in range(n):
        for a, sweep in ((theta[k] - beta, 2 * beta), (theta[k] + beta, ring_gap)):
            lid = 4 * n + len(ring_ids) + 1
            lanelets[lid] = _Pen(big_r * _unit(a), a + math.pi / 2).turn(sweep, big_r).lanelet(lid, w)
            ring_ids.append(lid)
    for i, lid in enumerate(ring_ids):
        _connect(lanelets, lid, ring_ids[(i + 1) % len(ring_ids)])
    return ring_ids


def _arms(cfg: MapConfig) -> list[float]:
    return list(cfg.arm_lengths) or [cfg.arm_length]


def intersection_map(cfg: MapConfig) -> RoadMap:
    """The procedural intersection of a MapConfig (kind intersection)."""
    return build_intersection(cfg.name or cfg.kind, float(cfg.lane_width), int(cfg.n_arms), _arms(cfg), float(cfg.junction_offset))


def on_ramp_map(cfg: MapConfig) -> RoadMap:
    """The procedural on-ramp of a MapConfig (kind on_ramp)."""
    return build_on_ramp(cfg.name or cfg.kind, float(cfg.lane_width), int(cfg.n_ramps), float(cfg.main_length),
                         float(cfg.ramp_drop), float(cfg.ramp_angle), float(cfg.ramp_radius))


def roundabout_map(cfg: MapConfig) -> RoadMap:
    """The procedural roundabout of a MapConfig (kind roundabout)."""
    return build_roundabout(cfg.name or cfg.kind, float(cfg.lane_width), int(cfg.n_arms), _arms(cfg), float(cfg.radius),
                            float(cfg.entry_radius))
