"""The clipped-PPO update of a seed block: the lean loss (`ppo_loss.LeanPPOLoss`) of S seeds at
once, each seed's terms computed over its own minibatch and the seeds' losses summed (not
averaged, so each seed's gradient is the gradient its lone run takes), each seed's gradient
clipped by its own norm.

Tensors are [S, N, agents, ...]: seed k's rollout at index k. Minibatches are [S, m] indices,
each seed's drawn from its own generator in the order a lone run draws them.
"""

from __future__ import annotations

import contextlib
import math
from functools import partial

import torch
import torch.nn.functional as F
from tensordict import TensorDictBase

from sigmarl.config import PPOConfig
from sigmarl.env.streams import SeedStreams
from sigmarl.training.networks import (
    LOG_PROB,
    OBS,
    PREIMAGE,
    PolicyHead,
    gaussian_log_prob,
    tanh_log_jacobian,
)
from sigmarl.training.ppo_loss import ADVANTAGE, TERMS, VALUE_TARGET
from sigmarl.training.stacked import StackedMLP


def _mean(x: torch.Tensor) -> torch.Tensor:
    """Per seed: the mean over everything but the leading seed dimension."""
    return x.flatten(1).mean(1)


class BlockPPOLoss:
    def __init__(self, head: PolicyHead, actor: StackedMLP, critic: StackedMLP, ppo: PPOConfig,
                 precision: str, streams: SeedStreams):
        self.head, self.actor, self.critic, self.streams = head, actor, critic, streams
        self.clip = (math.log1p(-ppo.clip_epsilon), math.log1p(ppo.clip_epsilon))
        self.entropy_coef = ppo.entropy_coef
        self.normalize_advantage = ppo.normalize_advantage
        device = actor.params[0].device
        self.autocast = (partial(torch.autocast, device.type, dtype=torch.bfloat16)
                         if precision == "bf16" else contextlib.nullcontext)
        self.seeds = torch.arange(actor.n_seeds, device=device).unsqueeze(1)

    def prepare(self, data: TensorDictBase) -> dict[str, torch.Tensor]:
        """[S, frames, agents, ...] tensors of a block's rollout [S * E, T]."""
        s = self.actor.n_seeds
        flat = data.select(OBS, LOG_PROB, PREIMAGE, ADVANTAGE, VALUE_TARGET).reshape(-1)
        view = lambda t: t.reshape(s, t.shape[0] // s, *t.shape[1:])  # noqa: E731
        u = view(flat.get(PREIMAGE))
        return {
            "obs": view(flat.get(OBS)),
            "u": u,
            "log_jac": tanh_log_jacobian(u, self.head.log_half),
            "old_log_prob": view(flat.get(LOG_PROB)),
            "advantage": view(flat.get(ADVANTAGE)),
            "target": view(flat.get(VALUE_TARGET)),
        }

    def __call__(self, batch: dict[str, torch.Tensor], idx: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The summed loss of the seeds' minibatches idx [S, m], and their terms [S, len(TERMS)]."""
        if len(idx) == 1:  # one seed: index its frames alone (cheaper than a gather over seeds)
            rows = idx[0]
            take = lambda key: batch[key][:, rows]  # noqa: E731
        else:
            take = lambda key: batch[key][self.seeds, idx]  # noqa: E731
        h = self.head
        with self.autocast():
            obs = take("obs")
            out, value = self.actor(obs), self.critic(obs)
        loc, scale = h.scale_map(out.float())
        value = value.float()
        log_scale = scale.log()
        log_prob = gaussian_log_prob((take("u") - loc) / scale, scale.log()) - take("log_jac")
        log_weight = (log_prob - take("old_log_prob")).unsqueeze(-1)
        adv = take("advantage")
        if self.normalize_advantage:
            flat = adv.flatten(1)
            adv = (adv - flat.mean(1).view(-1, 1, 1, 1)) / flat.std(1).clamp_min(1e-6).view(-1, 1, 1, 1)
        clipped = log_weight.clamp(*self.clip)
        gain = torch.minimum(log_weight.exp() * adv, clipped.exp() * adv)
        loss_objective = -_mean(gain)
        # entropy: -log p of one reparameterised sample per agent, the noise from each seed's stream
        noise = self.streams.randn(loc.shape[1:])
        noise = noise.reshape(loc.shape)
        u = loc + scale * noise
        entropy = -_mean(gaussian_log_prob(noise, log_scale) - tanh_log_jacobian(u, h.log_half))
        loss_entropy = -self.entropy_coef * entropy
        loss_critic = _mean(F.smooth_l1_loss(value, take("target"), reduction="none"))
        total = (loss_objective + loss_critic + loss_entropy).sum()
        with torch.no_grad():
            terms = torch.stack([
                loss_objective, loss_critic, loss_entropy, entropy,
                _mean((log_weight != clipped).float()), -_mean(log_weight),
            ], 1)
        return total, terms


def clip_grad_norm_per_seed(params: list[torch.Tensor], max_norm: float) -> torch.Tensor:
    """`torch.nn.utils.clip_grad_norm_` for each seed of stacked parameters [S, ...]: seed k's
    gradients scaled by min(1, max_norm / (|g_k| + 1e-6)), |g_k| over all its parameters.
    Returns the seeds' norms [S]."""
    grads = [p.grad for p in params if p.grad is not None]
    if grads and grads[0].shape[0] == 1:  # one seed: torch's own (fused) clip, the same maths
        return torch.nn.utils.clip_grad_norm_(params, max_norm).reshape(1)
    norms = torch.stack([torch.linalg.vector_norm(g.flatten(1), 2, dim=1) for g in grads], 1)
    total = torch.linalg.vector_norm(norms, 2, dim=1)
    coef = (max_norm / (total + 1e-6)).clamp(max=1.0)
    for g in grads:
        g.mul_(coef.view(-1, *(1,) * (g.dim() - 1)))
    return total


def block_update(data: TensorDictBase, loss: BlockPPOLoss, optimiser: torch.optim.Optimizer,
                 ppo: PPOConfig) -> list[dict[str, float]]:
    """`mappo.update` for a block: per seed, `epochs` passes of that seed's own shuffled
    minibatches; returns each seed's mean loss terms."""
    batch = loss.prepare(data)
    s, n = batch["obs"].shape[:2]
    per_epoch = n // ppo.minibatch_size
    params = [p for group in optimiser.param_groups for p in group["params"]]
    device = batch["obs"].device
    totals = torch.zeros(s, len(TERMS), device=device)
    gens = loss.streams.generators
    for _ in range(ppo.epochs):
        order = torch.stack([torch.randperm(n, generator=g, device=device) for g in gens])
        for b in range(per_epoch):
            total, terms = loss(batch, order[:, b * ppo.minibatch_size: (b + 1) * ppo.minibatch_size])
            optimiser.zero_grad(set_to_none=True)
            total.backward()
            clip_grad_norm_per_seed(params, ppo.max_grad_norm)
            optimiser.step()
            totals += terms
    means = (totals / (ppo.epochs * per_epoch)).tolist()
    return [dict(zip(TERMS, row, strict=True)) for row in means]
