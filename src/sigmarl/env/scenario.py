"""The traffic scenario: a VMAS `BaseScenario` whose work is batched over envs and agents.

VMAS asks a scenario for each agent's action, observation, reward and info one
agent at a time. Here those calls only read or write slices of [E, A] tensors:
the step is computed once for all agents in `post_step`, and resets requested
per environment are collected and carried out as one batch when the next
observation is read. Vehicles are not integrated by VMAS' physics; the
kinematic single-track model runs on our own state tensors.

The work is split by what it does: `ego` (each agent's own geometry against its route),
`step_phases` (the phases of `post_step`) and `resets` (batched resets, respawns, placed states).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import torch
from vmas.simulator.core import Agent, Box, World
from vmas.simulator.scenario import BaseScenario

from sigmarl.env import paper_rules as paper
from sigmarl.env.ego import LENGTH, WIDTH, EgoTables
from sigmarl.env.observation import WORLD_SIZE, ObsInputs, build_observation
from sigmarl.env.resets import Resets
from sigmarl.env.route_bank import RouteBank
from sigmarl.env.spawn import spawn_index_range
from sigmarl.env.step_phases import StepPhases
from sigmarl.env.streams import SeedStreams
from sigmarl.maps.model import RoadMap
from sigmarl.params import DT

if TYPE_CHECKING:
    from sigmarl.config import ObsConfig, RulesConfig
    from sigmarl.config.reward import RewardConfig
    from sigmarl.config.vehicle import VehicleConfig


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



class TrafficScenario(Resets, StepPhases, BaseScenario):
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
        self.ego = EgoTables(self.bank, self.n_ref, self.ref_stride, device)
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
        self._eye_big = torch.eye(self.n_agents, device=device) * 1e9
        self._alloc(batch_dim, device)
        self.per_agent_infos = True
        self.compute_reward = True  # the evaluation reads no reward and turns it off
        self.spawn_table = self.ego.spawn_table()
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
        self.reward_speed_scale = paper.reward_speed_scale(rules)
        self.reset_speed = paper.reset_speed_limit(rules, self.max_speed)
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

    def _geometry(self) -> None:
        """Everything observation, reward and info read, for all agents at once."""
        self.geo = self.ego.geometry(self.pos, self.heading, self.route, self.index)
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

    def _record_step_end(self) -> None:
        """Metrics of the state the step ended in, and its poses, kept before anyone respawns
        (infos report them; rendering draws test-mode collisions where they happened)."""
        self.step_d_center, self.step_speed = self.geo.d_center, self.speed.abs()
        self.step_pos, self.step_heading = self.pos, self.heading

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

    # ---- VMAS hooks ------------------------------------------------------------------------
    def process_action(self, agent: Agent) -> None:
        self.action[:, self._agent_index[agent.name]] = agent.action.u

    def post_step(self) -> None:
        """One step of every environment and agent, in phases (`step_phases`)."""
        if self.obs is None:
            self._refresh()
        prev_pos, prev_ref = self.pos, self.obs_ref_points
        self._move()
        self._progress_index()
        self._geometry()
        self._collisions()
        hit_agent, hit_lane = self._scored_contacts()
        if self.compute_reward:  # the evaluation never reads it
            self._score(prev_pos, prev_ref, hit_agent, hit_lane)
        self._record_step_end()
        self._end_episodes(hit_agent | hit_lane)
        self._respawn_and_observe()

    def observation(self, agent: Agent) -> torch.Tensor:
        return self.current_observation()[:, self._agent_index[agent.name]]

    def reward(self, agent: Agent) -> torch.Tensor:
        return self.rew[:, self._agent_index[agent.name]]

    def done(self) -> torch.Tensor:
        self.current_observation()  # resets still pending are carried out first
        return self.terminated

    def info(self, agent: Agent) -> dict[str, torch.Tensor]:
        if not self.per_agent_infos:  # TrafficEnv reads `infos()` for all agents at once
            return {}
        i = self._agent_index[agent.name]
        return {key: value[:, i, 0] for key, value in self.infos().items()}
