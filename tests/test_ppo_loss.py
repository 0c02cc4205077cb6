"""The lean PPO loss against torchrl's ClipPPOLoss, the independent oracle: same terms, same
gradients, on a real rollout batch of the training environment."""

from __future__ import annotations

import pytest
import torch

from sigmarl.compose import compose_config
from sigmarl.errors import SigmarlError
from sigmarl.training.loop import build, train
from sigmarl.training.mappo import collect
from sigmarl.training.ppo_loss import TERMS, LeanPPOLoss, TorchrlPPOLoss


@pytest.fixture(scope="module")
def setup():
    cfg = compose_config([
        "tracking.enabled=false", "ppo=smoke", "ppo.num_envs=4", "ppo.frames_per_iteration=128",
        "ppo.entropy_coef=0.01", "network.hidden=[32,32]",
    ])
    torch.manual_seed(0)
    parts = build(cfg, torch.device("cpu"))
    data = collect(iter(parts.collector))
    with torch.no_grad():
        parts.gae(data)
    # move the policy away from the one that collected, so that ratios leave 1 and some clip
    with torch.no_grad():
        for p in parts.actor.parameters():
            p.add_(torch.randn_like(p) * 0.05)
    yield cfg, parts, data
    parts.close()


def _run(loss, data, idx, seed: int):
    batch = loss.prepare(data)
    torch.manual_seed(seed)  # the same noise for the entropy sample
    return loss(batch, idx)


def _grads(parts, total) -> list[torch.Tensor]:
    params = [*parts.actor.parameters(), *parts.critic.parameters()]
    return torch.autograd.grad(total, params)


def test_lean_loss_equals_clip_ppo_loss(setup) -> None:
    cfg, parts, data = setup
    lean = LeanPPOLoss(parts.actor, parts.critic, cfg.ppo)
    ref = TorchrlPPOLoss(parts.actor, parts.critic, cfg.ppo)
    idx = torch.randperm(data.numel(), generator=torch.Generator().manual_seed(1))[:64]
    total_l, terms_l = _run(lean, data, idx, seed=7)
    total_r, terms_r = _run(ref, data, idx, seed=7)
    values = dict(zip(TERMS, terms_l.tolist(), strict=True))
    assert 0 < values["clip_fraction"] < 1  # both branches of the clipped objective are in play
    torch.testing.assert_close(terms_l, terms_r, rtol=1e-4, atol=1e-6)
    torch.testing.assert_close(total_l, total_r, rtol=1e-4, atol=1e-6)
    for g_l, g_r in zip(_grads(parts, _run(lean, data, idx, 7)[0]), _grads(parts, _run(ref, data, idx, 7)[0]),
                        strict=True):
        torch.testing.assert_close(g_l, g_r, rtol=1e-3, atol=1e-6)


def test_lean_loss_scores_the_collected_actions_like_the_actor(setup) -> None:
    """Before any update the ratio is 1 for actions away from saturation: the pre-tanh actions
    and log-Jacobians recovered once per iteration score exactly what the actor sampled."""
    cfg, parts, _ = setup
    fresh = build(cfg, torch.device("cpu"))
    try:
        data = collect(iter(fresh.collector))
        with torch.no_grad():
            fresh.gae(data)
        lean = LeanPPOLoss(fresh.actor, fresh.critic, cfg.ppo)
        batch = lean.prepare(data)
        high = fresh.dims["action_high"]
        inside = (data["agents", "action"].reshape(-1, *batch["u"].shape[1:]).abs() < 0.999 * high).all(-1)
        with torch.no_grad():
            loc, scale = lean.scale_map(lean.policy(batch["obs"]))
            z = (batch["u"] - loc) / scale
            lp = (-0.5 * z * z - scale.log() - 0.5 * torch.log(torch.tensor(2 * torch.pi))).sum(-1) - batch["log_jac"]
        assert inside.float().mean() > 0.5
        torch.testing.assert_close(lp[inside], batch["old_log_prob"][inside], rtol=0, atol=1e-3)
    finally:
        fresh.close()


def test_unknown_loss_is_rejected(tmp_path) -> None:
    cfg = compose_config(["tracking.enabled=false", "ppo=smoke", "ppo.loss=clipped", f"run_dir={tmp_path}"])
    with pytest.raises(SigmarlError, match="ppo.loss"):
        train(cfg)
