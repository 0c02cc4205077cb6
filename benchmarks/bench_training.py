"""Training speed at the paper's settings: where an iteration's time goes, against a floor.

One MAPPO iteration = collection (32 envs x 128 steps) + GAE + optimisation (60 epochs x 8
minibatches of 512). The floor is the optimisation alone written as a bare PyTorch loop over
identical MLP shapes (same batch, same clipped-PPO/entropy/smooth-L1 maths, Adam, grad clip):
the compute any implementation must pay. Target: full iteration <= 1.15 x floor.

To keep the run short, optimisation (torchrl and floor) runs `--epochs` epochs and is scaled
to the configured 60; collection and GAE run in full. Usage:

    python benchmarks/bench_training.py [--epochs 6] [--threads 1 2] [--collector] [overrides...]
"""

from __future__ import annotations

import argparse
import math
import statistics
import time

import torch
import torch.nn.functional as F
from torch import nn

from sigmarl.compose import compose_config
from sigmarl.training.loop import build, learning_rate
from sigmarl.training.mappo import collect, update


def _mlp(n_in: int, hidden: list[int], n_out: int) -> nn.Sequential:
    layers: list[nn.Module] = []
    for h in hidden:
        layers += [nn.Linear(n_in, h), nn.Tanh()]
        n_in = h
    return nn.Sequential(*layers, nn.Linear(n_in, n_out))


def floor_seconds(
    obs: torch.Tensor, high: torch.Tensor, hidden: list[int], ppo, steps: int
) -> float:
    """`steps` optimiser steps of a hand-written MAPPO update on frames obs [F, A, D]."""
    n, n_agents, d = obs.shape
    actor, critic = _mlp(d, hidden, 4), _mlp(n_agents * d, hidden, 1)
    params = [*actor.parameters(), *critic.parameters()]
    opt = torch.optim.Adam(params, lr=ppo.lr)
    act = (torch.rand(n, n_agents, 2) * 2 - 1) * high * 0.99
    old_lp, adv, target = torch.randn(n, n_agents), torch.randn(n, n_agents, 1), torch.randn(n, n_agents, 1)
    shift = math.log(math.e - 1)  # softplus(0 + shift) = 1

    def log_prob(loc, scale, a):
        u = torch.atanh((a / high).clamp(-0.999999, 0.999999))
        jac = torch.log(high * (1 - torch.tanh(u) ** 2) + 1e-6)
        return (torch.distributions.Normal(loc, scale).log_prob(u) - jac).sum(-1)

    def step(idx):
        o = obs[idx]
        loc, s = actor(o).chunk(2, -1)
        scale = F.softplus(s + shift).clamp_min(1e-4)
        lw = (log_prob(loc, scale, act[idx]) - old_lp[idx]).unsqueeze(-1)
        a = adv[idx]
        eps = ppo.clip_epsilon
        gain = torch.min(lw.exp() * a, lw.clamp(math.log1p(-eps), math.log1p(eps)).exp() * a)
        sample = torch.tanh(loc + scale * torch.randn_like(loc)) * high
        entropy = -log_prob(loc, scale, sample).mean()
        value = critic(o.flatten(-2)).unsqueeze(-2).expand(-1, n_agents, 1)
        loss = -gain.mean() + F.smooth_l1_loss(value, target[idx]) - ppo.entropy_coef * entropy
        opt.zero_grad(set_to_none=True)
        loss.backward()
        torch.nn.utils.clip_grad_norm_(params, ppo.max_grad_norm)
        opt.step()

    for _ in range(3):  # warm-up
        step(torch.randint(0, n, (ppo.minibatch_size,)))
    t = time.perf_counter()
    per_epoch = n // ppo.minibatch_size
    for i in range(steps):
        if i % per_epoch == 0:
            order = torch.randperm(n)
        j = i % per_epoch
        step(order[j * ppo.minibatch_size : (j + 1) * ppo.minibatch_size])
    return time.perf_counter() - t


def measure(cfg, epochs: int, repeats: int, use_collector: bool) -> dict[str, float]:
    ppo = cfg.ppo
    parts = build(cfg, torch.device("cpu"))
    steps = ppo.frames_per_iteration // ppo.num_envs
    short = cfg.ppo.copy()
    short.epochs = epochs
    scale = ppo.epochs / epochs
    for g in parts.optimiser.param_groups:
        g["lr"] = learning_rate(ppo, 0)
    collect(parts.env, parts.actor, 8)  # warm-up
    rows: dict[str, list[float]] = {"collect": [], "advantage": [], "optimise": [], "floor": []}
    for r in range(repeats):
        parts.env.set_seed(r)
        t0 = time.perf_counter()
        data = collect(parts.env, parts.actor, steps)
        t1 = time.perf_counter()
        with torch.no_grad():
            parts.gae(data)
        t2 = time.perf_counter()
        update(data, parts.loss, parts.optimiser, short)
        t3 = time.perf_counter()
        obs = data["agents", "observation"].reshape(-1, *data["agents", "observation"].shape[-2:])
        fl = floor_seconds(obs, parts.dims["action_high"], list(cfg.network.hidden), ppo,
                           epochs * (ppo.frames_per_iteration // ppo.minibatch_size))
        rows["collect"].append(t1 - t0)
        rows["advantage"].append(t2 - t1)
        rows["optimise"].append((t3 - t2) * scale)
        rows["floor"].append(fl * scale)
    out = {k: statistics.median(v) for k, v in rows.items()}
    if use_collector:
        from torchrl.collectors import Collector
        from torchrl.envs.utils import ExplorationType

        col = Collector(parts.env, parts.actor, frames_per_batch=ppo.frames_per_iteration,
                        total_frames=-1, reset_at_each_iter=True,
                        exploration_type=ExplorationType.RANDOM)
        it = iter(col)
        next(it)
        t = time.perf_counter()
        next(it)
        out["collect_collector"] = time.perf_counter() - t
        col.shutdown()
    parts.env.close()
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--epochs", type=int, default=6, help="epochs actually run (scaled to ppo.epochs)")
    p.add_argument("--repeats", type=int, default=1, help="iterations measured (median)")
    p.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    p.add_argument("--collector", action="store_true", help="also time torchrl's Collector")
    p.add_argument("overrides", nargs="*", default=[], help="Hydra overrides (default: paper)")
    args = p.parse_args()
    cfg = compose_config(["tracking.enabled=false", *args.overrides])
    ppo = cfg.ppo
    print(
        f"paper settings: {ppo.num_envs} envs x {ppo.frames_per_iteration // ppo.num_envs} steps, "
        f"{ppo.epochs} epochs x {ppo.frames_per_iteration // ppo.minibatch_size} minibatches of "
        f"{ppo.minibatch_size}; map {cfg.map.name}, {cfg.env.n_agents} agents, obs {cfg.obs.preset}"
    )
    print(f"optimisation measured over {args.epochs} epochs and scaled x{ppo.epochs / args.epochs:g}; "
          f"median of {args.repeats} iteration(s)\n")
    for threads in args.threads:
        torch.set_num_threads(threads)
        m = measure(cfg, args.epochs, args.repeats, args.collector and threads == args.threads[0])
        total = m["collect"] + m["advantage"] + m["optimise"]
        print(f"threads={threads}  (seconds per iteration)")
        print(f"  collection   {m['collect']:7.2f}")
        if "collect_collector" in m:
            print(f"  (collection with torchrl Collector instead of env.rollout: {m['collect_collector']:.2f})")
        print(f"  advantage    {m['advantage']:7.2f}")
        print(f"  optimisation {m['optimise']:7.2f}   (bare PyTorch floor {m['floor']:.2f}, "
              f"x{m['optimise'] / m['floor']:.3f})")
        print(f"  iteration    {total:7.2f}   = x{total / m['floor']:.3f} the floor (target <= 1.15)")
        print(f"  projected {ppo.iterations} iterations: {total * ppo.iterations / 60:.1f} min\n")


if __name__ == "__main__":
    main()
