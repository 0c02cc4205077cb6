"""Each agent's own geometry against its route, for all agents at once: body corners, center-line
and boundary distances, short-term reference points, observed boundary points and boundary
contacts, read from windows of the route bank around the agent's progress index."""

from __future__ import annotations

from dataclasses import dataclass, fields

import torch

from sigmarl.env.collision import (
    crossings_odd,
    nearest_on_segments,
    segment_table,
    segments_box_overlap,
)
from sigmarl.env.geometry import rect_corners
from sigmarl.env.route_bank import CENTER, HALF_DIAGONAL, RouteBank
from sigmarl.params import VEHICLE

LENGTH, WIDTH = VEHICLE.length, VEHICLE.width
# Windows of points around an agent's progress index (spacing 0.08 m). Boundary distances and
# contacts use windows of raw boundary segments instead (RouteBank.boundary_window_table).
CENTER_WINDOW = (-3, 8)  # progress search: an agent moves at most 0.04 m per step
LINE_WINDOW = (-6, 7)  # center-line distance and reference points: +-0.48 m of center line
SIDE_WINDOW = (-1, 4)  # observed boundary points: 1 behind .. 3 ahead of the closest
# Margin of the exactness check against float32 rounding of the distances it adds up.
_REACH_MARGIN = 1e-3  # m


@dataclass
class EgoGeometry:
    """What observation, reward and collisions read of each agent's own pose, [E, A, ...]
    (or [rows, ...] in the spawn table)."""

    corners: torch.Tensor  # [E, A, 4, 2]
    d_center: torch.Tensor  # [E, A] distance to the own center line
    d_side: torch.Tensor  # [E, A, 2] DB: min(center distance - half width, corner distances)
    ref_points: torch.Tensor  # [E, A, P, 2] short-term reference points
    side_hit: torch.Tensor  # [E, A, 2] touching or beyond the left / right corridor boundary
    side_points: torch.Tensor  # [E, A, 2, 5, 2] observed corridor points, 1 behind .. 3 ahead

    def take(self, rows: torch.Tensor) -> EgoGeometry:
        return EgoGeometry(*(getattr(self, f.name)[rows] for f in fields(self)))

    def where(self, mask: torch.Tensor, other: EgoGeometry) -> EgoGeometry:
        """This geometry where mask [E, A] is True, `other`'s elsewhere."""
        out = []
        for f in fields(self):
            mine = getattr(self, f.name)
            out.append(torch.where(mask.view(*mask.shape, *(1,) * (mine.dim() - 2)), mine, getattr(other, f.name)))
        return EgoGeometry(*out)


def proven(probe: torch.Tensor, center: torch.Tensor, dist: torch.Tensor, reach: float) -> torch.Tensor:
    """[...] True where a boundary window reaching `reach` around `center` [..., 2] provably
    gives the exact distances dist [..., 2, 5] of the probes [..., 5, 2] (center first) and
    holds every segment the box can touch."""
    room = reach - _REACH_MARGIN - (probe - center.unsqueeze(-2)).norm(dim=-1)  # [..., 5]
    return (dist <= room.unsqueeze(-2)).flatten(-2).all(-1) & (room[..., 0] >= HALF_DIAGONAL)


def boundary_contacts(probe, pos, heading, center, table) -> tuple[torch.Tensor, torch.Tensor]:
    """Distances [..., 2, 5] and contact [..., 2] against boundary segments [..., 5, 2, S]."""
    dist, _ = nearest_on_segments(probe, table)
    # The box touches a boundary, or its center is already beyond one: the way from the
    # center-line point (inside the corridor) to the center crosses that boundary an odd
    # number of times. (A side test against the nearest segment got this wrong where a
    # corridor narrows in a step and at backtracking vertices: false contacts on CPM.)
    outside = crossings_odd(center, pos, table)
    touch = segments_box_overlap(table, pos, heading, LENGTH, WIDTH)
    return dist, touch | outside


class EgoTables:
    """The route bank's windows the ego geometry reads, cut once per scenario."""

    def __init__(self, bank: RouteBank, n_ref: int, ref_stride: int, device: torch.device) -> None:
        ar = lambda lo, hi: torch.arange(lo, hi, device=device)  # noqa: E731
        self.bank = bank
        self.center_offsets = ar(*CENTER_WINDOW)
        # Reference points: +2, +4, +6 center points ahead, as slots of the line window.
        self.ref_slots = -LINE_WINDOW[0] + ar(1, n_ref + 1) * ref_stride
        if int(self.ref_slots[-1]) >= LINE_WINDOW[1] - LINE_WINDOW[0]:
            raise ValueError("obs.n_ref_points x obs.ref_point_stride must be at most 6")
        self.line_table = bank.window_table("lines", ar(*LINE_WINDOW))
        self.side_table = bank.window_table("sides", ar(*SIDE_WINDOW))
        self.segment_table = segment_table(self.line_table)
        self.bound_table = bank.boundary_window_table(bank.reach)
        self.wide_table = bank.boundary_window_table(bank.wide_reach)

    def geometry(self, pos, heading, route, index) -> EgoGeometry:
        b = self.bank
        corners = rect_corners(pos, heading, LENGTH, WIDTH)  # [E, A, 4, 2]
        rows = b.row(route, index)
        lines = self.line_table[rows]  # center-line window: [E, A, 1, W, 2]
        d_center = nearest_on_segments(pos.unsqueeze(-2), self.segment_table[rows])[0][..., CENTER, 0]
        probe = torch.cat([pos.unsqueeze(-2), corners], dim=-2)  # [E, A, 5, 2]
        sides, side_hit = self.boundaries(probe, pos, heading, b.center[route, index], rows)
        return EgoGeometry(
            corners=corners,
            d_center=d_center,
            d_side=torch.minimum(sides[..., 0] - WIDTH / 2, sides[..., 1:].min(-1).values),
            ref_points=lines[..., CENTER, self.ref_slots, :],
            side_hit=side_hit,
            side_points=self.side_table[rows],
        )

    def boundaries(self, probe, pos, heading, center, rows) -> tuple[torch.Tensor, torch.Tensor]:
        """Distances from the probes [E, A, 5, 2] to each corridor boundary [E, A, 2, 5], and
        boundary contact [E, A, 2], exact against the raw boundary polylines.

        A row's window is the stretch of boundary that goes with the center point `center`
        [E, A, 2], out to the first segment farther than the map's reach from it. A segment of
        the stretch outside the window is farther than reach - |q - center| from a
        probe q, so the window's answer is provably the whole stretch's when every probe's
        distance stays below that; and the box, within HALF_DIAGONAL of its center, can only
        touch segments of the window then. Agents that fail the check (far off their center
        line) are recomputed on the wider window; one that fails that too is farther from its
        center line than its corridor allows, so it has left its corridor (`route_bank.reaches`).
        """
        dist, hit = boundary_contacts(probe, pos, heading, center, self.bound_table[rows])
        exact = proven(probe, center, dist, self.bank.reach)
        if not bool(exact.all()):
            far = (~exact).nonzero(as_tuple=True)
            p, c = probe[far], center[far]
            d, h = boundary_contacts(p, pos[far], heading[far], c, self.wide_table[rows[far]])
            h = h | ~proven(p, c, d, self.bank.wide_reach).unsqueeze(-1)
            dist, hit = dist.index_put(far, d), hit.index_put(far, h)
        return dist, hit

    def spawn_table(self) -> EgoGeometry:
        """Ego geometry of a vehicle standing on each center-line point, heading along the
        route: [R * M, ...] rows (`RouteBank.row`). Spawns are such poses, so a respawn reads
        its geometry here instead of recomputing it (a second geometry pass would cost as much
        as the step's)."""
        b = self.bank
        route, index = b.every_point()
        return self.geometry(b.center[route, index], b.heading[route, index], route, index)
