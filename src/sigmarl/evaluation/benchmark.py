"""The CPM Lab benchmark's metrics (`sigmarl.metrics`: TS, CAA_100m, CAL_100m, LV_100m),
reduced on the fly over a rollout's simulations and agents, batched [E, A].

- A **collision event** is an agent's contact (agent-agent, or agent-lane: its footprint on
  the own lane's boundary) with hysteresis (`Hysteresis`): it starts after CONTACT_STEPS
  consecutive steps in contact and ends after CLEAR_STEPS consecutive steps clear; the agent's
  next contact counts only after that, so one long contact is one event.
- A **lane violation** is the distance driven in steps with a lane contact.
- **Distance** is each agent's |speed| x DT summed over steps and agents (a respawn's jump is no
  distance). Per 100 m: count x 100 / distance, undefined (NaN) under MIN_DISTANCE_M.
- **Task success**: a try starts where an agent spawns and ends at a collision (failure: the
  test respawns it) or at its goal (success): the exit of a route that has one (it respawns on
  a new route), or one lap of a looping route (the route's length driven since the try began;
  it drives on, and the next try begins). TS is successes / (successes + failures); a try still
  running when the simulation ends is not counted, and TS is undefined (NaN) where no try ended.
"""

from __future__ import annotations

import torch

from sigmarl.metrics import (
    CAA_100M,
    CAL_100M,
    CLEAR_STEPS,
    CONTACT_STEPS,
    LV_100M,
    MIN_DISTANCE_M,
    PER_M,
    TS,
)
from sigmarl.params import DT


class Hysteresis:
    """Collision events of a batch of agents' contact flags, one step at a time: an event starts
    after `contact_steps` consecutive steps in contact, and ends after `clear_steps` clear ones;
    while it lasts, no new event of that agent counts."""

    def __init__(self, shape: tuple[int, ...], device: torch.device | str = "cpu",
                 contact_steps: int = CONTACT_STEPS, clear_steps: int = CLEAR_STEPS):
        self.contact_steps, self.clear_steps = contact_steps, clear_steps
        self.in_event = torch.zeros(shape, dtype=torch.bool, device=device)
        self.contact_run = torch.zeros(shape, dtype=torch.long, device=device)
        self.clear_run = torch.zeros(shape, dtype=torch.long, device=device)

    def step(self, contact: torch.Tensor) -> torch.Tensor:
        """The events that start at this step ([shape] bool), given its contact flags."""
        self.contact_run = torch.where(contact, self.contact_run + 1, 0)
        self.clear_run = torch.where(contact, 0, self.clear_run + 1)
        start = ~self.in_event & (self.contact_run >= self.contact_steps)
        self.in_event = (self.in_event | start) & ~(self.clear_run >= self.clear_steps)
        return start


class BenchmarkSums:
    """Per-simulation sums of a rollout, [E] each, and the per-agent state they need [E, A]."""

    def __init__(self, n_sims: int, n_agents: int, device: torch.device | str):
        zeros = lambda: torch.zeros(n_sims, dtype=torch.float32, device=device)  # noqa: E731
        self.distance, self.violation = zeros(), zeros()  # m: driven; driven in a lane contact
        self.aa_events, self.al_events = zeros(), zeros()
        self.successes, self.failures = zeros(), zeros()
        self.aa = Hysteresis((n_sims, n_agents), device)
        self.al = Hysteresis((n_sims, n_agents), device)
        self.try_distance = torch.zeros(n_sims, n_agents, dtype=torch.float32, device=device)
        self.goal: torch.Tensor | None = None  # m to drive for a lap; inf on a route with an exit

    def add(self, contact_aa: torch.Tensor, contact_al: torch.Tensor, speed: torch.Tensor,
            respawned: torch.Tensor, goal_of_route: torch.Tensor) -> None:
        """One step: the contacts and |speed| of the state it ended in, who respawned after it, and
        each agent's goal on the route it drives now (`lap_goals` of its route, after any respawn)."""
        if self.goal is None:
            self.goal = goal_of_route.float()  # the first step: the routes spawned on
        step = speed.float() * DT
        self.distance += step.sum(-1)
        self.violation += (step * contact_al).sum(-1)
        self.aa_events += self.aa.step(contact_aa).sum(-1)
        self.al_events += self.al.step(contact_al).sum(-1)
        collided = contact_aa | contact_al
        self.try_distance += step
        lap = ~respawned & (self.try_distance >= self.goal)
        self.successes += (lap | (respawned & ~collided)).sum(-1)  # a lap, or an exit
        self.failures += (respawned & collided).sum(-1)
        self.try_distance = torch.where(respawned, 0.0, torch.where(lap, self.try_distance - self.goal, self.try_distance))
        self.goal = torch.where(respawned, goal_of_route.float(), self.goal)

    def columns(self) -> dict[str, torch.Tensor]:
        """The benchmark's metric columns, [E] each (NaN where undefined)."""
        nan = torch.full_like(self.distance, float("nan"))
        per = torch.where(self.distance >= MIN_DISTANCE_M, PER_M / self.distance.clamp_min(1e-12), nan)
        tries = self.successes + self.failures
        return {TS: torch.where(tries > 0, self.successes / tries.clamp_min(1), nan),
                CAA_100M: self.aa_events * per, CAL_100M: self.al_events * per, LV_100M: self.violation * per}


def lap_goals(road_map, device: torch.device | str) -> torch.Tensor:
    """Per route [R]: the distance of one lap of a looping route (its length); inf for a route
    with an exit (its goal is the exit)."""
    return torch.tensor([r.length if r.is_loop else float("inf") for r in road_map.routes],
                        dtype=torch.float32, device=device)
