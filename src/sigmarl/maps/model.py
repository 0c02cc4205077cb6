"""Road-network model: lanelets, routes and the map that holds them.

Geometry is kept in float64 (numpy for lanelets, torch for routes) so that the
0.08 m resampling is exact to 1e-9 m; the environment casts the route tensors
to its own dtype and device once per map.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import torch

# Sampling step of every resampled route polyline (a fix: the paper used the raw map vertices, 0.056-0.19 m apart).
RESAMPLE_STEP = 0.08
# Length of the straight extension past the end of non-loop routes: covers the
# farthest look-ahead point (6 steps = 0.48 m) plus margin.
EXTENSION_LENGTH = 0.64


@dataclass
class Lanelet:
    """One lane segment. Boundaries run in driving direction."""

    id: int
    left: np.ndarray  # (n, 2)
    right: np.ndarray  # (n, 2)
    successors: list[int] = field(default_factory=list)
    predecessors: list[int] = field(default_factory=list)
    adj_left: int | None = None
    adj_left_same: bool = True
    adj_right: int | None = None
    adj_right_same: bool = True
    # Center-line maps: same-direction lanelets running beside this one, in driving order
    # (they may cover only part of it; see sigmarl.maps.multilane).
    beside_left: list[int] = field(default_factory=list)
    beside_right: list[int] = field(default_factory=list)

    @property
    def center(self) -> np.ndarray:
        return 0.5 * (self.left + self.right)

    @property
    def width(self) -> np.ndarray:
        """Lane width at each boundary vertex pair."""
        return np.linalg.norm(self.left - self.right, axis=-1)


@dataclass
class Route:
    """A long-term reference path with everything the environment precomputes.

    `center` is the route's center line resampled every RESAMPLE_STEP metres.
    For a non-loop route it carries the straight extension; `n_points` counts
    the points up to the route's real end (the extension starts after them).
    `left`/`right` are the corridor boundaries: the raw polylines (distances
    and collisions use these) and their resampled versions (observation points).
    """

    name: str
    lanelet_ids: tuple[int, ...]
    is_loop: bool
    center: torch.Tensor  # (M, 2) float64, extension included
    n_points: int  # points before the extension
    length: float  # polyline length of the raw center line
    left: torch.Tensor  # (B_l, 2) raw corridor left boundary, extension included
    right: torch.Tensor  # (B_r, 2)
    left_resampled: torch.Tensor  # (K_l, 2)
    right_resampled: torch.Tensor  # (K_r, 2)
    entry: torch.Tensor  # (2, 2): first left corridor point, first right corridor point
    exit: torch.Tensor  # (2, 2): last left, last right (before the extension)


@dataclass
class RoadMap:
    """A road network: lanelets plus the routes agents follow on it."""

    name: str
    lanelets: dict[int, Lanelet]
    routes: list[Route]
    lane_width: float
    source: str = ""  # file or builder it came from

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(xmin, ymin, xmax, ymax) over all lanelet boundary points."""
        pts = np.concatenate([np.concatenate([la.left, la.right]) for la in self.lanelets.values()])
        return (*pts.min(0), *pts.max(0))

    @property
    def size(self) -> tuple[float, float]:
        xmin, ymin, xmax, ymax = self.bounds
        return xmax - xmin, ymax - ymin

    def route(self, name: str) -> Route:
        for r in self.routes:
            if r.name == name:
                return r
        raise KeyError(name)
