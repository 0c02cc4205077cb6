"""The clipped-PPO minibatch loss (objective, smooth-L1 critic, one-sample entropy of the
tanh-Gaussian) of S seeds at once, on plain tensors over the stacked networks' parameters (S = 1
for one seed). Each seed's terms are computed over its own minibatch and the seeds' losses are
summed, not averaged, so each seed's gradient is the gradient it takes alone.

What does not depend on the parameters (the pre-tanh actions and their log-Jacobian) is computed
once per iteration (`prepare`); torchrl's `ClipPPOLoss` computes the same terms but cost 1.19x the
bare maths at the paper's sizes (it indexes TensorDicts, swaps MultiAgentMLP parameters into a
module and inverts tanh to score stored actions). tests/test_ppo_loss.py checks the terms and
gradients against ClipPPOLoss, the independent oracle.

Mixed precision (`ppo.precision=bf16`): the actor's and critic's MLPs run under
`torch.autocast(..., dtype=torch.bfloat16)`; their outputs are cast back to fp32 before the
scale mapping, so log-probabilities, ratios, advantages and every reduction stay fp32.

Tensors are [S, N, agents, ...]: seed k's rollout at index k. Minibatches are [S, m] indices.
"""

from __future__ import annotations

import contextlib
import math
from functools import cache, partial
from pathlib import Path

import torch
import torch.nn.functional as F
from tensordict import TensorDictBase

from sigmarl.config import Config, PPOConfig
from sigmarl.env.streams import SeedStreams
from sigmarl.training.networks import (
    ACTION,
    LOG_PROB,
    OBS,
    PREIMAGE,
    PolicyHead,
    StackedMLP,
    gaussian_log_prob,
    tanh_log_jacobian,
)

REWARD_KEY = ("agents", "reward")
DONE, TERMINATED = ("agents", "done"), ("agents", "terminated")
ADVANTAGE, VALUE_TARGET = ("agents", "advantage"), ("agents", "value_target")
TERMS = ("loss_objective", "loss_critic", "loss_entropy", "entropy", "clip_fraction", "kl_approx")


@cache
def cpu_has_native_bf16() -> bool:
    """True when the CPU computes bf16 natively (AVX512-BF16 or AMX-BF16 in /proc/cpuinfo);
    elsewhere bf16 is emulated and slower than fp32."""
    try:
        flags = Path("/proc/cpuinfo").read_text().split()
    except OSError:
        return False
    return "avx512_bf16" in flags or "amx_bf16" in flags


def resolve_precision(cfg: Config) -> str:
    """What `ppo.precision` means on this machine: "fp32" or "bf16". `auto` is bf16 only where
    the device computes it natively. The one place `auto` is resolved: training uses the value
    this returns, and a run can record it."""
    ppo = cfg.ppo
    if ppo.precision != "auto":
        return ppo.precision
    kind = torch.device(cfg.device).type
    if kind == "cpu":
        return "bf16" if cpu_has_native_bf16() else "fp32"
    return "bf16" if kind == "cuda" and torch.cuda.is_bf16_supported() else "fp32"


def _mean(x: torch.Tensor) -> torch.Tensor:
    """Per seed: the mean over everything but the leading seed dimension."""
    return x.flatten(1).mean(1)


class PPOLoss:
    """`prepare(data)` once per iteration, then `loss(batch, idx)` per minibatch: the summed loss
    to minimise and each seed's detached terms (`TERMS`)."""

    def __init__(self, head: PolicyHead, actor: StackedMLP, critic: StackedMLP, ppo: PPOConfig,
                 precision: str, streams: SeedStreams):
        """`precision`: "fp32" or "bf16", as `resolve_precision` gives it."""
        if precision not in ("fp32", "bf16"):
            raise ValueError(f"unresolved precision {precision!r}: pass resolve_precision(cfg)")
        self.head, self.actor, self.critic, self.streams = head, actor, critic, streams
        self.clip = (math.log1p(-ppo.clip_epsilon), math.log1p(ppo.clip_epsilon))
        self.entropy_coef = ppo.entropy_coef
        self.normalize_advantage = ppo.normalize_advantage
        device = actor.params[0].device
        self.precision = precision
        self.autocast = (partial(torch.autocast, device.type, dtype=torch.bfloat16)
                         if precision == "bf16" else contextlib.nullcontext)
        self.seeds = torch.arange(actor.n_seeds, device=device).unsqueeze(1)

    def prepare(self, data: TensorDictBase) -> dict[str, torch.Tensor]:
        """[S, frames, agents, ...] tensors of a rollout [S * E, T], with the pre-tanh actions
        (the sampler's, or for a rollout of the ProbabilisticActor its inverted tanh, as torchrl
        inverts it) and their log-Jacobian."""
        s, h = self.actor.n_seeds, self.head
        flat = data.select(OBS, ACTION, LOG_PROB, PREIMAGE, ADVANTAGE, VALUE_TARGET, strict=False).reshape(-1)
        view = lambda t: t.reshape(s, t.shape[0] // s, *t.shape[1:])  # noqa: E731
        u = flat.get(PREIMAGE, None)
        if u is None:
            u = ((flat.get(ACTION) - h.mid) / h.half).clamp(-h.tanh_limit, h.tanh_limit).atanh()
        u = view(u)
        return {
            "obs": view(flat.get(OBS)),
            "u": u,
            "log_jac": tanh_log_jacobian(u, self.head.log_half),
            "old_log_prob": view(flat.get(LOG_PROB)),
            "advantage": view(flat.get(ADVANTAGE)),
            "target": view(flat.get(VALUE_TARGET)),
        }

    def take(self, batch: dict[str, torch.Tensor], idx: torch.Tensor):
        """`key -> batch[key]` at the seeds' minibatches idx [S, m]."""
        if len(idx) == 1:  # one seed: index its frames alone (cheaper than a gather over seeds)
            rows = idx[0]
            return lambda key: batch[key][:, rows]
        return lambda key: batch[key][self.seeds, idx]

    def networks(self, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(loc, scale, value) of observations [S, m, agents, D] in fp32; the MLPs themselves
        under autocast when bf16."""
        with self.autocast():
            out, value = self.actor(obs), self.critic(obs)
        loc, scale = self.head.scale_map(out.float())
        return loc, scale, value.float()

    def log_weight(self, batch: dict[str, torch.Tensor], idx: torch.Tensor, loc: torch.Tensor,
                   scale: torch.Tensor) -> torch.Tensor:
        """log(new / old probability) of the stored actions, [S, m, agents, 1], fp32."""
        take = self.take(batch, idx)
        # its own scale.log(), not the entropy's: the gradient then sums in the order it always
        # did, and runs trained before the losses were one keep their bits
        log_prob = gaussian_log_prob((take("u") - loc) / scale, scale.log()) - take("log_jac")
        return (log_prob - take("old_log_prob")).unsqueeze(-1)

    def __call__(self, batch: dict[str, torch.Tensor], idx: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The summed loss of the seeds' minibatches idx [S, m], and their terms [S, len(TERMS)]."""
        take, h = self.take(batch, idx), self.head
        loc, scale, value = self.networks(take("obs"))
        log_scale = scale.log()
        log_weight = self.log_weight(batch, idx, loc, scale)
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
