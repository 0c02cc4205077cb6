"""The clipped-PPO minibatch loss, two implementations of the same maths.

- `TorchrlPPOLoss` wraps torchrl's `ClipPPOLoss` (`ppo.loss=torchrl`).
- `LeanPPOLoss` (`ppo.loss=lean`, the default) computes the same numbers on plain tensors
  over the actor's and critic's own parameters. At the paper's sizes ClipPPOLoss costs
  about 20% more than the maths (benchmarks/bench_training.py): per minibatch it indexes
  TensorDicts, swaps MultiAgentMLP parameters into a module and inverts tanh to score the
  stored actions. Here what does not depend on the parameters (pre-tanh actions and their
  log-Jacobian) is computed once per iteration. tests/test_ppo_loss.py checks its losses
  and gradients against ClipPPOLoss.

Both take `prepare(data)` once per iteration, then `loss(batch, idx)` per minibatch, which
returns the total loss to minimise and the detached terms named in `TERMS`.

Mixed precision (`ppo.precision=bf16`, lean loss only): the actor's and critic's MLPs run under
`torch.autocast(..., dtype=torch.bfloat16)`; their outputs are cast back to fp32 before the
scale mapping, so log-probabilities, ratios, advantages and every reduction stay fp32.
"""

from __future__ import annotations

import contextlib
import math
from functools import cache, partial
from pathlib import Path

import torch
import torch.nn.functional as F
from tensordict import TensorDictBase
from torch import nn
from torchrl.modules import ProbabilisticActor
from torchrl.objectives import ClipPPOLoss

from sigmarl.config import Config, PPOConfig
from sigmarl.training.networks import (
    ACTION,
    LOG_PROB,
    OBS,
    PREIMAGE,
    VALUE,
    PolicyHead,
    gaussian_log_prob,
    plain_forward,
    tanh_log_jacobian,
)

REWARD_KEY = ("agents", "reward")
DONE, TERMINATED = ("agents", "done"), ("agents", "terminated")
ADVANTAGE, VALUE_TARGET = ("agents", "advantage"), ("agents", "value_target")
TERMS = ("loss_objective", "loss_critic", "loss_entropy", "entropy", "clip_fraction", "kl_approx")
# what the update needs from a rollout
TRAIN_KEYS = [OBS, ACTION, LOG_PROB, ADVANTAGE, VALUE_TARGET]


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
    the device computes it natively and the loss is the lean one (ClipPPOLoss would compute
    log-probabilities in bf16). The one place `auto` is resolved: training uses the value
    this returns, and a run can record it."""
    ppo = cfg.ppo
    if ppo.precision != "auto":
        return ppo.precision
    if ppo.loss != "lean":
        return "fp32"
    kind = torch.device(cfg.device).type
    if kind == "cpu":
        return "bf16" if cpu_has_native_bf16() else "fp32"
    return "bf16" if kind == "cuda" and torch.cuda.is_bf16_supported() else "fp32"


class TorchrlPPOLoss:
    """torchrl's ClipPPOLoss over TensorDict minibatches."""

    def __init__(self, actor: ProbabilisticActor, critic: nn.Module, ppo: PPOConfig):
        self.loss = ClipPPOLoss(
            actor,
            critic,
            clip_epsilon=ppo.clip_epsilon,
            entropy_coeff=ppo.entropy_coef,
            critic_coeff=1.0,
            loss_critic_type="smooth_l1",
            normalize_advantage=ppo.normalize_advantage,
            log_explained_variance=False,
            # the loss uses the modules' own parameters: no functional copies to swap in per call
            functional=False,
        )
        self.loss.set_keys(
            reward=REWARD_KEY, action=ACTION, sample_log_prob=LOG_PROB, value=VALUE, done=DONE,
            terminated=TERMINATED, advantage=ADVANTAGE, value_target=VALUE_TARGET,
        )

    def prepare(self, data: TensorDictBase) -> TensorDictBase:
        return data.select(*TRAIN_KEYS).reshape(-1)

    def __call__(self, flat: TensorDictBase, idx: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        out = self.loss(flat[idx])
        total = out["loss_objective"] + out["loss_critic"] + out["loss_entropy"]
        return total, torch.stack([out[k].detach() for k in TERMS])


class LeanPPOLoss:
    """Clipped PPO (objective, smooth-L1 critic, one-sample entropy of the tanh-Gaussian)."""

    def __init__(self, actor: ProbabilisticActor, critic: nn.Module, ppo: PPOConfig,
                 precision: str | None = None):
        """`precision`: "fp32" or "bf16", as `resolve_precision` gives it (default: ppo.precision,
        which must then be one of the two)."""
        self.head = PolicyHead(actor)
        self.value = plain_forward(critic.module)
        self.clip = (math.log1p(-ppo.clip_epsilon), math.log1p(ppo.clip_epsilon))
        self.entropy_coef = ppo.entropy_coef
        self.normalize_advantage = ppo.normalize_advantage
        device = next(critic.parameters()).device
        self.precision = precision or ppo.precision
        if self.precision not in ("fp32", "bf16"):
            raise ValueError(f"unresolved precision {self.precision!r}: pass resolve_precision(cfg)")
        self.autocast = (partial(torch.autocast, device.type, dtype=torch.bfloat16)
                         if self.precision == "bf16" else contextlib.nullcontext)

    def networks(self, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(loc, scale, value) in fp32; the MLPs themselves under autocast when bf16."""
        with self.autocast():
            out, value = self.head.net(obs), self.value(obs)
        loc, scale = self.head.scale_map(out.float())
        return loc, scale, value.float()

    def log_weight(self, batch: dict[str, torch.Tensor], idx: torch.Tensor, loc: torch.Tensor,
                   scale: torch.Tensor) -> torch.Tensor:
        """log(new / old probability) of the stored actions, [m, agents, 1], fp32."""
        log_prob = gaussian_log_prob((batch["u"][idx] - loc) / scale, scale.log()) - batch["log_jac"][idx]
        return (log_prob - batch["old_log_prob"][idx]).unsqueeze(-1)

    def prepare(self, data: TensorDictBase) -> dict[str, torch.Tensor]:
        """Flat [frames, agents, ...] tensors, with the pre-tanh actions and their log-Jacobian."""
        flat = data.select(*TRAIN_KEYS, PREIMAGE, strict=False).reshape(-1)
        h = self.head
        u = flat.get(PREIMAGE, None)
        if u is None:  # collected by the ProbabilisticActor: invert the squashing as torchrl does
            y = (flat.get(ACTION) - h.mid) / h.half
            u = y.clamp(-h.tanh_limit, h.tanh_limit).atanh()
        return {
            "obs": flat.get(OBS),
            "u": u,
            "log_jac": tanh_log_jacobian(u, h.log_half),
            "old_log_prob": flat.get(LOG_PROB),
            "advantage": flat.get(ADVANTAGE),
            "target": flat.get(VALUE_TARGET),
        }

    def __call__(self, batch: dict[str, torch.Tensor], idx: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        loc, scale, value = self.networks(batch["obs"][idx])
        log_scale = scale.log()
        log_weight = self.log_weight(batch, idx, loc, scale)
        adv = batch["advantage"][idx]
        if self.normalize_advantage:
            adv = (adv - adv.mean()) / adv.std().clamp_min(1e-6)
        clipped = log_weight.clamp(*self.clip)
        gain = torch.minimum(log_weight.exp() * adv, clipped.exp() * adv)
        loss_objective = -gain.mean()
        # entropy: -log p of one reparameterised sample per agent (no closed form after tanh)
        noise = torch.randn_like(loc)
        u = loc + scale * noise
        entropy = -(gaussian_log_prob(noise, log_scale) - tanh_log_jacobian(u, self.head.log_half)).mean()
        loss_entropy = -self.entropy_coef * entropy
        loss_critic = F.smooth_l1_loss(value, batch["target"][idx])
        total = loss_objective + loss_critic + loss_entropy
        with torch.no_grad():
            terms = torch.stack([
                loss_objective, loss_critic, loss_entropy, entropy,
                (log_weight != clipped).float().mean(), -log_weight.mean(),
            ])
        return total, terms


def make_loss(actor: ProbabilisticActor, critic: nn.Module, ppo: PPOConfig,
              precision: str) -> LeanPPOLoss | TorchrlPPOLoss:
    """The loss `ppo.loss` names; `precision` is `resolve_precision(cfg)` (always fp32 for
    torchrl's loss: an explicit bf16 with it is refused when the config is composed)."""
    if ppo.loss == "torchrl":
        return TorchrlPPOLoss(actor, critic, ppo)
    return LeanPPOLoss(actor, critic, ppo, precision)
