"""Mixed precision in the PPO update (ppo.precision): bf16 forward passes, fp32 everywhere else."""

from __future__ import annotations

from dataclasses import replace

import pytest
import torch

from sigmarl.compose import compose_config
from sigmarl.errors import SigmarlError
from sigmarl.training.learner import Learner
from sigmarl.training.mappo import collect
from sigmarl.training.ppo_loss import TERMS, PPOLoss, cpu_has_native_bf16, resolve_precision

# Stated tolerance of a bf16 update against fp32 (bf16 keeps 8 significant bits, relative
# rounding 2^-9 = 0.2% per operation; three layers of 256 accumulate to about 1%): each loss
# term within 2% of its fp32 value plus 2e-3 absolute, gradients within cosine 0.99.
RTOL, ATOL, COSINE = 0.02, 2e-3, 0.99


@pytest.fixture(scope="module")
def setup():
    # the paper's network (256 x 256), a small real rollout of the training environment
    cfg = compose_config(["tracking.enabled=false", "ppo=smoke", "ppo.num_envs=4",
                          "ppo.frames_per_iteration=128", "ppo.entropy_coef=0.01"])
    torch.manual_seed(0)
    parts = Learner(cfg, [cfg.seed], torch.device("cpu"))
    parts.reseed(0)
    data = parts.advantage(collect(parts.batches))
    with torch.no_grad():
        for p in parts.actor.parameters():  # leave the collecting policy: ratios away from 1
            p.add_(torch.randn_like(p) * 0.05)
    yield cfg, parts, data
    parts.close()


def _loss(cfg, parts, precision: str) -> PPOLoss:
    return PPOLoss(parts.head, parts.actor, parts.critic, replace(cfg.ppo, precision=precision), precision,
                   parts.streams)


def _terms_and_grads(loss, data, idx, parts):
    batch = loss.prepare(data)
    parts.streams.seed([3])  # the same entropy noise
    total, terms = loss(batch, idx.unsqueeze(0))
    grads = torch.autograd.grad(total, [*parts.actor.parameters(), *parts.critic.parameters()])
    return terms[0], torch.cat([g.flatten() for g in grads])


def test_bf16_update_agrees_with_fp32(setup):
    cfg, parts, data = setup
    idx = torch.randperm(data.numel(), generator=torch.Generator().manual_seed(1))[:64]
    t32, g32 = _terms_and_grads(_loss(cfg, parts, "fp32"), data, idx, parts)
    t16, g16 = _terms_and_grads(_loss(cfg, parts, "bf16"), data, idx, parts)
    assert t16.dtype == torch.float32 and g16.dtype == torch.float32
    for name, a, b in zip(TERMS, t16.tolist(), t32.tolist(), strict=True):
        assert a == pytest.approx(b, rel=RTOL, abs=ATOL), name
    assert not torch.equal(t16, t32)  # bf16 was really in use
    assert torch.nn.functional.cosine_similarity(g16, g32, dim=0) > COSINE


def test_log_probabilities_and_ratios_stay_fp32(setup):
    cfg, parts, data = setup
    loss = _loss(cfg, parts, "bf16")
    batch = loss.prepare(data)
    idx = torch.arange(32).unsqueeze(0)  # seed 0's first 32 frames
    obs = batch["obs"][loss.seeds, idx]
    with loss.autocast():  # inside the autocast region the MLP itself computes in bf16
        assert loss.actor(obs).dtype == torch.bfloat16
    loc, scale, value = loss.networks(obs)
    assert loc.dtype == scale.dtype == value.dtype == torch.float32
    log_weight = loss.log_weight(batch, idx, loc, scale)
    assert log_weight.dtype == torch.float32 and log_weight.exp().dtype == torch.float32
    assert batch["advantage"].dtype == torch.float32


def test_precision_choice():
    def resolved(*overrides):
        return resolve_precision(compose_config(list(overrides)))

    assert resolved("ppo.precision=fp32") == "fp32" and resolved("ppo.precision=bf16") == "bf16"
    assert resolved("ppo.precision=auto") == ("bf16" if cpu_has_native_bf16() else "fp32")
    # torchrl's loss (which would compute log-probabilities in bf16) is no choice of training
    with pytest.raises(SigmarlError, match="ppo.loss"):
        compose_config(["ppo.precision=auto", "ppo.loss=torchrl"])
    with pytest.raises(SigmarlError, match="ppo.precision"):
        compose_config(["ppo.precision=fp16"])
    assert compose_config([]).ppo.precision == "fp32"  # the default stays fp32


def test_the_loss_takes_the_precision_resolved_once(setup):
    # `auto` is resolved by resolve_precision(cfg) alone; the loss never resolves it again
    cfg, parts, _ = setup
    ppo = replace(cfg.ppo, precision="auto")
    assert PPOLoss(parts.head, parts.actor, parts.critic, ppo, "bf16", parts.streams).precision == "bf16"
    with pytest.raises(ValueError, match="unresolved"):
        PPOLoss(parts.head, parts.actor, parts.critic, ppo, ppo.precision, parts.streams)
