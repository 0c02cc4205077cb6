"""All routes of a map as padded tensors on the simulation device.

Built once per map. Per-step code gathers windows of points around each
agent's progress index, for all agents, routes and lines at once:
- `lines` [R, 3, N, 2]: the center line (resampled every 0.08 m) and dense copies
  (every 0.02 m) of the left and right corridor boundaries, for distances and
  collisions;
- `sides` [R, 2, K, 2]: the boundaries resampled every 0.08 m, for the
  observed boundary points.
A lookup table maps each center-line index to the nearest point of every line,
so a fixed window around it always covers the agent.
"""

from __future__ import annotations

import torch

from sigmarl.maps.model import RoadMap
from sigmarl.maps.routes import resample

DENSE_STEP = 0.02  # m
CENTER, LEFT, RIGHT = 0, 1, 2


def _pad(polylines: list[torch.Tensor], n: int) -> torch.Tensor:
    """Stack polylines to length n, repeating each one's last point as padding."""
    return torch.stack([torch.cat([p, p[-1:].expand(n - len(p), 2)]) for p in polylines])


def _stack_lines(per_route: list[list[torch.Tensor]]) -> tuple[torch.Tensor, torch.Tensor]:
    """[R, C, N, 2] padded lines and their valid point counts [R, C]."""
    n = max(len(p) for lines in per_route for p in lines)
    table = torch.stack([_pad(lines, n) for lines in per_route])
    counts = torch.tensor([[len(p) for p in lines] for lines in per_route])
    return table, counts


def _nearest(table: torch.Tensor, counts: torch.Tensor, targets: torch.Tensor) -> torch.Tensor:
    """For targets [R, M, 2], the index of the nearest valid point of each line: [R, C, M]."""
    d = torch.cdist(targets.unsqueeze(1), table)  # [R, C, M, N]
    invalid = torch.arange(table.shape[2])[None, None, None, :] >= counts[:, :, None, None]
    return d.masked_fill(invalid, float("inf")).argmin(-1)


class RouteBank:
    """Padded route tensors plus per-route lookup tables, in float64 until moved to the device."""

    def __init__(self, road_map: RoadMap, device: torch.device | str = "cpu", dtype=torch.float32):
        routes = road_map.routes
        self.names = [r.name for r in routes]
        self.n_routes = len(routes)
        self.is_loop = torch.tensor([r.is_loop for r in routes])
        self.n_points = torch.tensor([r.n_points for r in routes])  # center points before the extension

        def dense(line: torch.Tensor) -> torch.Tensor:
            return torch.as_tensor(resample(line.numpy(), DENSE_STEP))

        lines, n_lines = _stack_lines([[r.center, dense(r.left), dense(r.right)] for r in routes])
        sides, n_sides = _stack_lines([[r.left_resampled, r.right_resampled] for r in routes])
        center = lines[:, CENTER]
        self.n_center = n_lines[:, CENTER]
        # Index arithmetic per line: wrap on loops (a closed boundary repeats its first
        # point at the end, so it wraps one earlier), clamp to the valid points otherwise.
        loop = self.is_loop.long()[:, None]
        self.lines_wrap = n_lines - loop * torch.tensor([0, 1, 1])
        self.lines_count = n_lines
        self.sides_wrap = n_sides
        self.sides_count = n_sides
        self.to_lines = _nearest(lines, n_lines, center).permute(0, 2, 1).contiguous()  # [R, M, 3]
        self.to_sides = _nearest(sides, n_sides, center).permute(0, 2, 1).contiguous()  # [R, M, 2]
        # Direction of the center line at each point (a loop's last point faces its first).
        nxt = torch.roll(center, -1, dims=1)
        last = self.n_center - 1
        r_idx = torch.arange(self.n_routes)
        nxt[r_idx, last] = torch.where(
            self.is_loop[:, None], center[r_idx, 0], 2 * center[r_idx, last] - center[r_idx, last - 1]
        )
        seg = nxt - center
        self.heading = torch.atan2(seg[..., 1], seg[..., 0])  # [R, M]

        to = dict(device=device)
        self.lines = lines.to(dtype=dtype, **to)
        self.sides = sides.to(dtype=dtype, **to)
        self.center = self.lines[:, CENTER]
        self.heading = self.heading.to(dtype=dtype, **to)
        for name in ("is_loop", "n_points", "n_center", "lines_wrap", "lines_count", "sides_wrap",
                     "sides_count", "to_lines", "to_sides"):
            setattr(self, name, getattr(self, name).to(**to))
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

    def row(self, route: torch.Tensor, index: torch.Tensor) -> torch.Tensor:
        """Row of the per-point tables for route and center index."""
        return route * self.center.shape[1] + index
