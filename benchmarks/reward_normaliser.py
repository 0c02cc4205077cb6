"""What the paper's reward normaliser does to the reward of a fixed policy.

Our reward divides its motion terms (progress, speed, moving) by 0.8 m/s, the paper's code by
1.0 m/s (`rules.reward_normaliser_one`). Each committed policy drives on its training map, as in
training (its config's environments, 128-step episodes, collisions ending an episode) but with
its deterministic action, for `--steps` steps; at every step the reward is totalled from the
same terms both ways (the motion terms times 0.8 for the paper's) and each agent's reward
clamped to [-1, 1] as the environment clamps it. Prints per policy the mean per-step reward
under each normaliser and their ratio (paper's / ours), and the range of the ratios. Usage:

    python benchmarks/reward_normaliser.py [--steps 256] [--envs 32]
        [results/paper-budget/M0/seed0/best.pt ...]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import torch
from torchrl.envs.utils import ExplorationType, set_exploration_type, step_mdp

from sigmarl.env import make_env
from sigmarl.env.paper_rules import COMMAND_LIMIT
from sigmarl.env.reward import total_reward
from sigmarl.params import VEHICLE
from sigmarl.training import checkpoint as ckpt
from sigmarl.training.loop import load_policy

ROOT = Path(__file__).resolve().parents[1]
MOTION = ("progress", "speed", "moving")
DEFAULT = [ROOT / "results" / "paper-budget" / m / f"seed{s}" / "best.pt"
           for m in ("M0", "M2", "M3", "M5") for s in (0, 1)]


@torch.no_grad()
def per_step_rewards(path: Path, steps: int, envs: int, seed: int) -> tuple[float, float]:
    """Mean per-agent, per-step reward of the policy at `path` under our normaliser and the paper's."""
    actor, state = load_policy(path)
    cfg = ckpt.config_of(state, path)
    if cfg.rules.reward_normaliser_one:
        raise SystemExit(f"{path} trained under the paper's normaliser; this compares from ours")
    env = make_env(cfg, num_envs=envs, mode="train", seed=seed)
    scenario = env._env.scenario
    factor = VEHICLE.max_speed / COMMAND_LIMIT  # /1.0 instead of /0.8
    ours = paper = 0.0
    td = env.reset()
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        for _ in range(steps):
            td = env.step(actor(td))
            terms = scenario.terms
            ours += float(td["next", "agents", "reward"].mean())
            paper += float(total_reward({k: v * factor if k in MOTION else v for k, v in terms.items()}).mean())
            td = env.maybe_reset(step_mdp(td))
    env.close()
    return ours / steps, paper / steps


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--steps", type=int, default=256)
    p.add_argument("--envs", type=int, default=32)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("policies", nargs="*", type=Path, default=DEFAULT)
    args = p.parse_args()
    torch.set_num_threads(args.threads)
    ratios = []
    for path in args.policies:
        ours, paper = per_step_rewards(path, args.steps, args.envs, args.seed)
        ratios.append(paper / ours)
        print(f"{path.relative_to(ROOT) if path.is_relative_to(ROOT) else path}: per-step reward "
              f"ours {ours:.4f}, paper's normaliser {paper:.4f}, ratio {paper / ours:.3f}")
    print(f"ratio (paper's / ours) over {len(ratios)} policies, {args.steps} steps x {args.envs} environments "
          f"each: {min(ratios):.3f}-{max(ratios):.3f}")


if __name__ == "__main__":
    main()
