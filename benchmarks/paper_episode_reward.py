"""The paper's mean episode reward, estimated from our batches, against a collector that never resets.

Training resets every environment at each batch (`reset_at_each_iter`) and logs
`episode_reward_mean`, which counts the segment a batch's end cuts as an episode. The paper's
collector never resets: it logs the whole return of each episode that ends in the batch, however
long ago it began. `episode_reward_mean_complete` estimates that from our batch
(`training.mappo.complete_episode_reward`). This runs one fixed, committed policy (sampling its
actions, as training collects) through both collectors on the training map, with the batch of
its config (32 environments x 128 steps at the paper's settings), and prints per batch and in
all: ours, the estimate, and the paper's quantity from the collector that does not reset (its
first batch, which starts from a reset like ours, left out), each mean with its standard error
over batches, and the estimate minus the paper's with a 95% interval. Usage:

    python benchmarks/paper_episode_reward.py [--batches 20] [--threads 1]
        [results/paper-budget/M0/seed0/best.pt ...]
"""

from __future__ import annotations

import argparse
import math
import statistics
from pathlib import Path

import torch
from torchrl.collectors import Collector
from torchrl.envs.utils import ExplorationType

from sigmarl.env import make_env
from sigmarl.run import COMPLETE_REWARD_COLUMN, REWARD_COLUMN
from sigmarl.training import checkpoint as ckpt
from sigmarl.training.loop import load_policy
from sigmarl.training.mappo import make_collector, mark_batch_end, rollout_stats

ROOT = Path(__file__).resolve().parents[1]
DEFAULT = [ROOT / "results" / "paper-budget" / "M0" / "seed0" / "best.pt"]


def ours(cfg, actor, batches: int, seed: int) -> tuple[list[float], list[float]]:
    """Per batch of the training collector: `episode_reward_mean` and the estimate."""
    env = make_env(cfg, num_envs=cfg.ppo.num_envs, mode="train", seed=seed)
    collector = make_collector(env, actor, cfg.ppo.frames_per_iteration, torch.device("cpu"))
    cut, complete = [], []
    for _, data in zip(range(batches), collector, strict=False):
        stats = rollout_stats(mark_batch_end(data), cfg.env.max_steps)
        cut.append(stats[REWARD_COLUMN])
        complete.append(stats[COMPLETE_REWARD_COLUMN])
    collector.shutdown()
    return cut, complete


def paper(cfg, actor, batches: int, seed: int) -> list[float]:
    """Per batch of a collector that never resets: the mean over the agent-episodes that end in
    the batch of their whole return, summed across batch ends (the paper's logged quantity)."""
    env = make_env(cfg, num_envs=cfg.ppo.num_envs, mode="train", seed=seed)
    collector = Collector(env, actor, frames_per_batch=cfg.ppo.frames_per_iteration, total_frames=-1,
                          reset_at_each_iter=False, exploration_type=ExplorationType.RANDOM,
                          auto_register_policy_transforms=False)
    running = None  # each environment's agents' returns so far [E, A]
    out = []
    for i, data in zip(range(batches + 1), collector, strict=False):
        reward = data["next", "agents", "reward"].squeeze(-1)  # [E, T, A]
        done = data["next", "done"].squeeze(-1)  # [E, T], the environment's own: no batch end marked
        running = torch.zeros_like(reward[:, 0]) if running is None else running
        ended = []
        for t in range(reward.shape[1]):
            running += reward[:, t]
            ended.append(running[done[:, t]].flatten())
            running[done[:, t]] = 0.0
        if i > 0:  # the first batch began at a reset, as ours do
            out.append(float(torch.cat(ended).mean()))
    collector.shutdown()
    return out


def _mean_se(x: list[float]) -> tuple[float, float]:
    return statistics.mean(x), statistics.stdev(x) / math.sqrt(len(x))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--batches", type=int, default=20, help="batches per collector")
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--seed", type=int, default=0, help="the environments' seed")
    p.add_argument("policies", nargs="*", type=Path, default=DEFAULT)
    args = p.parse_args()
    torch.set_num_threads(args.threads)
    for path in args.policies:
        torch.manual_seed(args.seed)
        actor, state = load_policy(path)
        cfg = ckpt.config_of(state, path)
        cut, complete = ours(cfg, actor, args.batches, args.seed)
        theirs = paper(cfg, actor, args.batches, args.seed + 1)
        (mc, sc), (me, se), (mp, sp) = _mean_se(cut), _mean_se(complete), _mean_se(theirs)
        diff, half = me - mp, 1.96 * math.hypot(se, sp)
        print(f"{path} ({args.batches} batches of {cfg.ppo.frames_per_iteration} frames each way)")
        print(f"  ours, {REWARD_COLUMN}:            {mc:.3f} +- {sc:.3f}")
        print(f"  ours, {COMPLETE_REWARD_COLUMN}:   {me:.3f} +- {se:.3f}")
        print(f"  no-reset collector (the paper's): {mp:.3f} +- {sp:.3f}")
        print(f"  estimate - paper's: {diff:+.3f} [{diff - half:+.3f}, {diff + half:+.3f}] (95%); "
              f"ours - paper's: {mc - mp:+.3f}")


if __name__ == "__main__":
    main()
