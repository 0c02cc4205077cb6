"""Environment speed against vmas' own road_traffic scenario and VMAS' floor, in one process.

One thread, random actions (`env.rand_action`), every step through torchrl's
`step_and_maybe_reset`, so done environments are reset (partially) as a collector resets them:
- ours: the default training setup (CPM intersection, 4 agents, 32 envs, train mode),
- vmas' road_traffic through torchrl's VmasEnv, 4 agents, 32 envs, training mode, on its
  CPM intersection (map_type "3", intersection only: the same sub-map as ours),
- a trivial VMAS scenario with our 4 box agents (observation = position, reward 0, never
  done): what stepping any VMAS scenario through torchrl costs (VMAS' floor),
and ours with 15 agents (whole CPM map, test mode) and with 1024 environments.

Timing: a warm-up, then rounds of `--steps` steps; the rounds of all environments are
interleaved (so that load from other processes hits them alike) and each keeps its best.

Run: python benchmarks/bench_env.py [--steps N] [--rounds R]
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable

import torch
from torchrl.envs import EnvBase
from torchrl.envs.libs.vmas import VmasEnv
from vmas.simulator.core import Agent, Box, World
from vmas.simulator.scenario import BaseScenario

from sigmarl.compose import compose_config
from sigmarl.env.factory import make_env


class Trivial(BaseScenario):
    """Our agents (same shape, flags and action range) and no scenario work at all."""

    def make_world(self, batch_dim: int, device: torch.device, **kwargs) -> World:
        world = World(batch_dim, device, dt=0.05, substeps=1, drag=0.0)
        for i in range(kwargs.get("n_agents", 4)):
            world.add_agent(
                Agent(
                    name=f"agent_{i}",
                    shape=Box(length=0.16, width=0.08),
                    collide=False,
                    movable=False,
                    rotatable=False,
                    u_range=[0.8, math.radians(35)],
                )
            )
        return world

    def reset_world_at(self, env_index: int | None = None) -> None:
        pass

    def observation(self, agent: Agent) -> torch.Tensor:
        return agent.state.pos

    def reward(self, agent: Agent) -> torch.Tensor:
        return torch.zeros(self.world.batch_dim, device=self.world.device)


class Timer:
    """Steps one env with random actions; `round()` times `steps` steps, keeping the best."""

    def __init__(self, env: EnvBase, warmup: int = 20):
        self.env, self.best = env, math.inf
        self.td = env.reset()
        self._run(warmup)

    def _run(self, steps: int) -> None:
        env, td = self.env, self.td
        for _ in range(steps):
            td = env.step_and_maybe_reset(env.rand_action(td))[1]
        self.td = td

    def round(self, steps: int) -> None:
        t0 = time.perf_counter()
        self._run(steps)
        self.best = min(self.best, (time.perf_counter() - t0) / steps)


def vmas_env(scenario, **kwargs) -> EnvBase:
    return VmasEnv(
        scenario, num_envs=32, n_agents=4, continuous_actions=True, max_steps=128, seed=0, **kwargs
    )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--steps", type=int, default=100, help="steps per round")
    p.add_argument("--rounds", type=int, default=3)
    args = p.parse_args()
    torch.set_num_threads(1)
    cfg = compose_config([])
    cpm = compose_config(["map=cpm"]).map
    cases: dict[str, tuple[int, int, Callable[[], EnvBase]]] = {
        "sigmarl (CPM intersection, train)": (32, 4, lambda: make_env(cfg)),
        "vmas road_traffic (intersection)": (
            32,
            4,
            lambda: vmas_env("road_traffic", map_type="3", scenario_probabilities=[1.0, 0.0, 0.0]),
        ),
        "trivial VMAS scenario (floor)": (32, 4, lambda: vmas_env(Trivial())),
        "sigmarl (CPM loops, test)": (
            32,
            15,
            lambda: make_env(cfg, n_agents=15, mode="test", max_steps=1200, map_cfg=cpm),
        ),
        "sigmarl (intersection, 1024 envs)": (1024, 4, lambda: make_env(cfg, num_envs=1024)),
    }
    t_start = time.perf_counter()
    timers = {name: Timer(make()) for name, (_, _, make) in cases.items()}
    for _ in range(args.rounds):
        for t in timers.values():
            t.round(args.steps)

    print(
        f"torch {torch.__version__}, 1 thread, random actions, best of {args.rounds} rounds "
        f"of {args.steps} steps (one step = all envs)"
    )
    print(
        f"{'environment':<36}{'envs':>6}{'agents':>8}{'steps/s':>10}{'ms/step':>9}{'agent-steps/s':>15}"
    )
    for name, (envs, agents, _) in cases.items():
        sps = 1 / timers[name].best
        print(
            f"{name:<36}{envs:>6}{agents:>8}{sps:>10.1f}{1000 / sps:>9.2f}{sps * envs * agents:>15.0f}"
        )
    ours, theirs, floor = (timers[n].best for n in list(cases)[:3])
    print(f"\nours / road_traffic: {theirs / ours:.1f}x faster (target >= 10x)")
    print(
        f"ours / floor: a step costs {ours / floor:.2f}x the trivial VMAS scenario's "
        f"({1000 * (ours - floor):.2f} ms above it)"
    )
    print(f"total {time.perf_counter() - t_start:.0f} s")


if __name__ == "__main__":
    main()
