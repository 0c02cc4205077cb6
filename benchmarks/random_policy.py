"""Mean episode reward of a uniformly random policy, collected exactly as training collects.

The baseline for the learning check: a trained model's `episode_reward_mean` (MLflow metric,
per iteration) should be clearly above it. Same environments, rollout length and per-iteration
seeds as `sigmarl train` with the same overrides. Usage:

    python benchmarks/random_policy.py [--iterations 5] [overrides...]
"""

from __future__ import annotations

import argparse
import statistics

import torch
from torchrl.collectors import Collector, RandomPolicy

from sigmarl.compose import compose_config
from sigmarl.env import make_env
from sigmarl.training.loop import iteration_seed
from sigmarl.training.mappo import mark_batch_end, rollout_stats


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--iterations", type=int, default=5, help="collections to average")
    p.add_argument("overrides", nargs="*", default=[])
    args = p.parse_args()
    cfg = compose_config(["tracking.enabled=false", *args.overrides])
    torch.set_num_threads(cfg.threads)
    env = make_env(cfg, num_envs=cfg.ppo.num_envs, mode="train", seed=cfg.seed, device=cfg.device)
    collector = Collector(env, RandomPolicy(env.full_action_spec), total_frames=-1,
                          frames_per_batch=cfg.ppo.frames_per_iteration, reset_at_each_iter=True)
    batches = iter(collector)
    rewards = []
    for it in range(args.iterations):
        s = iteration_seed(cfg.seed, it)
        torch.manual_seed(s)
        env.set_seed(s)
        stats = rollout_stats(mark_batch_end(next(batches)))
        rewards.append(stats["episode_reward_mean"])
        print(f"iteration {it + 1}: episode_reward_mean {stats['episode_reward_mean']:.3f}, "
              + ", ".join(f"{k} {v:.3f}" for k, v in stats.items() if k.startswith("train_")))
    collector.shutdown()
    print(f"random policy, mean over {args.iterations} collections: "
          f"{statistics.mean(rewards):.3f} (uniform actions in the box)")


if __name__ == "__main__":
    main()
