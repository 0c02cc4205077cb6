"""All routes of a map as padded tensors on the simulation device.

Built once per map. Per-step code gathers rows by each agent's route id, so
agents on different routes are handled in one batched operation.
"""

from __future__ import annotations

import torch

from sigmarl.maps.model import RoadMap
from sigmarl.maps.routes import resample

DENSE_STEP = 0.02  # m


def _pad(polylines: list[torch.Tensor], device, dtype) -> tuple[torch.Tensor, torch.Tensor]:
    """Stack polylines of different lengths, repeating each one's last point as padding."""
    n = max(len(p) for p in polylines)
    out = torch.stack([torch.cat([p, p[-1:].expand(n - len(p), 2)]) for p in polylines])
    counts = torch.tensor([len(p) for p in polylines], device=device)
    return out.to(device=device, dtype=dtype), counts


def _nearest_index(points: torch.Tensor, n_points: torch.Tensor, targets: torch.Tensor) -> torch.Tensor:
    """For every target point [R, M, 2], the index of the nearest valid point of `points` [R, B, 2]."""
    d = torch.cdist(targets, points)  # [R, M, B]
    invalid = torch.arange(points.shape[1], device=points.device)[None, None, :] >= n_points[:, None, None]
    return d.masked_fill(invalid, float("inf")).argmin(-1)


class RouteBank:
    """Padded route tensors [R, ...] plus per-route lookup tables."""

    def __init__(self, road_map: RoadMap, device: torch.device | str = "cpu", dtype=torch.float32):
        routes = road_map.routes
        self.names = [r.name for r in routes]
        self.n_routes = len(routes)
        self.center, self.n_center = _pad([r.center for r in routes], device, dtype)
        self.n_points = torch.tensor([r.n_points for r in routes], device=device)
        self.is_loop = torch.tensor([r.is_loop for r in routes], device=device)
        self.left, self.n_left = _pad([r.left for r in routes], device, dtype)
        self.right, self.n_right = _pad([r.right for r in routes], device, dtype)
        self.left_res, self.n_left_res = _pad([r.left_resampled for r in routes], device, dtype)
        self.right_res, self.n_right_res = _pad([r.right_resampled for r in routes], device, dtype)
        self.exit = torch.stack([r.exit for r in routes]).to(device=device, dtype=dtype)  # [R, 2, 2]
        # Direction of the center line at each point (last segment's for the final point).
        seg = self.center[:, 1:] - self.center[:, :-1]
        seg = torch.cat([seg, seg[:, -1:]], dim=1)
        # Loops: the last point's direction points back to the first point.
        last = self.n_center - 1
        r_idx = torch.arange(self.n_routes, device=device)
        wrap = self.center[r_idx, 0] - self.center[r_idx, last]
        seg[r_idx, last] = torch.where(self.is_loop[:, None], wrap, seg[r_idx, (last - 1).clamp(min=0)])
        self.heading = torch.atan2(seg[..., 1], seg[..., 0])  # [R, M]
        # Dense copies of the raw corridor boundaries (points on them every 2 cm), so that a
        # fixed window of points around the agent always spans the same distance, however
        # the map was drawn. Distances and boundary collisions use these.
        self.left_dense, self.n_left_dense = _pad(
            [torch.as_tensor(resample(r.left.numpy(), DENSE_STEP)) for r in routes], device, dtype)
        self.right_dense, self.n_right_dense = _pad(
            [torch.as_tensor(resample(r.right.numpy(), DENSE_STEP)) for r in routes], device, dtype)
        # Center index -> nearest dense and nearest resampled boundary point, so per-step
        # boundary queries look only at a small window.
        self.center_to_left = _nearest_index(self.left_dense, self.n_left_dense, self.center)
        self.center_to_right = _nearest_index(self.right_dense, self.n_right_dense, self.center)
        self.center_to_left_res = _nearest_index(self.left_res, self.n_left_res, self.center)
        self.center_to_right_res = _nearest_index(self.right_res, self.n_right_res, self.center)

    def index(self, route: torch.Tensor, idx: torch.Tensor, count: torch.Tensor | None = None,
              loop: bool = True) -> torch.Tensor:
        """Valid point indices: wrapped on loop routes, clamped to [0, count-1] otherwise.

        `route` [...] and `idx` [..., W] (same leading shape); `count` per route defaults
        to the center-line length (the real points on loops, all points otherwise).
        """
        if count is None:
            count = torch.where(self.is_loop, self.n_points, self.n_center)
        n = count[route].unsqueeze(-1)
        wrapped = torch.remainder(idx, n)
        clamped = idx.clamp(min=0).minimum(n - 1)
        if not loop:
            return clamped
        return torch.where(self.is_loop[route].unsqueeze(-1), wrapped, clamped)

    def gather(self, table: torch.Tensor, route: torch.Tensor, idx: torch.Tensor) -> torch.Tensor:
        """table[route, idx] for route [...] and idx [..., W]; keeps trailing dims of `table`."""
        r = route.unsqueeze(-1).expand_as(idx)
        return table[r, idx]
