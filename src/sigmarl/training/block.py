"""A seed block's learner: S seeds of one training config trained in one process as one batched
computation (`sigmarl train seeds=[0,1,2,3]`).

- One environment holds S x ppo.num_envs environments, seed k's at rows k*E .. (k+1)*E, each seed
  drawing its spawns and noise from its own generators (`sigmarl.env.streams`).
- Actor and critic are S stacked copies (`stacked.StackedMLP`), initialised as each lone run
  initialises its own; actions, minibatch order and the entropy sample come from each seed's own
  generator, seeded per iteration as the lone run seeds torch's global one.
- One Adam over the stacked parameters is S Adams; the loss is summed over seeds, each seed's
  gradient clipped by its own norm (`block_loss`).

So seed k of a block computes what its lone run computes, up to the last bits of the batched
products (tests/test_blocks.py measures it), and its checkpoints are a lone run's.
"""

from __future__ import annotations

import time
from typing import Any

import torch
from tensordict.nn import TensorDictModule
from torch import nn

from sigmarl.config import Config
from sigmarl.env.streams import SeedStreams
from sigmarl.training import checkpoint as ckpt
from sigmarl.training.block_loss import BlockPPOLoss, block_update
from sigmarl.training.lone import build_env, env_dims, iteration_seed, make_networks
from sigmarl.training.mappo import collect, make_collector, make_gae, rollout_stats
from sigmarl.training.networks import (
    ACTION,
    LOG_PROB,
    OBS,
    PREIMAGE,
    VALUE,
    PolicyHead,
    gaussian_log_prob,
    tanh_log_jacobian,
)
from sigmarl.training.ppo_loss import resolve_precision
from sigmarl.training.stacked import StackedMLP, per_seed


class BlockSampler(nn.Module):
    """The exploration policy of S seeds (`networks.TanhNormalSampler`, each seed's Gaussian
    noise from its own generator, drawn as torch.normal draws it: N(0, 1) scaled and shifted)."""

    def __init__(self, head: PolicyHead, actor: StackedMLP, streams: SeedStreams):
        super().__init__()
        self.head, self.actor, self.streams = head, actor, streams

    def forward(self, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        h = self.head
        loc, scale = h.scale_map(per_seed(self.actor, self.actor.n_seeds)(obs))
        z = self.streams.randn((loc.shape[0] // self.actor.n_seeds, *loc.shape[1:]))
        u = z * scale + loc
        action = h.mid + h.half * u.tanh().clamp(-h.tanh_limit, h.tanh_limit)
        log_prob = gaussian_log_prob((u - loc) / scale, scale.log()) - tanh_log_jacobian(u, h.log_half)
        return action, log_prob, u


class BlockLearner:
    """What trains a block: environment, stacked networks, loss, optimiser, collector."""

    def __init__(self, cfg: Config, seeds: list[int], device: torch.device):
        self.cfg, self.seeds, self.device = cfg, list(seeds), device
        s = len(self.seeds)
        ppo = cfg.ppo
        self.env = build_env(cfg, device, num_envs=s * ppo.num_envs, seeds=self.seeds)
        self.dims = env_dims(self.env)
        # each seed's lone networks, initialised as its lone run initialises them
        self.lone = [make_networks(cfg, self.dims, seed, device) for seed in self.seeds]
        self.actor = StackedMLP([_mlp(actor) for actor, _ in self.lone])
        self.critic = StackedMLP([critic.module for _, critic in self.lone])
        self.head = PolicyHead(self.lone[0][0])
        self.streams = SeedStreams(s, device)  # actions, minibatch order, the entropy sample
        self.optimiser = torch.optim.Adam([*self.actor.parameters(), *self.critic.parameters()], lr=ppo.lr)
        self.loss = BlockPPOLoss(self.head, self.actor, self.critic, ppo, resolve_precision(cfg), self.streams)
        self.gae = make_gae(None, ppo)  # reads the values `iterate` sets
        sampler = TensorDictModule(BlockSampler(self.head, self.actor, self.streams), in_keys=[OBS],
                                   out_keys=[ACTION, LOG_PROB, PREIMAGE])
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
        with torch.no_grad():
            value = per_seed(self.critic, len(self.seeds))
            data.set(VALUE, value(data.get(OBS)))
            data.set(("next", *VALUE), value(data.get(("next", *OBS))))
            self.gae(data)
        t2 = time.perf_counter()
        losses = block_update(data, self.loss, self.optimiser, self.cfg.ppo)
        t3 = time.perf_counter()
        e = data.shape[0] // len(self.seeds)
        metrics = [{**rollout_stats(data[k * e:(k + 1) * e]), **losses[k]} for k in range(len(self.seeds))]
        return metrics, {"total": t3 - t0, "collect": t1 - t0, "advantage": t2 - t1, "optimise": t3 - t2}

    def set_lr(self, lr: float) -> None:
        for group in self.optimiser.param_groups:
            group["lr"] = lr

    def networks(self, k: int):
        """Seed k's lone modules (what its checkpoint's weights are checked against)."""
        return self.lone[k]

    def state(self, k: int) -> dict[str, Any]:
        """Seed k's weights and optimiser state in its lone run's format."""
        actor, critic = self.lone[k]
        self.actor.unstack(k, _mlp(actor))
        self.critic.unstack(k, critic.module)
        return {"policy": _clone(actor.state_dict()), "critic": _clone(critic.state_dict()),
                "optimizer": self._optimiser_state(k), "rng": ckpt.rng_state()}

    def load(self, k: int, state: dict[str, Any]) -> None:
        actor, critic = self.lone[k]
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
        """Seed k's Adam as its lone run's `optimiser.state_dict()` (one parameter group, the
        parameters in the lone modules' order, which the stacked ones keep)."""
        group = self.optimiser.param_groups[0]
        state = {}
        for i, p in enumerate(group["params"]):
            st = self.optimiser.state.get(p)
            if st:
                state[i] = {"step": st["step"].clone(), "exp_avg": st["exp_avg"][k].clone(),
                            "exp_avg_sq": st["exp_avg_sq"][k].clone()}
        lone_group = {key: value for key, value in group.items() if key != "params"}
        return {"state": state, "param_groups": [{**lone_group, "params": list(range(len(group["params"])))}]}

    def close(self) -> None:
        self.collector.shutdown()
        if not self.env.is_closed:
            self.env.close()


def _mlp(actor) -> nn.Module:
    return actor.module[0].module[0]  # ProbabilisticActor -> Sequential(MultiAgentMLP, extractor)


def _clone(weights: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    return {k: v.detach().clone() for k, v in weights.items()}
