"""The traffic scenario: a VMAS `BaseScenario` whose work is batched over envs and agents.

VMAS asks a scenario for each agent's action, observation, reward and info one
agent at a time. Here those calls only read or write slices of [E, A] tensors:
the step is computed once for all agents in `post_step`, and resets requested
per environment are collected and carried out as one batch when the next
observation is read. Vehicles are not integrated by VMAS' physics; the
kinematic single-track model runs on our own state tensors.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, fields, replace
from typing import TYPE_CHECKING

import torch
from vmas.simulator.core import Agent, Box, World
from vmas.simulator.scenario import BaseScenario

from sigmarl.env import paper_rules as paper
from sigmarl.env.collision import (
    crossings_odd,
    nearest_on_segments,
    pairwise_box_overlap,
    segment_table,
    segments_box_overlap,
)
from sigmarl.env.dynamics import bicycle_step
from sigmarl.env.geometry import rect_corners
from sigmarl.env.observation import WORLD_SIZE, ObsInputs, build_observation
from sigmarl.env.params import DT, VEHICLE
from sigmarl.env.reward import RewardInputs, reward_terms, total_reward
from sigmarl.env.route_bank import CENTER, HALF_DIAGONAL, RouteBank
from sigmarl.env.spawn import sample_spawns, spawn_index_range
from sigmarl.env.streams import SeedStreams
from sigmarl.maps.model import RoadMap

if TYPE_CHECKING:
    from sigmarl.config import ObsConfig, RulesConfig
    from sigmarl.reward_config import RewardConfig
    from sigmarl.vehicle_config import VehicleConfig

LENGTH, WIDTH = VEHICLE.length, VEHICLE.width
# Windows of points around an agent's progress index (spacing 0.08 m). Boundary distances and
# contacts use windows of raw boundary segments instead (RouteBank.boundary_window_table).
CENTER_WINDOW = (-3, 8)  # progress search: an agent moves at most 0.04 m per step
LINE_WINDOW = (-6, 7)  # center-line distance and reference points: +-0.48 m of center line
SIDE_WINDOW = (-1, 4)  # observed boundary points: 1 behind .. 3 ahead of the closest
# Margin of the exactness check against float32 rounding of the distances it adds up.
_REACH_MARGIN = 1e-3  # m


@dataclass(frozen=True)
class ScenarioSettings:
    """Everything the scenario is built from (`make_env` fills it from the config)."""

    road_map: RoadMap
    flags: ObsConfig  # the observation design
    n_agents: int
    mode: str  # train | test
    noise: float  # total width of the zero-mean uniform observation noise
    ref_point_stride: int  # center points between reference points
    spawn_start_m: float
    spawn_end_fraction: float
    spawn_margin_m: float
    seed: int  # the spawn and noise generators' seed
    rules: RulesConfig  # the paper's rules switched on (none: ours)
    reward: RewardConfig  # the reward's weights and shaping scales (env.reward.*)
    vehicle: VehicleConfig  # the vehicle's limits (env.vehicle.*)
    # a seed block's seeds, seed k driving environments [k E/S, (k+1) E/S) (`env.streams`);
    # empty: one seed, `seed`
    seeds: tuple[int, ...] = ()


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


def _proven(probe: torch.Tensor, center: torch.Tensor, dist: torch.Tensor, reach: float) -> torch.Tensor:
    """[...] True where a boundary window reaching `reach` around `center` [..., 2] provably
    gives the exact distances dist [..., 2, 5] of the probes [..., 5, 2] (center first) and
    holds every segment the box can touch."""
    room = reach - _REACH_MARGIN - (probe - center.unsqueeze(-2)).norm(dim=-1)  # [..., 5]
    return (dist <= room.unsqueeze(-2)).flatten(-2).all(-1) & (room[..., 0] >= HALF_DIAGONAL)


class TrafficScenario(BaseScenario):
    """Connected automated vehicles following routes on a road map."""

    def make_world(self, batch_dim: int, device: torch.device, **kwargs) -> World:
        # VMAS passes the scenario's settings as keyword arguments: one typed object, built by
        # `make_env` from the config, so no default is stated twice.
        settings: ScenarioSettings = kwargs["settings"]
        self.road_map = settings.road_map  # what renderers draw
        self.flags = settings.flags
        self.n_agents = settings.n_agents
        self.train = settings.mode == "train"
        self.noise = settings.noise
        self.n_ref = self.flags.n_ref_points
        self.ref_stride = settings.ref_point_stride
        self.bank = RouteBank(settings.road_map, device)
        self.spawn_lo, self.spawn_hi = spawn_index_range(
            self.bank,
            train=self.train,
            start_m=settings.spawn_start_m,
            end_fraction=settings.spawn_end_fraction,
            margin_m=settings.spawn_margin_m,
        )
        seeds = settings.seeds or (settings.seed,)
        if batch_dim % len(seeds):
            raise ValueError(f"{batch_dim} environments do not split into {len(seeds)} seeds")
        self.n_seeds = len(seeds)
        self.rng = SeedStreams(self.n_seeds, device)
        self.noise_rng = SeedStreams(self.n_seeds, device)
        self.seed(seeds)
        self._init_rules(settings)

        world = World(batch_dim, device, dt=DT, substeps=1, drag=0.0)
        for i in range(self.n_agents):
            world.add_agent(
                Agent(
                    name=f"agent_{i}",
                    shape=Box(length=LENGTH, width=WIDTH),
                    collide=False,
                    movable=False,  # our own dynamics move the vehicles
                    rotatable=False,
                    u_range=[self.command_limit, self.max_steer],
                    render_action=False,
                )
            )
        self._agent_index = {a.name: i for i, a in enumerate(world.agents)}
        ar = lambda lo, hi: torch.arange(lo, hi, device=device)  # noqa: E731
        self._center_offsets = ar(*CENTER_WINDOW)
        self._line_offsets = ar(*LINE_WINDOW)
        self._side_offsets = ar(*SIDE_WINDOW)
        # Reference points: +2, +4, +6 center points ahead, as slots of the line window.
        self._ref_slots = -LINE_WINDOW[0] + ar(1, self.n_ref + 1) * self.ref_stride
        if int(self._ref_slots[-1]) >= LINE_WINDOW[1] - LINE_WINDOW[0]:
            raise ValueError("obs.n_ref_points x obs.ref_point_stride must be at most 6")
        self._eye_big = torch.eye(self.n_agents, device=device) * 1e9
        self._alloc(batch_dim, device)
        self.per_agent_infos = True
        self.compute_reward = True  # the evaluation reads no reward and turns it off
        self._line_table = self.bank.window_table("lines", self._line_offsets)
        self._side_table = self.bank.window_table("sides", self._side_offsets)
        self._segment_table = segment_table(self._line_table)
        self._bound_table = self.bank.boundary_window_table(self.bank.reach)
        self._wide_table = self.bank.boundary_window_table(self.bank.wide_reach)
        self.spawn_table = self._spawn_table()
        if self.rules.raw_center_line or (self.rules.own_boundary_index and not self.flags.distance_to_boundaries):
            self.raw_geo = paper.RawGeometry(self.bank, self.road_map, self.ref_stride, self.n_ref, device)
        return world

    def _init_rules(self, settings: ScenarioSettings) -> None:
        """What the paper's rules (`paper_rules`) change, decided once here, not per step."""
        rules = self.rules = settings.rules
        self.reward_weights = settings.reward
        self.max_speed, self.max_steer = settings.vehicle.max_speed, settings.vehicle.max_steering
        self.command_limit = paper.COMMAND_LIMIT if rules.drag_dynamics else self.max_speed
        self.obs_world = paper.test_world(self.road_map) if rules.test_world_size and not self.train else WORLD_SIZE
        self.obs_speed_scale = paper.speed_scale(rules)
        self.raw_geo: paper.RawGeometry | None = None
        self.d_line = None  # raw center-line distance (raw_center_line), else geo.d_center

    def seed(self, seed: int | Sequence[int]) -> None:
        """Reseed the spawn and the noise generators (separate streams, so that spawns do not
        depend on how much noise an observation design draws); a block takes one seed per seed."""
        seeds = [seed] if isinstance(seed, int) else list(seed)
        self.rng.seed(seeds)
        self.noise_rng.seed([s + 7919 for s in seeds])

    # ---- state -------------------------------------------------------------------------
    def _alloc(self, n_env: int, device) -> None:
        z = lambda *s: torch.zeros(n_env, self.n_agents, *s, device=device)  # noqa: E731
        self.pos, self.vel, self.heading, self.speed = z(2), z(2), z(), z()
        self.steering, self.prev_steering = z(), z()
        self.prev2_steering, self.yaw_rate = z(), z()  # lagged_steering, drag_dynamics
        self.action = z(2)
        self.route = torch.zeros(n_env, self.n_agents, dtype=torch.long, device=device)
        self.index = torch.zeros_like(self.route)
        self.agent_collision = torch.zeros(n_env, self.n_agents, dtype=torch.bool, device=device)
        self.lane_collision = torch.zeros_like(self.agent_collision)
        self.respawned = torch.zeros_like(self.agent_collision)
        self.terminated = torch.zeros(n_env, dtype=torch.bool, device=device)
        self.rew = z()
        self.terms: dict[str, torch.Tensor] = {}
        self.obs: torch.Tensor | None = None
        self.last_obs: torch.Tensor | None = None  # before a reset (what a block's other seeds keep)
        self.pending_reset = torch.ones(n_env, dtype=torch.bool, device=device)

    def reset_world_at(self, env_index: int | None = None) -> None:
        # Only mark: the reset itself runs batched when the observation is next read.
        if env_index is None:
            self.pending_reset[:] = True
        else:
            self.pending_reset[env_index] = True
        self._drop_obs()

    def reset_envs(self, mask: torch.Tensor) -> None:
        """Mark several environments for a reset at once (batched counterpart of reset_world_at)."""
        self.pending_reset |= mask
        self._drop_obs()

    def _drop_obs(self) -> None:
        if self.obs is not None:
            self.last_obs = self.obs
        self.obs = None

    def current_observation(self) -> torch.Tensor:
        """[E, A, D] observation of the current state (carrying out pending resets first)."""
        if self.obs is None:
            self._refresh()
        return self.obs

    def infos(self) -> dict[str, torch.Tensor]:
        """Per-agent infos of the last step, [E, A, 1] each."""
        return {
            "agent_collision": self.agent_collision.unsqueeze(-1).float(),
            "lane_collision": self.lane_collision.unsqueeze(-1).float(),
            "distance_to_center_line": self.step_d_center.unsqueeze(-1),
            "speed": self.step_speed.unsqueeze(-1),
            "respawned": self.respawned.unsqueeze(-1).float(),
        }

    def _flush_resets(self) -> torch.Tensor | None:
        """Respawn every agent of the environments marked for a reset; returns where [E, A]."""
        envs = self.pending_reset
        if not envs.any():
            return None
        place = envs.unsqueeze(-1).expand(-1, self.n_agents)
        self._respawn(place)
        # Rebound, never written in place: the last step's output still holds these tensors
        # (an in-place write here once zeroed the collision penalty of every terminal step).
        self.agent_collision = self.agent_collision & ~place
        self.lane_collision = self.lane_collision & ~place
        self.respawned = self.respawned & ~place
        self.rew = self.rew.masked_fill(place, 0.0)
        self.terminated = self.terminated & ~envs
        self.pending_reset = torch.zeros_like(envs)
        return place

    def _respawn(self, place: torch.Tensor) -> None:
        """New route, position, heading and speed for the agents where `place` is True."""
        # Agents being replaced do not block the sampler: park them far away.
        pos = torch.where(place.unsqueeze(-1), torch.full_like(self.pos, 1e6), self.pos)
        route, idx = sample_spawns(self.bank, pos, place, self.spawn_lo, self.spawn_hi, self.rng)
        speed = self.rng.rand(self._per_seed(place.shape), self.rng.active(place)) * self.max_speed
        heading = self.bank.heading[route, idx]
        self.route = torch.where(place, route, self.route)
        self.index = torch.where(place, idx, self.index)
        self.pos = torch.where(place.unsqueeze(-1), self.bank.center[route, idx], self.pos)
        self.heading = torch.where(place, heading, self.heading)
        self.speed = torch.where(place, speed, self.speed)
        vel = speed.unsqueeze(-1) * torch.stack([heading.cos(), heading.sin()], -1)
        self.vel = torch.where(place.unsqueeze(-1), vel, self.vel)
        self.steering = torch.where(place, torch.zeros_like(self.steering), self.steering)
        self.prev_steering = torch.where(place, torch.zeros_like(self.steering), self.prev_steering)
        if self.rules.lagged_steering or self.rules.drag_dynamics:
            self.prev2_steering = self.prev2_steering.masked_fill(place, 0.0)
            self.yaw_rate = self.yaw_rate.masked_fill(place, 0.0)

    # ---- per-step geometry ---------------------------------------------------------------
    def _progress_index(self) -> None:
        """Closest center-line point, searched in a window ahead/behind the last one."""
        b = self.bank
        idx = b.center_index(self.route, self.index.unsqueeze(-1) + self._center_offsets)
        pts = b.center[self.route.unsqueeze(-1).expand_as(idx), idx]
        d = (pts - self.pos.unsqueeze(-2)).norm(dim=-1)
        self.index = idx.gather(-1, d.argmin(-1, keepdim=True)).squeeze(-1)

    def _ego_geometry(self, pos, heading, route, index) -> EgoGeometry:
        b = self.bank
        corners = rect_corners(pos, heading, LENGTH, WIDTH)  # [E, A, 4, 2]
        rows = b.row(route, index)
        lines = self._line_table[rows]  # center-line window: [E, A, 1, W, 2]
        d_center = nearest_on_segments(pos.unsqueeze(-2), self._segment_table[rows])[0][..., CENTER, 0]
        probe = torch.cat([pos.unsqueeze(-2), corners], dim=-2)  # [E, A, 5, 2]
        sides, side_hit = self._boundaries(probe, pos, heading, b.center[route, index], rows)
        return EgoGeometry(
            corners=corners,
            d_center=d_center,
            d_side=torch.minimum(sides[..., 0] - WIDTH / 2, sides[..., 1:].min(-1).values),
            ref_points=lines[..., CENTER, self._ref_slots, :],
            side_hit=side_hit,
            side_points=self._side_table[rows],
        )

    def _boundaries(self, probe, pos, heading, center, rows) -> tuple[torch.Tensor, torch.Tensor]:
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
        dist, hit = self._boundary_contacts(probe, pos, heading, center, self._bound_table[rows])
        exact = _proven(probe, center, dist, self.bank.reach)
        if not bool(exact.all()):
            far = (~exact).nonzero(as_tuple=True)
            p, c = probe[far], center[far]
            d, h = self._boundary_contacts(p, pos[far], heading[far], c, self._wide_table[rows[far]])
            h = h | ~_proven(p, c, d, self.bank.wide_reach).unsqueeze(-1)
            dist, hit = dist.index_put(far, d), hit.index_put(far, h)
        return dist, hit

    def _boundary_contacts(self, probe, pos, heading, center, table) -> tuple[torch.Tensor, torch.Tensor]:
        """Distances [..., 2, 5] and contact [..., 2] against boundary segments [..., 5, 2, S]."""
        dist, _ = nearest_on_segments(probe, table)
        # The box touches a boundary, or its center is already beyond one: the way from the
        # center-line point (inside the corridor) to the center crosses that boundary an odd
        # number of times. (A side test against the nearest segment got this wrong where a
        # corridor narrows in a step and at backtracking vertices: false contacts on CPM.)
        outside = crossings_odd(center, pos, table)
        touch = segments_box_overlap(table, pos, heading, LENGTH, WIDTH)
        return dist, touch | outside

    def _geometry(self) -> None:
        """Everything observation, reward and info read, for all agents at once."""
        self.geo = self._ego_geometry(self.pos, self.heading, self.route, self.index)
        self._neighbour_geometry()
        if self.raw_geo is not None:
            self._raw_geometry()

    def _raw_geometry(self) -> None:
        """The paper's reference points, center-line distance (raw_center_line) and M4 boundary
        points (own_boundary_index) in place of ours; geo.d_center stays ours, for the metrics."""
        rows = self.bank.row(self.route, self.index)
        changes = {}
        if self.rules.raw_center_line:
            self.d_line, changes["ref_points"] = self.raw_geo.center(self.pos, rows)
        if self.rules.own_boundary_index and not self.flags.distance_to_boundaries:
            changes["side_points"] = self.raw_geo.side_points(self.pos, self.route, rows)
        self.geo = replace(self.geo, **changes)

    def _neighbour_geometry(self) -> None:
        self.distances = torch.cdist(self.pos, self.pos)
        masked = self.distances + self._eye_big
        self.neighbours = masked.topk(self.flags.n_nearest, dim=-1, largest=False, sorted=True).indices

    def _spawn_table(self) -> EgoGeometry:
        """Ego geometry of a vehicle standing on each center-line point, heading along the
        route: [R * M, ...] rows (`RouteBank.row`). Spawns are such poses, so a respawn reads
        its geometry here instead of recomputing it (a second geometry pass would cost as much
        as the step's)."""
        b = self.bank
        route, index = b.every_point()
        return self._ego_geometry(b.center[route, index], b.heading[route, index], route, index)

    def _spawn_geometry(self, place: torch.Tensor) -> None:
        """Geometry after the agents where `place` [E, A] were respawned (see `_spawn_table`)."""
        fresh = self.spawn_table.take(self.bank.row(self.route, self.index))
        # Everyone is respawned at the first reset, before any geometry exists.
        self.geo = fresh if bool(place.all()) else fresh.where(place, self.geo)
        self._neighbour_geometry()
        if self.raw_geo is not None:
            self._raw_geometry()

    def _record_step_end(self) -> None:
        """Metrics of the state the step ended in, and its poses, kept before anyone respawns
        (infos report them; rendering draws test-mode collisions where they happened)."""
        self.step_d_center, self.step_speed = self.geo.d_center, self.speed.abs()
        self.step_pos, self.step_heading = self.pos, self.heading

    def _collisions(self) -> None:
        self.agent_collision = pairwise_box_overlap(self.pos, self.heading, LENGTH, WIDTH).any(-1)
        self.lane_collision = self.geo.side_hit.any(-1)

    def _past_exit(self) -> torch.Tensor:
        """Non-loop agents whose center has passed the route's last real point."""
        b = self.bank
        last = b.n_points[self.route] - 1
        end = b.center[self.route, last]
        direction = torch.stack([b.heading[self.route, last].cos(), b.heading[self.route, last].sin()], -1)
        beyond = ((self.pos - end) * direction).sum(-1) > 0
        return ~b.is_loop[self.route] & (self.index >= last) & beyond

    def _per_seed(self, shape: Sequence[int]) -> tuple[int, ...]:
        """One seed's share of a [S * E, ...] shape."""
        return (shape[0] // self.n_seeds, *shape[1:])

    def _observe(self, active: list[bool] | None = None) -> None:
        """The observation of the current state; in a block only for the seeds `active` names
        (a lone run of the others would not observe now: they keep theirs, and draw no noise)."""
        rules = self.rules
        speed = self.speed.abs() if rules.unsigned_speed else self.speed
        ego = self.flags.ego_view and rules.others_velocity_heading
        vel = paper.heading_velocity(self.vel, self.heading) if ego else self.vel
        x = ObsInputs(
            pos=self.pos, heading=self.heading, speed=speed, vel=vel,
            ref_points=self.geo.ref_points, d_center=self.geo.d_center if self.d_line is None else self.d_line,
            d_left=self.geo.d_side[..., 0], d_right=self.geo.d_side[..., 1],
            left_points=self.geo.side_points[..., 0, :, :], right_points=self.geo.side_points[..., 1, :, :],
            corners=self.geo.corners, neighbours=self.neighbours, distances=self.distances,
            length=LENGTH, width=WIDTH, world=self.obs_world, speed_scale=self.obs_speed_scale,
            wrap_headings=not rules.unwrapped_headings,
        )
        obs = build_observation(x, self.flags)
        if self.noise > 0:
            u = self.noise_rng.rand(self._per_seed(obs.shape), active)
            obs = obs + u * self.noise if rules.one_sided_noise else obs + (u - 0.5) * self.noise
        if active is not None and not all(active) and self.last_obs is not None:
            rows = torch.tensor(active, device=obs.device).repeat_interleave(obs.shape[0] // self.n_seeds)
            obs = torch.where(rows.view(-1, 1, 1), obs, self.last_obs)
        self.obs = obs
        self.obs_ref_points = self.geo.ref_points  # what the next reward measures progress against

    def _refresh(self) -> None:
        """Observation of the current state (after resets)."""
        active = self.noise_rng.active(self.pending_reset)
        place = self._flush_resets()
        if place is not None:
            self._spawn_geometry(place)
        self._record_step_end()
        self._observe(active)

    def set_state(
        self,
        route: torch.Tensor,
        pos: torch.Tensor,
        heading: torch.Tensor,
        speed: torch.Tensor | None = None,
        steering: torch.Tensor | None = None,
    ) -> torch.Tensor:
        """Place every agent by hand ([E, A] route ids, [E, A, 2] positions, ...) and return
        the observation of that state. For tests, demos and scripted scenes."""
        self.pending_reset[:] = False
        dev = self.pos.device
        self.route = route.to(dev).long().expand_as(self.route).clone()
        self.pos = pos.to(self.pos).expand_as(self.pos).clone()
        self.heading = heading.to(self.pos).expand_as(self.heading).clone()
        self.speed = (speed.to(self.pos) if speed is not None else torch.zeros_like(self.speed)).expand_as(self.speed).clone()
        self.vel = self.speed.unsqueeze(-1) * torch.stack([self.heading.cos(), self.heading.sin()], -1)
        self.steering = (steering.to(self.pos) if steering is not None else torch.zeros_like(self.steering)).expand_as(self.steering).clone()
        self.prev_steering = self.steering.clone()
        self.prev2_steering, self.yaw_rate = self.steering.clone(), torch.zeros_like(self.speed)
        # Closest center-line point over the whole route (no previous index to search around).
        b = self.bank
        d = (b.center[self.route] - self.pos.unsqueeze(-2)).norm(dim=-1)
        invalid = torch.arange(b.center.shape[1], device=dev) >= b.n_center[self.route].unsqueeze(-1)
        self.index = d.masked_fill(invalid, float("inf")).argmin(-1)
        self._geometry()
        self._collisions()
        self._record_step_end()
        self._observe()
        return self.obs

    # ---- VMAS hooks ------------------------------------------------------------------------
    def process_action(self, agent: Agent) -> None:
        self.action[:, self._agent_index[agent.name]] = agent.action.u

    def post_step(self) -> None:
        if self.obs is None:
            self._refresh()
        prev_pos, prev_ref = self.pos, self.obs_ref_points
        rules = self.rules
        speed = self.action[..., 0].clamp(-self.command_limit, self.command_limit)
        steer = self.action[..., 1].clamp(-self.max_steer, self.max_steer)
        self.prev2_steering = self.prev_steering
        self.prev_steering = self.steering
        self.steering = steer
        if rules.drag_dynamics:
            self.pos, self.heading, self.vel, self.speed, self.yaw_rate = paper.drag_step(
                self.pos, self.heading, self.vel, self.yaw_rate, speed, steer, DT, wrap=not rules.unwrapped_headings)
        else:
            self.speed = speed
            self.pos, self.heading, self.vel = bicycle_step(self.pos, self.heading, speed, steer, DT,
                                                            wrap=not rules.unwrapped_headings)
        self._progress_index()
        self._geometry()
        self._collisions()
        # What the reward and the episode's end read: our contacts, or the paper's strict
        # crossings (the infos, hence the metrics, keep ours).
        hit_agent, hit_lane = self.agent_collision, self.lane_collision
        if rules.strict_crossings:
            hit_agent = paper.strict_agent_crossings(self.geo.corners)
            hit_lane = paper.strict_lane_crossings(self.geo.corners, self.bank.bounds[self.route])
        if self.compute_reward:  # the evaluation never reads it
            steering, prev_steering = self.steering, self.prev_steering
            if rules.lagged_steering:  # the paper compared the previous two actions
                steering, prev_steering = self.prev_steering, self.prev2_steering
            self.terms = reward_terms(
                RewardInputs(
                    pos=self.pos, prev_pos=prev_pos, vel=self.vel, prev_ref_points=prev_ref,
                    d_boundary=self.geo.d_side.min(-1).values,
                    distances=self.distances, d_center=self.geo.d_center if self.d_line is None else self.d_line,
                    steering=steering, prev_steering=prev_steering,
                    agent_collision=hit_agent, lane_collision=hit_lane,
                ), self.reward_weights)
            self.rew = total_reward(self.terms)
        self._record_step_end()
        exited = self._past_exit()
        collided = hit_agent | hit_lane
        if rules.env_lane_flag:  # the paper's info flag: any lane collision in the environment
            self.lane_collision = self.lane_collision.any(-1, keepdim=True).expand_as(self.lane_collision)
        if self.train:
            self.terminated = collided.any(-1)
            self.respawned = exited & ~self.terminated.unsqueeze(-1)
        else:
            self.terminated = torch.zeros_like(self.terminated)
            self.respawned = exited | collided
        stale = None
        if self.respawned.any():
            if rules.stale_respawn_obs and not self.train:  # the paper's: the pre-respawn observation
                self._observe()
                stale = self.obs
            self._respawn(self.respawned)
            self._spawn_geometry(self.respawned)
        self._observe()
        if stale is not None:
            self.obs = torch.where(self.respawned.unsqueeze(-1), stale, self.obs)

    def observation(self, agent: Agent) -> torch.Tensor:
        if self.obs is None:
            self._refresh()
        return self.obs[:, self._agent_index[agent.name]]

    def reward(self, agent: Agent) -> torch.Tensor:
        return self.rew[:, self._agent_index[agent.name]]

    def done(self) -> torch.Tensor:
        if self.obs is None:
            self._refresh()
        return self.terminated

    def info(self, agent: Agent) -> dict[str, torch.Tensor]:
        if not self.per_agent_infos:  # TrafficEnv reads `infos()` for all agents at once
            return {}
        i = self._agent_index[agent.name]
        return {
            "agent_collision": self.agent_collision[:, i].float(),
            "lane_collision": self.lane_collision[:, i].float(),
            "distance_to_center_line": self.step_d_center[:, i],
            "speed": self.step_speed[:, i],
            "respawned": self.respawned[:, i].float(),
        }
