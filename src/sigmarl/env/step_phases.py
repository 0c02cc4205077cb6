"""The phases of one batched step of every environment and agent (`TrafficScenario.post_step`):
move the vehicles, find their progress, detect collisions, score the step, end episodes and
respawn the agents that are done.

A mixin of `TrafficScenario`: its methods read and rebind the scenario's [E, A] state tensors."""

from __future__ import annotations

import torch

from sigmarl.env import paper_rules as paper
from sigmarl.env.collision import pairwise_box_overlap
from sigmarl.env.dynamics import bicycle_step
from sigmarl.env.ego import LENGTH, WIDTH
from sigmarl.env.reward import RewardInputs, reward_terms, total_reward
from sigmarl.params import DT


class StepPhases:
    """Per-step phase methods of `TrafficScenario` (see the module's docstring)."""

    def _move(self) -> None:
        """Clamp the commands and integrate the vehicles one sample time."""
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

    def _progress_index(self) -> None:
        """Closest center-line point, searched in a window ahead/behind the last one."""
        b = self.bank
        idx = b.center_index(self.route, self.index.unsqueeze(-1) + self.ego.center_offsets)
        pts = b.center[self.route.unsqueeze(-1).expand_as(idx), idx]
        d = (pts - self.pos.unsqueeze(-2)).norm(dim=-1)
        self.index = idx.gather(-1, d.argmin(-1, keepdim=True)).squeeze(-1)

    def _collisions(self) -> None:
        self.agent_collision = pairwise_box_overlap(self.pos, self.heading, LENGTH, WIDTH).any(-1)
        self.lane_collision = self.geo.side_hit.any(-1)

    def _scored_contacts(self) -> tuple[torch.Tensor, torch.Tensor]:
        """What the reward and the episode's end read: our contacts, or the paper's strict
        crossings (the infos, hence the metrics, keep ours)."""
        if self.rules.strict_crossings:
            return (paper.strict_agent_crossings(self.geo.corners),
                    paper.strict_lane_crossings(self.geo.corners, self.bank.bounds[self.route]))
        return self.agent_collision, self.lane_collision

    def _score(self, prev_pos, prev_ref, hit_agent, hit_lane) -> None:
        """The step's reward terms and total (the evaluation never reads them)."""
        steering, prev_steering = self.steering, self.prev_steering
        if self.rules.lagged_steering:  # the paper compared the previous two actions
            steering, prev_steering = self.prev_steering, self.prev2_steering
        self.terms = reward_terms(
            RewardInputs(
                pos=self.pos, prev_pos=prev_pos, vel=self.vel, prev_ref_points=prev_ref,
                d_boundary=self.geo.d_side.min(-1).values,
                distances=self.distances, d_center=self.geo.d_center if self.d_line is None else self.d_line,
                steering=steering, prev_steering=prev_steering,
                agent_collision=hit_agent, lane_collision=hit_lane,
            ), self.reward_weights, self.reward_speed_scale)
        self.rew = total_reward(self.terms)

    def _past_exit(self) -> torch.Tensor:
        """Non-loop agents whose center has passed the route's last real point."""
        b = self.bank
        last = b.n_points[self.route] - 1
        end = b.center[self.route, last]
        direction = torch.stack([b.heading[self.route, last].cos(), b.heading[self.route, last].sin()], -1)
        beyond = ((self.pos - end) * direction).sum(-1) > 0
        return ~b.is_loop[self.route] & (self.index >= last) & beyond

    def _end_episodes(self, collided: torch.Tensor) -> None:
        """Who is done: in training a collision ends its environment and an exit respawns the
        agent; in a test both respawn the agent."""
        exited = self._past_exit()
        if self.rules.env_lane_flag:  # the paper's info flag: any lane collision in the environment
            self.lane_collision = self.lane_collision.any(-1, keepdim=True).expand_as(self.lane_collision)
        if self.train:
            self.terminated = collided.any(-1)
            self.respawned = exited & ~self.terminated.unsqueeze(-1)
        else:
            self.terminated = torch.zeros_like(self.terminated)
            self.respawned = exited | collided

    def _respawn_and_observe(self) -> None:
        """Respawn the agents that are done and observe the new state."""
        stale = None
        if self.respawned.any():
            if self.rules.stale_respawn_obs and not self.train:  # the paper's: the pre-respawn observation
                self._observe()
                stale = self.obs
            self._respawn(self.respawned)
            self._spawn_geometry(self.respawned)
        self._observe()
        if stale is not None:
            self.obs = torch.where(self.respawned.unsqueeze(-1), stale, self.obs)
