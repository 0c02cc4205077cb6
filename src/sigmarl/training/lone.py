"""A lone run's learner: one seed, torchrl's modules, torch's global generator.

Exact resume: every iteration starts from a state that depends only on (seed, iteration): the
global generators and the environment are reseeded (`reseed`) and every environment is reset.
A checkpoint after iteration k (weights, optimiser, RNG states) is all iteration k+1 needs.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import numpy as np
import torch

from sigmarl.config import Config
from sigmarl.errors import SigmarlError
from sigmarl.training import checkpoint as ckpt
from sigmarl.training.mappo import collect, make_collector, make_gae, rollout_stats, update
from sigmarl.training.networks import ACTION, OBS, make_actor, make_critic, make_sampler
from sigmarl.training.ppo_loss import make_loss, resolve_precision


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


class LoneLearner:
    """Environment, networks (initialised from cfg.seed), loss, GAE, optimiser, collector."""

    def __init__(self, cfg: Config, device: torch.device):
        self.cfg, self.seeds = cfg, [cfg.seed]
        self.env = build_env(cfg, device)
        self.dims = env_dims(self.env)
        self.actor, self.critic = make_networks(cfg, self.dims, cfg.seed, device)
        self.optimiser = torch.optim.Adam([*self.actor.parameters(), *self.critic.parameters()], lr=cfg.ppo.lr)
        self.collector = make_collector(self.env, make_sampler(self.actor), cfg.ppo.frames_per_iteration, device)
        self.loss = make_loss(self.actor, self.critic, cfg.ppo, resolve_precision(cfg))
        self.gae = make_gae(self.critic, cfg.ppo)
        self.batches = iter(self.collector)

    def reseed(self, iteration: int) -> None:
        s = iteration_seed(self.cfg.seed, iteration)
        torch.manual_seed(s)
        self.env.set_seed(s)

    def set_lr(self, lr: float) -> None:
        for group in self.optimiser.param_groups:
            group["lr"] = lr

    def iterate(self) -> tuple[list[dict[str, float]], dict[str, float]]:
        t0 = time.perf_counter()
        data = collect(self.batches)
        t1 = time.perf_counter()
        with torch.no_grad():
            self.gae(data)
        t2 = time.perf_counter()
        losses = update(data, self.loss, self.optimiser, self.cfg.ppo)
        t3 = time.perf_counter()
        return [{**rollout_stats(data), **losses}], {"total": t3 - t0, "collect": t1 - t0, "advantage": t2 - t1,
                                                     "optimise": t3 - t2}

    def networks(self, k: int = 0):
        """The lone modules (what a checkpoint's weights are checked against)."""
        return self.actor, self.critic

    def state(self, k: int = 0) -> dict[str, Any]:
        return {"policy": self.actor.state_dict(), "critic": self.critic.state_dict(),
                "optimizer": self.optimiser.state_dict(), "rng": ckpt.rng_state()}

    def load(self, k: int, state: dict[str, Any]) -> None:
        self.actor.load_state_dict(state["policy"])
        self.critic.load_state_dict(state["critic"])
        try:
            self.optimiser.load_state_dict(state["optimizer"])
        except (ValueError, KeyError, RuntimeError) as e:
            raise SigmarlError(f"the optimiser state does not fit ({e})") from e
        ckpt.set_rng_state(state["rng"])

    def close(self) -> None:
        self.collector.shutdown()
        if not self.env.is_closed:
            self.env.close()
