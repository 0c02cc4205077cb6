"""Training speed at the paper's settings: where an iteration's time goes, against a floor.

One MAPPO iteration = collection (32 envs x 128 steps) + GAE + optimisation (60 epochs x 8
minibatches of 512). The floor is the optimisation alone written as a bare PyTorch loop over
identical MLP shapes (same batch, same clipped-PPO/entropy/smooth-L1 maths, Adam, grad clip):
the compute any implementation must pay. Target: full iteration <= 1.15 x floor.

To keep the run short, optimisation (ours and the floor, interleaved epoch by epoch) runs
`--epochs` epochs and is scaled to the configured 60; collection and GAE run in full.

Mixed precision: the PPO update (epochs of 8 minibatches of 512 over one collected batch) with
`ppo.precision=fp32` and `bf16`, epoch by epoch in turn on one thread, and their ratio
(`--precision-epochs`, 0 to skip; `--only-precision` for this alone). Usage:

    python benchmarks/bench_training.py [--epochs 6] [--repeats 1] [--threads 1 2] [--compare-rollout]
        [--precision-epochs 10] [--only-precision] [overrides...]
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import time
from dataclasses import replace

import torch
import torch.nn.functional as F
from tensordict.nn import TensorDictModule
from torch import nn

from sigmarl.compose import compose_config
from sigmarl.training.learner import Learner
from sigmarl.training.loop import learning_rate
from sigmarl.training.mappo import collect, update
from sigmarl.training.networks import ACTION, OBS
from sigmarl.training.ppo_loss import PPOLoss, cpu_has_native_bf16


def _mlp(n_in: int, hidden: list[int], n_out: int) -> nn.Sequential:
    layers: list[nn.Module] = []
    for h in hidden:
        layers += [nn.Linear(n_in, h), nn.Tanh()]
        n_in = h
    return nn.Sequential(*layers, nn.Linear(n_in, n_out))


class Floor:
    """A hand-written MAPPO update over identical MLP shapes, as lean as the maths allows:
    everything that does not depend on the parameters (the pre-tanh actions and their
    log-Jacobian) is computed once, outside the loop."""

    def __init__(self, obs: torch.Tensor, high: torch.Tensor, hidden: list[int], ppo) -> None:
        n, n_agents, d = obs.shape
        self.obs, self.n, self.ppo = obs, n, ppo
        self.actor, self.critic = _mlp(d, hidden, 4), _mlp(n_agents * d, hidden, 1)
        self.params = [*self.actor.parameters(), *self.critic.parameters()]
        self.opt = torch.optim.Adam(self.params, lr=ppo.lr)
        self.high = high
        self.u_act = torch.randn(n, n_agents, 2)  # pre-tanh actions; tanh(u) * high is the action
        self.log_jac = _log_jac(self.u_act, high).sum(-1)
        self.old_lp, self.adv = torch.randn(n, n_agents), torch.randn(n, n_agents, 1)
        self.target = torch.randn(n, 1)  # one centralised value per frame, shared by the agents
        for _ in range(3):  # warm-up
            self.step(torch.randint(0, n, (ppo.minibatch_size,)))

    def step(self, idx: torch.Tensor) -> None:
        ppo, eps = self.ppo, self.ppo.clip_epsilon
        half_log_2pi = 0.5 * math.log(2 * math.pi)
        o = self.obs[idx]
        loc, s = self.actor(o).chunk(2, -1)
        scale = F.softplus(s + math.log(math.e - 1)).clamp_min(1e-4)  # softplus(0 + shift) = 1
        z = (self.u_act[idx] - loc) / scale
        lp = (-0.5 * z**2 - scale.log() - half_log_2pi).sum(-1) - self.log_jac[idx]
        lw = (lp - self.old_lp[idx]).unsqueeze(-1)
        a = self.adv[idx]
        gain = torch.min(lw.exp() * a, lw.clamp(math.log1p(-eps), math.log1p(eps)).exp() * a)
        noise = torch.randn_like(loc)  # one-sample entropy estimate of the tanh-Gaussian
        u = loc + scale * noise
        entropy = -((-0.5 * noise**2 - scale.log() - half_log_2pi) - _log_jac(u, self.high)).sum(-1)
        value = self.critic(o.flatten(-2))
        loss = -gain.mean() + F.smooth_l1_loss(value, self.target[idx]) - ppo.entropy_coef * entropy.mean()
        self.opt.zero_grad(set_to_none=True)
        loss.backward()
        torch.nn.utils.clip_grad_norm_(self.params, ppo.max_grad_norm)
        self.opt.step()

    def epoch(self) -> None:
        order, m = torch.randperm(self.n), self.ppo.minibatch_size
        for j in range(self.n // m):
            self.step(order[j * m : (j + 1) * m])


def _log_jac(u: torch.Tensor, high: torch.Tensor) -> torch.Tensor:
    """log |d(high * tanh u)/du|, stable: log(1 - tanh^2 u) = 2 (log 2 - u - softplus(-2u))."""
    return high.log() + 2 * (math.log(2) - u - F.softplus(-2 * u))


class _Replay(TensorDictModule):
    """Plays back recorded actions [envs, steps, agents, 2], one step per call."""

    def __init__(self, actions: torch.Tensor) -> None:
        super().__init__(self._next, in_keys=[OBS], out_keys=[ACTION])
        self.actions, self.t = actions, 0

    def _next(self, obs: torch.Tensor) -> torch.Tensor:
        self.t += 1
        return self.actions[:, self.t - 1]


class _Clock:
    """Wall and CPU time of a block; CPU time is robust when other processes share the cores."""

    def __enter__(self) -> _Clock:
        self.w, self.c = time.perf_counter(), time.process_time()
        return self

    def __exit__(self, *exc: object) -> None:
        self.wall, self.cpu = time.perf_counter() - self.w, time.process_time() - self.c


def measure(cfg, epochs: int, repeats: int, compare_rollout: bool) -> dict[str, tuple[float, float]]:
    """Median (wall, cpu) seconds per iteration of each phase, optimisation scaled to ppo.epochs.

    Optimisation and floor run interleaved, one epoch each in turn, so that load from other
    processes on the machine hits both alike.
    """
    ppo = cfg.ppo
    parts = Learner(cfg, [cfg.seed], torch.device("cpu"))  # one seed: what `sigmarl train seed=0` runs
    env = parts.env
    steps = ppo.frames_per_iteration // ppo.num_envs
    one = replace(cfg.ppo, epochs=1)
    scale = ppo.epochs / epochs
    for g in parts.optimiser.param_groups:
        g["lr"] = learning_rate(ppo, 0)
    batches = iter(parts.collector)
    collect(batches)  # warm-up
    rows: dict[str, list[tuple[float, float]]] = {}

    def add(name: str, clock: _Clock, factor: float = 1.0) -> None:
        rows.setdefault(name, []).append((clock.wall * factor, clock.cpu * factor))

    for r in range(repeats):
        parts.reseed(r)
        with _Clock() as col:
            data = collect(batches)
        # the environment's share: the same seed and the recorded actions replay the very same
        # trajectories (same resets) through the env, without policy or collector
        parts.reseed(r)
        with _Clock() as env_only, torch.no_grad():
            env.rollout(steps, _Replay(data["agents", "action"]), auto_reset=True,
                        break_when_any_done=False)
        with _Clock() as adv:
            parts.advantage(data)
        obs = data["agents", "observation"].reshape(-1, *data["agents", "observation"].shape[-2:])
        floor = Floor(obs, parts.dims["action_high"], list(cfg.network.hidden), ppo)
        update(data, parts.loss, parts.optimiser, one)  # warm-up
        opt, bare = _Clock(), _Clock()
        opt.wall = opt.cpu = bare.wall = bare.cpu = 0.0
        for _ in range(epochs):
            with _Clock() as c:
                update(data, parts.loss, parts.optimiser, one)
            opt.wall, opt.cpu = opt.wall + c.wall, opt.cpu + c.cpu
            with _Clock() as c:
                floor.epoch()
            bare.wall, bare.cpu = bare.wall + c.wall, bare.cpu + c.cpu
        add("env_only", env_only)
        add("collect", col)
        add("advantage", adv)
        add("optimise", opt, scale)
        add("floor", bare, scale)
    if compare_rollout:  # the alternative to the collector: EnvBase.rollout (stacks at the end)
        for r in range(repeats):
            parts.reseed(r)
            with _Clock() as c, torch.no_grad():
                env.rollout(steps, parts.collector.policy, auto_reset=True, break_when_any_done=False)
            add("collect_rollout", c)
    parts.close()
    return {k: tuple(statistics.median(x[i] for x in v) for i in (0, 1)) for k, v in rows.items()}


def measure_precision(cfg, epochs: int) -> dict[str, float]:
    """CPU seconds of `epochs` PPO epochs in fp32 and in bf16, run alternately on one thread."""
    torch.set_num_threads(1)
    parts = Learner(cfg, [cfg.seed], torch.device("cpu"))
    parts.reseed(0)
    data = parts.advantage(collect(parts.batches))
    one = replace(cfg.ppo, epochs=1)
    losses = {}
    for precision in ("fp32", "bf16"):
        ppo = replace(cfg.ppo, precision=precision)
        losses[precision] = PPOLoss(parts.head, parts.actor, parts.critic, ppo, precision, parts.streams)
        update(data, losses[precision], parts.optimiser, one)  # warm-up
    cpu = dict.fromkeys(losses, 0.0)
    for _ in range(epochs):
        for precision, loss in losses.items():
            with _Clock() as c:
                update(data, loss, parts.optimiser, one)
            cpu[precision] += c.cpu
    parts.close()
    return cpu


def _cpu_name() -> str:
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return "unknown CPU"


def report_precision(cfg, epochs: int) -> None:
    ppo = cfg.ppo
    cpu = measure_precision(cfg, epochs)
    print(f"PPO update, fp32 vs bf16 autocast (one thread, {epochs} epochs each, interleaved, "
          f"{ppo.frames_per_iteration // ppo.minibatch_size} minibatches of {ppo.minibatch_size} per epoch)")
    print(f"  CPU: {_cpu_name()}; native bf16 (avx512_bf16/amx_bf16): {cpu_has_native_bf16()}")
    for precision, seconds in cpu.items():
        print(f"  {precision:<6}{seconds / epochs:7.3f} s per epoch")
    print(f"  fp32 / bf16   x{cpu['fp32'] / cpu['bf16']:.3f}   (>1: bf16 is faster)\n")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--epochs", type=int, default=6, help="epochs actually run (scaled to ppo.epochs)")
    p.add_argument("--repeats", type=int, default=1, help="iterations measured (median)")
    p.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    p.add_argument("--compare-rollout", action="store_true",
                   help="also time collection with env.rollout instead of the Collector")
    p.add_argument("--precision-epochs", type=int, default=10,
                   help="epochs per precision in the fp32/bf16 comparison (0: skip it)")
    p.add_argument("--only-precision", action="store_true", help="run only the fp32/bf16 comparison")
    p.add_argument("overrides", nargs="*", default=[], help="Hydra overrides (default: paper)")
    args = p.parse_args()
    cfg = compose_config(["tracking.enabled=false", *args.overrides])
    if args.only_precision:
        report_precision(cfg, max(args.precision_epochs, 1))
        return
    ppo = cfg.ppo
    print(
        f"settings: {ppo.num_envs} envs x {ppo.frames_per_iteration // ppo.num_envs} steps, "
        f"{ppo.epochs} epochs x {ppo.frames_per_iteration // ppo.minibatch_size} minibatches of "
        f"{ppo.minibatch_size}; map {cfg.map.name}, {cfg.env.n_agents} agents, obs {cfg.obs.preset}"
    )
    load = os.getloadavg()[0]
    print(f"machine: {os.cpu_count()} cores, load average {load:.2f} at start"
          + ("  (busy: other processes share the cores; wall times of >1 thread are unreliable)"
             if load > 0.5 else ""))
    print(f"optimisation measured over {args.epochs} epochs and scaled x{ppo.epochs / args.epochs:g}; "
          f"median of {args.repeats} iteration(s)\n")
    projected = {}
    for threads in args.threads:
        torch.set_num_threads(threads)
        m = measure(cfg, args.epochs, args.repeats, args.compare_rollout and threads == args.threads[0])
        # one thread: CPU time is the process's own work, unaffected by other processes on the
        # machine; more threads: only wall time says what they buy
        k = 1 if threads == 1 else 0
        clock = "CPU" if k else "wall"
        total = m["collect"][k] + m["advantage"][k] + m["optimise"][k]
        floor = m["floor"][k]
        print(f"threads={threads}: seconds per iteration ({clock} time; wall in brackets)")
        for name, label in [("collect", "collection"), ("advantage", "advantage (GAE)"),
                            ("optimise", "optimisation"), ("floor", "bare PyTorch floor")]:
            print(f"  {label:<20}{m[name][k]:7.2f}  [{m[name][0]:.2f}]")
        print(f"    of the collection, the environment (same steps replayed): {m['env_only'][k]:.2f}")
        if "collect_rollout" in m:
            print(f"    collection with env.rollout instead of the Collector: {m['collect_rollout'][k]:.2f}")
        print(f"  optimisation / floor   x{m['optimise'][k] / floor:.3f}")
        print(f"  iteration / floor      x{total / floor:.3f}   (target <= 1.15)")
        projected[threads] = total * ppo.iterations
        print(f"  projected {ppo.iterations} iterations: {projected[threads] / 60:.1f} min\n")
    print("projected wall time for", ppo.iterations, "iterations:",
          ", ".join(f"{t} thread(s) {s / 60:.1f} min" for t, s in projected.items()))
    if args.precision_epochs > 0:
        print()
        report_precision(cfg, args.precision_epochs)


if __name__ == "__main__":
    main()
