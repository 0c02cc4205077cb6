"""All routes of a map as padded tensors on the simulation device.

Built once per map. Per-step code gathers windows around each agent's progress index,
for all agents and routes at once:
- `lines` [R, 1, N, 2]: the center line (resampled every 0.08 m), for the center-line
  distance and the reference points;
- `sides` [R, 2, K, 2]: the boundaries resampled every 0.08 m, for the observed
  boundary points;
- `bounds` [R, 5, 2, S]: the corridor boundaries as the map gives them (raw vertices), as
  segment constants, for boundary distances and collisions. Their window per center point
  is the stretch of boundary that goes with it, out to `BOUNDARY_REACH` from the point
  (`boundary_window_table`); the scenario checks per agent that this stretch provably holds
  everything the vehicle can touch or is nearest to, and falls back to a wider one
  otherwise (see `TrafficScenario._boundaries`).
A lookup table maps each center-line index to the nearest point of every line,
so a fixed window around it always covers the agent.
"""

from __future__ import annotations

import numpy as np
import torch

from sigmarl.env.collision import segment_table
from sigmarl.maps.model import RoadMap
from sigmarl.params import VEHICLE

CENTER = 0
HALF_DIAGONAL = VEHICLE.half_diagonal


def _pad(polylines: list[torch.Tensor], n: int) -> torch.Tensor:
    """Stack polylines to length n, repeating each one's last point as padding."""
    return torch.stack([torch.cat([p, p[-1:].expand(n - len(p), 2)]) for p in polylines])


def _stack_lines(per_route: list[list[torch.Tensor]]) -> tuple[torch.Tensor, torch.Tensor]:
    """[R, C, N, 2] padded lines and their valid point counts [R, C]."""
    n = max(len(p) for lines in per_route for p in lines)
    table = torch.stack([_pad(lines, n) for lines in per_route])
    counts = torch.tensor([[len(p) for p in lines] for lines in per_route])
    return table, counts


class RouteBank:
    """Padded route tensors plus per-route lookup tables, in float64 until moved to the device."""

    def __init__(self, road_map: RoadMap, device: torch.device | str = "cpu", dtype=torch.float32):
        routes = road_map.routes
        self.names = [r.name for r in routes]
        self.n_routes = len(routes)
        self.is_loop = torch.tensor([r.is_loop for r in routes])
        self.n_points = torch.tensor([r.n_points for r in routes])  # center points before the extension

        lines, n_lines = _stack_lines([[r.center] for r in routes])
        sides, n_sides = _stack_lines([[r.left_resampled, r.right_resampled] for r in routes])
        # Raw corridor boundaries; padding repeats the last point (zero-length segments there
        # add nothing new to a distance or a contact test).
        bounds, n_bounds = _stack_lines([[r.left, r.right] for r in routes])
        center = lines[:, CENTER]
        self.n_center = n_lines[:, CENTER]
        # Index arithmetic per line: wrap on loops, clamp to the valid points otherwise.
        self.lines_wrap = n_lines.clone()
        self.lines_count = n_lines
        self.sides_wrap = n_sides
        self.sides_count = n_sides
        m = torch.arange(center.shape[1])
        self.to_lines = torch.minimum(m, self.n_center[:, None] - 1)[..., None]  # [R, M, 1]
        # Boundary points and segments that go with each center point: followed along the
        # route, so that where a route crosses itself the other pass is never taken for it.
        point_dist = torch.cdist(center.unsqueeze(1), sides)  # [R, 2, M, K]
        self.to_sides = follow_line(point_dist, n_sides, self.n_center, self.is_loop).permute(0, 2, 1).contiguous()
        # Direction of the center line at each point (a loop's last point faces its first).
        nxt = torch.roll(center, -1, dims=1)
        last = self.n_center - 1
        r_idx = torch.arange(self.n_routes)
        nxt[r_idx, last] = torch.where(
            self.is_loop[:, None], center[r_idx, 0], 2 * center[r_idx, last] - center[r_idx, last - 1]
        )
        seg = nxt - center
        self.heading = torch.atan2(seg[..., 1], seg[..., 0])  # [R, M]

        table = segment_table(bounds)  # [R, 5, 2, S]
        seg_dist = segment_distances(center, table)  # [R, 2, M, S]
        n_seg = n_bounds - 1
        near = follow_line(seg_dist, n_seg, self.n_center, self.is_loop)  # [R, 2, M]
        self.bounds = table.to(dtype=dtype, device=device)
        # How far a boundary lies from its center line on this map (0.225 m on CPM's two-lane
        # corridors), and from it the reach of the two boundary windows (see `reaches`).
        self.extent = float(seg_dist.gather(-1, near.unsqueeze(-1)).max())
        self.reach, self.wide_reach = reaches(self.extent)
        self._bound_window = {
            reach: _local_runs(seg_dist, near, n_seg, self.is_loop, reach)
            for reach in (self.reach, self.wide_reach)
        }

        to = dict(device=device)
        self.lines = lines.to(dtype=dtype, **to)
        self.sides = sides.to(dtype=dtype, **to)
        self.center = self.lines[:, CENTER]
        self.heading = self.heading.to(dtype=dtype, **to)
        for name in ("is_loop", "n_points", "n_center", "lines_wrap", "lines_count", "sides_wrap",
                     "sides_count", "to_lines", "to_sides"):
            setattr(self, name, getattr(self, name).to(**to))
        self._bound_window = {k: v.to(**to) for k, v in self._bound_window.items()}
        # Center-line windows wrap at the real points of a loop and clamp at the extension's end.
        self.center_wrap = self.lines_wrap[:, CENTER]

    def center_index(self, route: torch.Tensor, idx: torch.Tensor) -> torch.Tensor:
        """Valid center-line indices for route [...] and idx [..., W] (wrapped on loops)."""
        n = self.center_wrap[route].unsqueeze(-1)
        loop = self.is_loop[route].unsqueeze(-1)
        return torch.where(loop, torch.remainder(idx, n), idx.clamp(min=0).minimum(n - 1))

    def windows(self, which: str, route: torch.Tensor, index: torch.Tensor, offsets: torch.Tensor) -> torch.Tensor:
        """Points of every line of `which` ("lines" or "sides") around the agents' center index.

        route, index [E, A]; offsets [W] -> [E, A, C, W, 2].
        """
        table = getattr(self, which)
        wrap, count = getattr(self, f"{which}_wrap")[route], getattr(self, f"{which}_count")[route]
        near = getattr(self, f"to_{which}")[route, index]  # [E, A, C]
        idx = near.unsqueeze(-1) + offsets  # [E, A, C, W]
        loop = self.is_loop[route][..., None, None]
        idx = torch.where(loop, torch.remainder(idx, wrap.unsqueeze(-1)),
                          idx.clamp(min=0).minimum(count.unsqueeze(-1) - 1))
        r = route[..., None, None].expand_as(idx)
        c = torch.arange(table.shape[1], device=idx.device)[:, None].expand_as(idx)
        return table[r, c, idx]

    def every_point(self) -> tuple[torch.Tensor, torch.Tensor]:
        """(route, center index) of every row of the per-point tables, [R * M] each, in row
        order (see `row`); padding rows repeat their route's last real point."""
        n = self.center.shape[1]
        route = torch.arange(self.n_routes, device=self.center.device).repeat_interleave(n)
        index = torch.arange(n, device=route.device).repeat(self.n_routes)
        return route, torch.minimum(index, self.n_center[route] - 1)

    def window_table(self, which: str, offsets: torch.Tensor) -> torch.Tensor:
        """`windows` precomputed for every (route, center index): [R * M, C, W, 2]. Per step, a
        window is then one row lookup instead of index arithmetic (wrap, clamp) and a three-way
        gather."""
        return self.windows(which, *self.every_point(), offsets).contiguous()

    def boundary_window_table(self, reach: float) -> torch.Tensor:
        """Per row, the segment constants of the boundary stretch that goes with the center
        point: the run of consecutive segments around the one that goes with it, out to the
        first segment farther than `reach` (`self.reach` or `self.wide_reach`) from the point,
        on either side. [R * M, 5, 2, S_w]; shorter runs repeat their last member."""
        route, index = self.every_point()
        seg = self._bound_window[reach][route, index]  # [R * M, 2, S_w]
        table = self.bounds[route]  # [R * M, 5, 2, S]
        return table.gather(-1, seg.unsqueeze(1).expand(-1, 5, -1, -1)).contiguous()

    def row(self, route: torch.Tensor, index: torch.Tensor) -> torch.Tensor:
        """Row of the per-point tables for route and center index."""
        return route * self.center.shape[1] + index


def reaches(extent: float) -> tuple[float, float]:
    """Reach of the boundary windows of a map whose boundaries lie at most `extent` from their
    center line: the window's answer is exact for an agent whose probes q (center, corners)
    all satisfy |q - c| + d(q, window) <= reach, c its center point (the scenario checks).

    - near: extent + 0.3 m covers a vehicle anywhere inside its corridor, near its center line;
    - wide: a vehicle inside its corridor has |q - c| <= extent + 0.04 (half a center-point
      spacing) + HALF_DIAGONAL and d(q) <= 2 extent + HALF_DIAGONAL (the corridor's width,
      from a corner), so 3 extent + 2 HALF_DIAGONAL + 0.1 m covers every vehicle that has not
      left its corridor: one that fails it has.
    """
    return extent + 0.3, 3 * extent + 2 * HALF_DIAGONAL + 0.1


def segment_distances(points: torch.Tensor, table: torch.Tensor) -> torch.Tensor:
    """Distance from every point [R, M, 2] to every segment of a `segment_table` [R, 5, C, S]:
    [R, C, M, S]."""
    px, py = points[..., 0][:, None, :, None], points[..., 1][:, None, :, None]  # [R, 1, M, 1]
    ax, ay, dx, dy, inv = (t.unsqueeze(-2) for t in table.unbind(1))  # [R, C, 1, S]
    t = (((px - ax) * dx + (py - ay) * dy) * inv).clamp(0.0, 1.0)
    return torch.hypot(px - ax - t * dx, py - ay - t * dy)


def _step(j: int, k: int, n: int, loop: bool) -> int:
    """Index j moved by k along a line of n elements (wrapping on loops, clamped otherwise)."""
    return (j + k) % n if loop else min(max(j + k, 0), n - 1)


def follow_line(dist: torch.Tensor, n_line: torch.Tensor, n_center: torch.Tensor, is_loop: torch.Tensor,
            ahead: int = 8) -> torch.Tensor:
    """For each center point, the element (point or segment) of each line that goes with it.

    dist [R, C, M, N] from center points to line elements. Walking the center line from its
    start, each point takes the nearest element among the previous point's and the `ahead`
    elements after it (a center step of 0.08 m never passes more; the first of equally near
    ones). Both start at the route's start, so the walk stays on the same stretch of road even
    where a route crosses itself or comes back near itself. Returns [R, C, M] (padding rows
    repeat the last real one). The walk is sequential along the center line only: every
    route and line walks at once.
    """
    r_n, c_n, m_n, _ = dist.shape
    d = dist.numpy()
    n = n_line.numpy()[..., None]  # [R, C, 1]
    loop = np.broadcast_to(is_loop.numpy()[:, None, None], (r_n, c_n, 1))
    live = np.arange(m_n)[None, :] < n_center.numpy()[:, None]  # [R, M]
    rr, cc = np.ogrid[:r_n, :c_n]
    j = np.zeros((r_n, c_n), dtype=np.int64)
    out = np.zeros((r_n, c_n, m_n), dtype=np.int64)
    steps = np.arange(ahead + 1)
    for i in range(m_n):
        cand = j[..., None] + steps  # [R, C, ahead + 1]
        cand = np.where(loop, cand % n, np.minimum(cand, n - 1))
        best = cand[rr, cc, d[rr[..., None], cc[..., None], i, cand].argmin(-1)]
        j = np.where(live[:, i][:, None], best, j)
        out[..., i] = j
    return torch.from_numpy(out)


def _local_runs(dist: torch.Tensor, near: torch.Tensor, n_seg: torch.Tensor, is_loop: torch.Tensor,
                reach: float) -> torch.Tensor:
    """Per route, center point and side, the run of consecutive segments around `near` out to
    the first one farther than `reach` on either side: [R, M, C, S_w] indices, shorter runs
    padded with their last member.

    A run holds each segment once: on a loop it takes at most all n segments (the backward
    side first), otherwise it stops at the line's ends.
    """
    r_n, c_n, m_n, s_n = dist.shape
    d = dist.numpy()
    j0 = near.numpy()[..., None]  # [R, C, M, 1]
    n = n_seg.numpy()[:, :, None, None]
    loop = is_loop.numpy()[:, None, None, None]
    q = np.arange(1, max(s_n, 2))  # steps away from j0

    def extent(sign: int, cap: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """How many segments the run takes on one side, and their indices."""
        idx = j0 + sign * q
        inside = loop | ((idx >= 0) & (idx < n))
        idx = np.where(loop, idx % n, np.clip(idx, 0, n - 1))
        near_enough = np.take_along_axis(d, idx, axis=-1) <= reach
        ok = inside & near_enough & (q <= cap)
        return np.cumprod(ok, axis=-1).sum(-1, keepdims=True), idx

    left, left_idx = extent(-1, np.where(loop, n - 1, j0))
    right, right_idx = extent(1, np.where(loop, n - 1 - left, n - 1 - j0))
    width = int((left + right).max()) + 1
    # run position p = 0 .. width-1 holds j0 - left + p, clipped to the run's last member
    p = np.arange(width)
    offset = np.minimum(p - left, right)  # [R, C, M, W]: -left .. right, then right repeated
    back = np.take_along_axis(left_idx, np.clip(-offset - 1, 0, None), axis=-1)
    ahead = np.take_along_axis(right_idx, np.clip(offset - 1, 0, None), axis=-1)
    runs = np.where(offset < 0, back, np.where(offset > 0, ahead, j0))
    return torch.from_numpy(np.ascontiguousarray(runs.transpose(0, 2, 1, 3)))
