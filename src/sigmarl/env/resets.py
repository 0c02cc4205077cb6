"""The scenario's resets: environments marked for a reset, respawned as one batch when the next
observation is read; respawns of single agents; and states placed by hand.

A mixin of `TrafficScenario`: its methods read and rebind the scenario's [E, A] state tensors."""

from __future__ import annotations

import torch

from sigmarl.env.spawn import sample_spawns


class Resets:
    """Reset and respawn methods of `TrafficScenario` (see the module's docstring)."""

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
        speed = self.rng.rand(self._per_seed(place.shape), self.rng.active(place)) * self.reset_speed
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

    def _spawn_geometry(self, place: torch.Tensor) -> None:
        """Geometry after the agents where `place` [E, A] were respawned (`EgoTables.spawn_table`)."""
        fresh = self.spawn_table.take(self.bank.row(self.route, self.index))
        # Everyone is respawned at the first reset, before any geometry exists.
        self.geo = fresh if bool(place.all()) else fresh.where(place, self.geo)
        self._neighbour_geometry()
        if self.raw_geo is not None:
            self._raw_geometry()

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
