"""The lean PPO loss against torchrl's ClipPPOLoss, the independent oracle: same terms, same
gradients, on a real rollout batch of the training environment."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest
import torch
from torchrl.envs.utils import ExplorationType, set_exploration_type

from sigmarl.compose import compose_config
from sigmarl.errors import SigmarlError
from sigmarl.training.lone import LoneLearner
from sigmarl.training.mappo import collect
from sigmarl.training.networks import ACTION, LOG_PROB, OBS, PREIMAGE, make_sampler
from sigmarl.training.ppo_loss import TERMS, LeanPPOLoss, TorchrlPPOLoss


@pytest.fixture(scope="module", params=[(True, True), (True, False), (False, True)],
                ids=["shared_value", "value_per_agent", "decentralised_critic"])
def setup(request):
    centralised, shared = request.param
    cfg = compose_config([
        "tracking.enabled=false", "ppo=smoke", "ppo.num_envs=4", "ppo.frames_per_iteration=128",
        "ppo.entropy_coef=0.01", "network.hidden=[32,32]",
        f"network.shared_critic_value={shared}", f"network.centralised_critic={centralised}",
    ])
    torch.manual_seed(0)
    parts = LoneLearner(cfg, torch.device("cpu"))
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


@pytest.mark.parametrize("normalize_advantage", [False, True])
def test_lean_loss_equals_clip_ppo_loss(setup, normalize_advantage) -> None:
    cfg, parts, data = setup
    ppo = replace(cfg.ppo, normalize_advantage=normalize_advantage)
    lean = LeanPPOLoss(parts.actor, parts.critic, ppo)
    ref = TorchrlPPOLoss(parts.actor, parts.critic, ppo)
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


def test_lean_loss_scores_the_collected_actions_like_the_sampler(setup) -> None:
    """Before any update the ratio is 1: from the stored pre-tanh sample for every action,
    and from the inverted tanh (rollouts without it) for actions away from saturation."""
    cfg, parts, _ = setup
    fresh = LoneLearner(cfg, torch.device("cpu"))
    try:
        data = collect(iter(fresh.collector))
        with torch.no_grad():
            fresh.gae(data)
        lean = LeanPPOLoss(fresh.actor, fresh.critic, cfg.ppo)
        for rollout in (data, data.exclude(PREIMAGE)):
            batch = lean.prepare(rollout)
            with torch.no_grad():
                loc, scale = lean.head.loc_scale(batch["obs"])
                z = (batch["u"] - loc) / scale
                lp = (-0.5 * z * z - scale.log() - 0.5 * math.log(2 * math.pi)).sum(-1) - batch["log_jac"]
            keep = torch.ones_like(lp, dtype=torch.bool)
            if PREIMAGE not in rollout.keys(True):
                high = fresh.dims["action_high"]
                keep = (rollout[ACTION].reshape(*lp.shape, -1).abs() < 0.999 * high).all(-1)
                assert keep.float().mean() > 0.5
            torch.testing.assert_close(lp[keep], batch["old_log_prob"][keep], rtol=0, atol=1e-3)
    finally:
        fresh.close()


def test_unknown_loss_is_rejected(tmp_path) -> None:
    # at composition, before anything trains (sigmarl.validate)
    with pytest.raises(SigmarlError, match="ppo.loss"):
        compose_config(["tracking.enabled=false", "ppo=smoke", "ppo.loss=clipped", f"run_dir={tmp_path}"])
    assert not any(tmp_path.iterdir())


def test_sampler_draws_what_the_probabilistic_actor_draws(setup) -> None:
    """Same seed, same observations: the collection sampler returns the ProbabilisticActor's
    actions and log-probabilities (torchrl's TanhNormal), and its pre-tanh sample maps onto them."""
    _, parts, data = setup
    obs = data[:, :5].reshape(-1).select(OBS)
    torch.manual_seed(3)
    with set_exploration_type(ExplorationType.RANDOM):
        ref = parts.actor(obs.clone())
    torch.manual_seed(3)
    ours = make_sampler(parts.actor)(obs.clone())
    torch.testing.assert_close(ours[ACTION], ref[ACTION], rtol=0, atol=1e-6)
    torch.testing.assert_close(ours[LOG_PROB], ref[LOG_PROB], rtol=1e-5, atol=1e-4)
    high = parts.dims["action_high"]
    torch.testing.assert_close(ours[PREIMAGE].tanh() * high, ours[ACTION], rtol=0, atol=1e-6)
    assert ours[ACTION].std() > 0.05  # a stochastic policy, not the mean


def test_update_runs_either_loss_and_moves_the_weights(setup) -> None:
    from sigmarl.training.mappo import update

    cfg, parts, data = setup
    ppo = replace(cfg.ppo, epochs=1, minibatch_size=64)
    for loss in (LeanPPOLoss(parts.actor, parts.critic, ppo), TorchrlPPOLoss(parts.actor, parts.critic, ppo)):
        before = [p.detach().clone() for p in parts.actor.parameters()]
        terms = update(data, loss, parts.optimiser, ppo)
        assert set(terms) == set(TERMS) and all(math.isfinite(v) for v in terms.values())
        assert any(not torch.equal(b, p) for b, p in zip(before, parts.actor.parameters(), strict=True))
