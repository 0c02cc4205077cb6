"""The paper's own rules where ours differ, as switches (`rules.*`; `rules=paper` turns all on).

Everything here runs only where a switch is on: the scenario decides once, at construction,
which of these it needs, so our own rules (all off) pay nothing for them.

Which switches reach evaluation: a policy is evaluated under the dynamics and observation it
was trained with, but the study's metrics are always measured our way (exact contacts,
per-agent flags, a fresh observation after a respawn), so `for_evaluation` turns the
switches that would change what is measured off.
"""

from __future__ import annotations

import dataclasses
from dataclasses import fields
from typing import TYPE_CHECKING, Any

import numpy as np
import torch

from sigmarl.env.collision import nearest_on_segments, segment_table
from sigmarl.env.dynamics import bicycle_step
from sigmarl.env.geometry import wrap_angle
from sigmarl.env.route_bank import follow_line, segment_distances
from sigmarl.maps.routes import extend_straight, join_polylines
from sigmarl.params import NORMALISERS, VEHICLE

if TYPE_CHECKING:
    from sigmarl.config import RulesConfig
    from sigmarl.env.route_bank import RouteBank
    from sigmarl.maps.model import RoadMap

DRAG = 0.25  # VMAS' drag, which the paper's simulator applied to every velocity
COMMAND_LIMIT = 1.0  # m/s, the paper's speed command range (its effective top speed: 0.8)
# Straight vertices appended past the end of a non-loop route's raw center line, so that the
# vertex 6 after the last real segment's start exists (spacing like the paper's test maps).
RAW_EXTENSION = (0.8, 0.1)  # m: length, vertex spacing
RAW_WINDOW = (-2, 10)  # raw center vertices kept around a resampled point's raw segment
RAW_SEGMENTS = 5  # of which the first five segments are searched for the closest one
# The paper's test maps had vertices about 0.1 m apart; ours are simplified to within 2 mm of
# them (straight stretches one segment, up to 2.2 m), so segments longer than 0.2 m are cut
# into equal pieces of at most 0.1 m (CPM's vertices, at most 0.155 m apart, stay the paper's).
DENSIFY = (0.2, 0.1)  # m: longest segment kept, piece length
SIDE_VERTICES = (-1, 4)  # M4's boundary vertices: one before to three after the closest segment's start
# Switches that would change what an evaluation measures: evaluation keeps them off.
MEASUREMENT_SWITCHES = ("strict_crossings", "env_lane_flag", "stale_respawn_obs")


def switches_on(rules: RulesConfig) -> list[str]:
    """The rules' switches that are on, in the config's order."""
    return [f.name for f in fields(rules) if getattr(rules, f.name)]


def rules_label(rules: RulesConfig) -> str:
    """`ours` (every switch off), `paper` (every switch on), the switches on joined by +, or,
    with most on, `paper-` and the switches off (`paper-reward_normaliser_one+reset_speed_one`:
    the runs trained under `rules=paper` before those two switches existed)."""
    on = switches_on(rules)
    off = [f.name for f in fields(rules) if f.name not in on]
    return "ours" if not on else "paper" if not off else "+".join(on) if len(on) <= len(off) else "paper-" + "+".join(off)


def for_evaluation(cfg: Any) -> Any:
    """A config whose rules keep the policy's dynamics and observation but measure our way."""
    rules = dataclasses.replace(cfg.rules, **{k: False for k in MEASUREMENT_SWITCHES})
    return dataclasses.replace(cfg, rules=rules)


def test_world(road_map: RoadMap) -> tuple[float, float]:
    """The world size a map's bird's-eye view is divided by under `test_world_size`: the
    bounding box widened by its distance from the origin on the far side too (4.5 x 4.0 m on
    CPM, whose points span 0.03..4.47 x 0.03..3.97); a map reaching below 0: its box."""
    xmin, ymin, xmax, ymax = road_map.bounds
    return (float(xmax + xmin if xmin >= 0 else xmax - xmin), float(ymax + ymin if ymin >= 0 else ymax - ymin))


# ---- dynamics ------------------------------------------------------------------------------
def drag_step(pos, heading, vel, yaw_rate, command, steering, dt: float, wrap: bool = True):
    """One step of the paper's simulator: the kinematic model's change Δ for the command, turned
    into a velocity after VMAS' drag, v = Δ/dt - 0.25 v_prev (and the yaw rate likewise), then
    integrated: p += v dt. Returns (pos, heading, vel, signed speed, yaw rate)."""
    target, turned, _ = bicycle_step(pos, heading, command, steering, dt, wrap=False)
    vel = (target - pos) / dt - DRAG * vel
    yaw_rate = (turned - heading) / dt - DRAG * yaw_rate
    heading = heading + yaw_rate * dt
    if wrap:
        heading = wrap_angle(heading)
    forward = (vel[..., 0] * heading.cos() + vel[..., 1] * heading.sin()).sign()
    return pos + vel * dt, heading, vel, forward * vel.norm(dim=-1), yaw_rate


def heading_velocity(vel: torch.Tensor, heading: torch.Tensor) -> torch.Tensor:
    """|v| along the heading, (cos, sin)(psi) |v|: what the paper observed of other agents."""
    return vel.norm(dim=-1, keepdim=True) * torch.stack([heading.cos(), heading.sin()], -1)


def speed_scale(rules: RulesConfig) -> float:
    return COMMAND_LIMIT if rules.speed_normaliser_one else NORMALISERS.speed


def reward_speed_scale(rules: RulesConfig) -> float:
    """What the reward's motion terms divide speeds by: the paper's command limit, or our top speed."""
    return COMMAND_LIMIT if rules.reward_normaliser_one else VEHICLE.max_speed


def reset_speed_limit(rules: RulesConfig, max_speed: float) -> float:
    """A respawn's speed is drawn in [0, this): the paper's command limit, or the vehicle's top speed."""
    return COMMAND_LIMIT if rules.reset_speed_one else max_speed


# ---- collisions ----------------------------------------------------------------------------
def _edges(corners: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Starts and directions [..., 4, 2] of a rectangle's edges from its corners [..., 4, 2]."""
    return corners, torch.roll(corners, -1, dims=-2) - corners


def _strict(a, d, b, e) -> torch.Tensor:
    """True where segments a + t d and b + u e (broadcast [..., 2]) cross at 0 < t, u < 1."""
    denom = d[..., 0] * e[..., 1] - d[..., 1] * e[..., 0]
    w = b - a
    t = (w[..., 0] * e[..., 1] - w[..., 1] * e[..., 0]) / denom
    u = (w[..., 0] * d[..., 1] - w[..., 1] * d[..., 0]) / denom
    return (denom != 0) & (t > 0) & (t < 1) & (u > 0) & (u < 1)


def strict_agent_crossings(corners: torch.Tensor) -> torch.Tensor:
    """[E, A] True where an edge of the agent's rectangle strictly crosses an edge of another's
    (corners [E, A, 4, 2]). Touching and containment are not crossings."""
    a, d = _edges(corners)
    ai, di = a[:, :, None, :, None], d[:, :, None, :, None]  # [E, i, 1, 4, 1, 2]
    aj, dj = a[:, None, :, None], d[:, None, :, None]  # [E, 1, j, 1, 4, 2]
    hit = _strict(ai, di, aj, dj).flatten(-2).any(-1)  # [E, i, j]
    eye = torch.eye(corners.shape[1], dtype=torch.bool, device=corners.device)
    return (hit & ~eye).any(-1)


def strict_lane_crossings(corners: torch.Tensor, bounds: torch.Tensor) -> torch.Tensor:
    """[E, A] True where an edge of the rectangle strictly crosses a segment of its route's raw
    boundary polylines (`segment_table` rows [E, A, 5, 2, S], the whole polylines)."""
    a, d = _edges(corners)
    a, d = a[..., None, :, None, :], d[..., None, :, None, :]  # [E, A, 1, 4, 1, 2]
    b = bounds[..., 0:2, :, :].movedim(-3, -1)[..., :, None, :, :]  # [E, A, 2, 1, S, 2]
    e = bounds[..., 2:4, :, :].movedim(-3, -1)[..., :, None, :, :]
    return _strict(a, d, b, e).flatten(-3).any(-1)


# ---- the paper's geometry on raw map vertices ----------------------------------------------
def densify(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The polyline with every segment longer than DENSIFY[0] cut into equal pieces of at most
    DENSIFY[1]; and per original segment its first piece's index and its number of pieces."""
    length = np.linalg.norm(np.diff(points, axis=0), axis=-1)
    return cut(points, np.where(length > DENSIFY[0] + 1e-9, np.ceil(length / DENSIFY[1] - 1e-9), 1).astype(int))


def cut(points: np.ndarray, pieces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The polyline with segment j cut into pieces[j] equal pieces; per segment its first piece's
    index, and `pieces`."""
    seg = np.diff(points, axis=0)
    parts = [points[j] + np.arange(n)[:, None] / n * seg[j] for j, n in enumerate(pieces)]
    return np.concatenate([*parts, points[-1:]]), np.concatenate([[0], np.cumsum(pieces)[:-1]]), pieces


def _raw_center(road_map: RoadMap, route) -> np.ndarray:
    line = join_polylines(road_map.lanelets[i].center for i in route.lanelet_ids)
    if route.is_loop:
        line = join_polylines([line, line[:1]])
    line = densify(line)[0]
    return line if route.is_loop else extend_straight(line, *RAW_EXTENSION)


def _indices(j: torch.Tensor, n: torch.Tensor, loop: torch.Tensor) -> torch.Tensor:
    """Vertex indices j [...] on polylines of n vertices: wrapped on closed loops (whose last
    vertex repeats the first), clamped otherwise."""
    return torch.where(loop, torch.remainder(j, n - 1), j.clamp(min=0).minimum(n - 1))


def _pad_ids(ids: list[np.ndarray], n_routes: int) -> torch.Tensor:
    """Per-segment integers of each route's two boundaries, padded: [R, 2, S]."""
    n = max(len(i) for i in ids)
    return torch.as_tensor(np.stack([np.pad(i, (0, n - len(i)), mode="edge") for i in ids])).view(n_routes, 2, n)


def _pad(lines: list[np.ndarray]) -> tuple[torch.Tensor, torch.Tensor]:
    n = max(len(p) for p in lines)
    table = torch.stack([torch.as_tensor(np.concatenate([p, p[-1:].repeat(n - len(p), 0)])) for p in lines])
    return table, torch.tensor([len(p) for p in lines])


class RawGeometry:
    """The paper's center-line distance and reference points on the raw center line, and M4's
    boundary points at raw boundary vertices, for all agents at once."""

    def __init__(self, bank: RouteBank, road_map: RoadMap, ref_stride: int, n_ref: int, device, dtype=torch.float32):
        routes = road_map.routes
        loop = bank.is_loop.cpu()
        raw, n_raw = _pad([_raw_center(road_map, r) for r in routes])  # [R, V, 2] float64
        # The raw segment that goes with each resampled center point, followed along the route.
        center = bank.lines[:, 0].cpu().double()
        dist = segment_distances(center, segment_table(raw.unsqueeze(1)))  # [R, 1, M, V-1]
        near = follow_line(dist, (n_raw - 1).unsqueeze(-1), bank.n_center.cpu(), loop)[:, 0]  # [R, M]
        offsets = torch.arange(*RAW_WINDOW)
        idx = _indices(near.unsqueeze(-1) + offsets, n_raw[:, None, None], loop[:, None, None])
        r = torch.arange(len(routes))[:, None, None].expand_as(idx)
        window = raw[r, idx]  # [R, M, W, 2]
        self.window = window.flatten(0, 1).to(dtype=dtype, device=device)  # [R * M, W, 2]
        self.segments = segment_table(window[..., : RAW_SEGMENTS + 1, :].unsqueeze(-3)).flatten(0, 1)
        self.segments = self.segments.to(dtype=dtype, device=device)  # [R * M, 5, 1, S]
        first = -RAW_WINDOW[0]  # the slot of the segment that goes with the point
        self.ref_steps = torch.arange(1, n_ref + 1, device=device) * ref_stride
        if RAW_SEGMENTS - 1 + int(self.ref_steps[-1]) >= RAW_WINDOW[1] - RAW_WINDOW[0] or first >= RAW_SEGMENTS:
            raise ValueError("the raw reference points reach past the raw center-line window")
        # M4: the corridor boundaries as (densified) raw vertices, where each raw segment's
        # pieces start, and the boundary windows' segment ids.
        dense = [densify(b.numpy()) for r in routes for b in (r.left, r.right)]
        bounds, n_bounds = _pad([d[0] for d in dense])
        self.bound_points = bounds.view(len(routes), 2, -1, 2).to(dtype=dtype, device=device)
        self.n_bound = n_bounds.view(len(routes), 2).to(device)
        first, pieces = (_pad_ids([d[k] for d in dense], len(routes)).to(device) for k in (1, 2))
        self.piece_first, self.pieces = first, pieces  # [R, 2, S]
        self.loop = bank.is_loop
        self.bound_ids = bank._bound_window[bank.reach].flatten(0, 1)  # [R * M, 2, S_w]
        self.bound_table = bank.boundary_window_table(bank.reach)  # [R * M, 5, 2, S_w]
        self.side_offsets = torch.arange(*SIDE_VERTICES, device=device)

    def center(self, pos: torch.Tensor, rows: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Distance [E, A] to the raw center line, and the reference points [E, A, P, 2]: the
        vertices +2, +4, +6 from the start of the closest raw segment."""
        dist, seg = nearest_on_segments(pos.unsqueeze(-2), self.segments[rows])  # [E, A, 1, 1]
        slots = seg[..., 0, :] + self.ref_steps  # [E, A, P]
        refs = self.window[rows].gather(-2, slots.unsqueeze(-1).expand(*slots.shape, 2))
        return dist[..., 0, 0], refs

    def side_points(self, pos: torch.Tensor, route: torch.Tensor, rows: torch.Tensor) -> torch.Tensor:
        """[E, A, 2, 5, 2]: per side, the raw boundary vertices from one before to three after
        the start of that boundary's own closest segment (within the boundary window)."""
        table = self.bound_table[rows]  # [E, A, 5, 2, S_w]
        _, seg = nearest_on_segments(pos.unsqueeze(-2), table)  # [E, A, 2, 1]
        j = self.bound_ids[rows].gather(-1, seg)  # [E, A, 2, 1] raw segment id
        # the piece of that segment the closest point lies on: its projection t in [0, 1]
        ax, ay, dx, dy, inv = table.gather(-1, seg.unsqueeze(-3).expand(*seg.shape[:-2], 5, 2, 1)).unbind(-3)
        t = (((pos[..., 0, None, None] - ax) * dx + (pos[..., 1, None, None] - ay) * dy) * inv).clamp(0, 1)
        side = torch.arange(2, device=pos.device)[:, None]
        n = self.pieces[route[..., None, None], side, j]
        start = self.piece_first[route[..., None, None], side, j] + (t * n).long().clamp(max=n - 1)
        idx = _indices(start + self.side_offsets, self.n_bound[route].unsqueeze(-1),
                       self.loop[route][..., None, None])  # [E, A, 2, 5]
        points = self.bound_points[route]  # [E, A, 2, V, 2]
        return points.gather(-2, idx.unsqueeze(-1).expand(*idx.shape, 2))
