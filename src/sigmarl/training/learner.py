"""The learner: S seeds of one training config trained in one process as one batched computation
(`sigmarl train seeds=[0,1,2,3]`); one seed (`sigmarl train seed=0`) is a block of S = 1.

- One environment holds S x ppo.num_envs environments, seed k's at rows k*E .. (k+1)*E, each seed
  drawing its spawns and noise from its own generators (`sigmarl.env.streams`).
- Actor and critic are S stacked copies (`networks.StackedMLP`), each initialised from its seed;
  actions, minibatch order and the entropy sample come from each seed's own generator, seeded per
  iteration from (seed, iteration).
- One Adam over the stacked parameters is S Adams; the loss is summed over seeds, each seed's
  gradient clipped by its own norm (`ppo_loss`, `mappo.update`).

So seed k of a block computes what it computes alone (S = 1), up to the last bits of the batched
products (tests/test_blocks.py measures it), and its checkpoints are the ones it writes alone:
the torchrl modules' weights and one Adam's state (`state`). Exact resume: every iteration
starts from a state that depends only on (seed, iteration): the generators and the environment
are reseeded (`reseed`) and every environment is reset.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import numpy as np
import torch
from tensordict import TensorDictBase
from torch import nn

from sigmarl.config import Config
from sigmarl.env.streams import SeedStreams
from sigmarl.training import checkpoint as ckpt
from sigmarl.training.mappo import collect, make_collector, make_gae, rollout_stats, update
from sigmarl.training.networks import (
    ACTION,
    OBS,
    VALUE,
    PolicyHead,
    StackedMLP,
    make_actor,
    make_critic,
    make_sampler,
    per_seed,
)
from sigmarl.training.ppo_loss import PPOLoss, resolve_precision


def iteration_seed(seed: int, iteration: int) -> int:
    """A well-mixed 31-bit seed per (run seed, iteration)."""
    return int(np.random.SeedSequence([seed, iteration]).generate_state(1)[0] >> 1)


def build_env(cfg: Config, device: torch.device, num_envs: int | None = None, seeds: Sequence[int] = ()):
    from sigmarl.env import make_env

    return make_env(cfg, num_envs=num_envs or cfg.ppo.num_envs, mode="train", seed=cfg.seed,
                    device=str(device), seeds=seeds)


def env_dims(env: Any) -> dict[str, Any]:
    obs_shape = env.full_observation_spec[OBS].shape
    box = env.full_action_spec[ACTION].space
    n_act = box.low.shape[-1]
    return {
        "obs_dim": int(obs_shape[-1]),
        "n_agents": int(obs_shape[-2]),
        "action_low": box.low.reshape(-1, n_act)[0].cpu(),
        "action_high": box.high.reshape(-1, n_act)[0].cpu(),
    }


def make_networks(cfg: Config, dims: dict[str, Any], seed: int, device: torch.device):
    """Actor and critic initialised from `seed`, as a run of that seed initialises them."""
    torch.manual_seed(seed)
    actor = make_actor(cfg.network, dims["obs_dim"], dims["n_agents"], dims["action_low"],
                       dims["action_high"], device)
    return actor, make_critic(cfg.network, dims["obs_dim"], dims["n_agents"], device)


class Learner:
    """What trains S seeds: environment, stacked networks, loss, optimiser, collector."""

    def __init__(self, cfg: Config, seeds: list[int], device: torch.device):
        self.cfg, self.seeds, self.device = cfg, list(seeds), device
        s = len(self.seeds)
        ppo = cfg.ppo
        self.env = build_env(cfg, device, num_envs=s * ppo.num_envs, seeds=self.seeds)
        self.dims = env_dims(self.env)
        # each seed's torchrl modules, initialised from its seed (what its checkpoints hold)
        self.modules = [make_networks(cfg, self.dims, seed, device) for seed in self.seeds]
        self.actor = StackedMLP([_mlp(actor) for actor, _ in self.modules])
        self.critic = StackedMLP([critic.module for _, critic in self.modules])
        self.head = PolicyHead(self.modules[0][0])
        self.streams = SeedStreams(s, device)  # actions, minibatch order, the entropy sample
        self.optimiser = torch.optim.Adam([*self.actor.parameters(), *self.critic.parameters()], lr=ppo.lr)
        self.loss = PPOLoss(self.head, self.actor, self.critic, ppo, resolve_precision(cfg), self.streams)
        self.gae = make_gae(None, ppo)  # reads the values `iterate` sets
        sampler = make_sampler(self.head, self.actor, self.streams)
        self.collector = make_collector(self.env, sampler, s * ppo.frames_per_iteration, device)
        self.batches = iter(self.collector)

    def reseed(self, iteration: int) -> None:
        seeds = [iteration_seed(seed, iteration) for seed in self.seeds]
        self.env.seed_block(seeds)
        self.streams.seed(seeds)

    def iterate(self) -> tuple[list[dict[str, float]], dict[str, float]]:
        """One iteration of every seed: each seed's metrics, and the block's timings."""
        t0 = time.perf_counter()
        data = collect(self.batches)
        t1 = time.perf_counter()
        self.advantage(data)
        t2 = time.perf_counter()
        losses = update(data, self.loss, self.optimiser, self.cfg.ppo)
        t3 = time.perf_counter()
        e = data.shape[0] // len(self.seeds)
        metrics = [{**rollout_stats(data[k * e:(k + 1) * e], self.cfg.env.max_steps), **losses[k]}
                   for k in range(len(self.seeds))]
        return metrics, {"total": t3 - t0, "collect": t1 - t0, "advantage": t2 - t1, "optimise": t3 - t2}

    @torch.no_grad()
    def advantage(self, data: TensorDictBase) -> TensorDictBase:
        """The critic's values of a collected batch and GAE's advantages and targets, set in it."""
        value = per_seed(self.critic, len(self.seeds))
        data.set(VALUE, value(data.get(OBS)))
        data.set(("next", *VALUE), value(data.get(("next", *OBS))))
        self.gae(data)
        return data

    def set_lr(self, lr: float) -> None:
        for group in self.optimiser.param_groups:
            group["lr"] = lr

    def networks(self, k: int):
        """Seed k's torchrl modules (what its checkpoint's weights are checked against)."""
        return self.modules[k]

    def state(self, k: int) -> dict[str, Any]:
        """Seed k's resume point: the torchrl modules' weights, one Adam's state, the generators
        (the format every checkpoint has, whatever S its run trained in)."""
        actor, critic = self.modules[k]
        self.actor.unstack(k, _mlp(actor))
        self.critic.unstack(k, critic.module)
        return {"policy": _clone(actor.state_dict()), "critic": _clone(critic.state_dict()),
                "optimizer": self._optimiser_state(k), "rng": ckpt.rng_state()}

    def load(self, k: int, state: dict[str, Any]) -> None:
        actor, critic = self.modules[k]
        actor.load_state_dict(state["policy"])
        critic.load_state_dict(state["critic"])
        self.actor.restack(k, _mlp(actor))
        self.critic.restack(k, critic.module)
        saved = state["optimizer"]
        params = [p for group in self.optimiser.param_groups for p in group["params"]]
        if len(saved["state"]) not in (0, len(params)):
            raise ValueError(f"{len(saved['state'])} optimiser states for {len(params)} parameters")
        for i, p in enumerate(params):
            if i not in saved["state"]:
                continue
            mine = self.optimiser.state[p]
            if not mine:
                mine.update({"step": saved["state"][i]["step"].clone(), "exp_avg": torch.zeros_like(p),
                             "exp_avg_sq": torch.zeros_like(p)})
            for key in ("exp_avg", "exp_avg_sq"):
                mine[key][k].copy_(saved["state"][i][key])
            mine["step"] = saved["state"][i]["step"].clone()

    def _optimiser_state(self, k: int) -> dict[str, Any]:
        """Seed k's Adam as one Adam's `optimiser.state_dict()` over its torchrl modules (one
        parameter group, the parameters in the modules' order, which the stacked ones keep)."""
        group = self.optimiser.param_groups[0]
        state = {}
        for i, p in enumerate(group["params"]):
            st = self.optimiser.state.get(p)
            if st:
                state[i] = {"step": st["step"].clone(), "exp_avg": st["exp_avg"][k].clone(),
                            "exp_avg_sq": st["exp_avg_sq"][k].clone()}
        one = {key: value for key, value in group.items() if key != "params"}
        return {"state": state, "param_groups": [{**one, "params": list(range(len(group["params"])))}]}

    def close(self) -> None:
        self.collector.shutdown()
        if not self.env.is_closed:
            self.env.close()


def _mlp(actor) -> nn.Module:
    return actor.module[0].module[0]  # ProbabilisticActor -> Sequential(MultiAgentMLP, extractor)


def _clone(weights: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    return {k: v.detach().clone() for k, v in weights.items()}
