"""Environment speed against vmas' own road_traffic scenario and VMAS' floor, in one process.

All on one thread, random actions, through torchrl (`rand_step` + `step_mdp`, with partial
resets of done environments as a collector does them):
- ours: the default training setup (CPM intersection, 4 agents, 32 envs, train mode),
- vmas' road_traffic scenario (its own CPM map), 4 agents, 32 envs,
- a trivial VMAS scenario with the same 4 box agents (observation = position, reward 0):
  what stepping any VMAS scenario through torchrl costs (VMAS' floor),
and ours with 15 agents (CPM, test mode) and with 1024 environments.

Run: python benchmarks/bench_env.py [--steps N] [--rounds R]
"""

from __future__ import annotations

import argparse
import time

import torch
from torchrl.envs.libs.vmas import VmasEnv
from vmas.simulator.core import Agent, Box, World
from vmas.simulator.scenario import BaseScenario

from sigmarl.compose import compose_config
from sigmarl.env import make_env


class Trivial(BaseScenario):
    """Box agents and nothing else: the per-step cost of VMAS + torchrl themselves."""

    def make_world(self, batch_dim, device, **kwargs):
        world = World(batch_dim, device)
        for i in range(kwargs.get("n_agents", 4)):
            world.add_agent(Agent(name=f"agent_{i}", shape=Box(0.16, 0.08), collide=False))
        return world

    def reset_world_at(self, env_index=None):
        pass

    def observation(self, agent):
        return agent.state.pos

    def reward(self, agent):
        return torch.zeros(self.world.batch_dim, device=self.world.device)


def steps_per_second(env, steps: int, rounds: int) -> float:
    """Best of `rounds` rounds of `steps` environment steps (batched: one step = all envs)."""
    td = env.reset()
    for _ in range(10):
        td = env.step_and_maybe_reset(env.rand_action(td))[1]
    best = float("inf")
    for _ in range(rounds):
        t0 = time.perf_counter()
        for _ in range(steps):
            td = env.step_and_maybe_reset(env.rand_action(td))[1]
        best = min(best, time.perf_counter() - t0)
    return steps / best


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--steps", type=int, default=100)
    p.add_argument("--rounds", type=int, default=3)
    args = p.parse_args()
    torch.set_num_threads(1)
    cfg = compose_config([])
    rows = []

    def run(name: str, env, envs: int, agents: int) -> float:
        sps = steps_per_second(env, args.steps, args.rounds)
        rows.append((name, envs, agents, sps))
        return sps

    ours = run("sigmarl (CPM intersection, train)", make_env(cfg, num_envs=32, n_agents=4), 32, 4)
    theirs = run("vmas road_traffic", VmasEnv("road_traffic", num_envs=32, n_agents=4,
                                             continuous_actions=True, max_steps=128, seed=0), 32, 4)
    floor = run("trivial VMAS scenario (floor)", VmasEnv(Trivial(), num_envs=32, n_agents=4,
                                                         continuous_actions=True, max_steps=128, seed=0), 32, 4)
    cpm = compose_config(["map=cpm"]).map
    run("sigmarl CPM, 15 agents, test", make_env(cfg, num_envs=32, n_agents=15, mode="test", map_cfg=cpm), 32, 15)
    run("sigmarl, 1024 envs", make_env(cfg, num_envs=1024, n_agents=4), 1024, 4)
    print(f"{'environment':<36}{'envs':>6}{'agents':>8}{'steps/s':>10}{'ms/step':>9}")
    for name, envs, agents, sps in rows:
        print(f"{name:<36}{envs:>6}{agents:>8}{sps:>10.1f}{1000 / sps:>9.2f}")
    print(f"\nours / road_traffic: x{ours / theirs:.1f} faster (target >= 10)")
    print(f"ours costs {floor / ours:.2f} x the trivial VMAS scenario (VMAS' own floor)")


if __name__ == "__main__":
    main()
