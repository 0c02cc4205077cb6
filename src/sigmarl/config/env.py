"""The training environment (`env.*`): agents, episode length, spawns, and the reward's and
the vehicle's records."""

from __future__ import annotations

from dataclasses import dataclass, field

from sigmarl.config.ranges import ranged
from sigmarl.config.reward import RewardConfig
from sigmarl.config.vehicle import VehicleConfig


@dataclass
class EnvConfig:
    """The training environment (evaluation sets its own agent counts, mode and length from
    `eval.*` and the scenarios; the number of training environments is `ppo.num_envs`)."""

    n_agents: int = ranged(4, lo=1, hi=10**5, size=True)
    """Vehicles per training environment."""
    max_steps: int = ranged(128, lo=1, hi=10**6, size=True)
    """Training episode length in steps (evaluation: eval.steps)."""
    spawn_start_m: float = ranged(0.5, lo=0)
    """Training spawns on non-loop routes start this many m after a route's start."""
    spawn_end_fraction: float = ranged(0.5, lo=0, hi=1, lo_open=True)
    """Training spawns on non-loop routes end at this fraction of the route's length."""
    spawn_margin_m: float = ranged(0.25, lo=0)
    """Test spawns keep this many m from either end of a route."""
    reward: RewardConfig = field(default_factory=RewardConfig)
    """The reward's weights and shaping scales (the paper's by default)."""
    vehicle: VehicleConfig = field(default_factory=VehicleConfig)
    """The vehicle's limits (the CPM Lab vehicle's by default)."""
