"""The PPO loss against torchrl's ClipPPOLoss, the independent oracle: same terms, same
gradients, on a real rollout batch of the training environment (one seed: a block of one)."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest
import torch
from torchrl.envs.utils import ExplorationType, set_exploration_type
from torchrl.objectives import ClipPPOLoss

from sigmarl.compose import compose_config
from sigmarl.errors import SigmarlError
from sigmarl.training.learner import Learner
from sigmarl.training.mappo import collect
from sigmarl.training.networks import ACTION, LOG_PROB, OBS, PREIMAGE, VALUE, make_sampler
from sigmarl.training.ppo_loss import (
    ADVANTAGE,
    DONE,
    REWARD_KEY,
    TERMINATED,
    TERMS,
    VALUE_TARGET,
    PPOLoss,
    resolve_precision,
)


def clip_ppo_loss(learner: Learner, ppo):
    """torchrl's ClipPPOLoss over the seed's torchrl modules (synchronised with the stacked
    networks first); a function of (data, idx) giving (total, terms) like ours."""
    actor, critic = learner.networks(0)
    learner.state(0)  # writes the stacked parameters into the torchrl modules
    loss = ClipPPOLoss(actor, critic, clip_epsilon=ppo.clip_epsilon, entropy_coeff=ppo.entropy_coef,
                       critic_coeff=1.0, loss_critic_type="smooth_l1", normalize_advantage=ppo.normalize_advantage,
                       log_explained_variance=False, functional=False)
    loss.set_keys(reward=REWARD_KEY, action=ACTION, sample_log_prob=LOG_PROB, value=VALUE, done=DONE,
                  terminated=TERMINATED, advantage=ADVANTAGE, value_target=VALUE_TARGET)

    def run(data, idx):
        out = loss(data.select(OBS, ACTION, LOG_PROB, ADVANTAGE, VALUE_TARGET).reshape(-1)[idx])
        total = out["loss_objective"] + out["loss_critic"] + out["loss_entropy"]
        return total, torch.stack([out[k].detach() for k in TERMS])
    return run


def _parameters(learner: Learner, torchrl_modules: bool) -> list[torch.Tensor]:
    """The actor's then the critic's parameters, as the stacked tensors or the torchrl modules'
    (the same order: what a checkpoint's optimiser state is indexed by)."""
    if not torchrl_modules:
        return list(learner.optimiser.param_groups[0]["params"])
    actor, critic = learner.networks(0)
    mlps = [actor.module[0].module[0], critic.module]
    return [m.params[name, kind] for m, stacked in zip(mlps, (learner.actor, learner.critic), strict=True)
            for name, kind in stacked._names]


def _loss(cfg, learner: Learner, ppo=None) -> PPOLoss:
    return PPOLoss(learner.head, learner.actor, learner.critic, ppo or cfg.ppo, resolve_precision(cfg),
                   learner.streams)


@pytest.fixture(scope="module", params=[(True, True), (True, False), (False, True), (False, False)],
                ids=["shared_value", "value_per_agent", "decentralised_critic", "decentralised_per_agent"])
def setup(request):
    centralised, shared = request.param
    cfg = compose_config([
        "tracking.enabled=false", "ppo=smoke", "ppo.num_envs=4", "ppo.frames_per_iteration=128",
        "ppo.entropy_coef=0.01", "network.hidden=[32,32]",
        f"network.shared_critic_value={shared}", f"network.centralised_critic={centralised}",
    ])
    parts = Learner(cfg, [cfg.seed], torch.device("cpu"))
    parts.reseed(0)
    data = parts.advantage(collect(parts.batches))
    # move the policy away from the one that collected, so that ratios leave 1 and some clip
    torch.manual_seed(0)
    with torch.no_grad():
        for p in parts.actor.parameters():
            p.add_(torch.randn_like(p) * 0.05)
    parts.state(0)
    yield cfg, parts, data
    parts.close()


def _run(loss, data, idx, seed: int, learner):
    if isinstance(loss, PPOLoss):
        learner.streams.seed([seed])  # the entropy sample's noise, drawn as torch.randn draws it
        total, terms = loss(loss.prepare(data), idx.unsqueeze(0))
        return total, terms[0]
    torch.manual_seed(seed)  # the same noise for the oracle's entropy sample
    return loss(data, idx)


@pytest.mark.parametrize("normalize_advantage", [False, True])
def test_the_loss_equals_clip_ppo_loss(setup, normalize_advantage) -> None:
    cfg, parts, data = setup
    ppo = replace(cfg.ppo, normalize_advantage=normalize_advantage)
    ours, ref = _loss(cfg, parts, ppo), clip_ppo_loss(parts, ppo)
    idx = torch.randperm(data.numel(), generator=torch.Generator().manual_seed(1))[:64]
    total_l, terms_l = _run(ours, data, idx, 7, parts)
    total_r, terms_r = _run(ref, data, idx, 7, parts)
    values = dict(zip(TERMS, terms_l.tolist(), strict=True))
    assert 0 < values["clip_fraction"] < 1  # both branches of the clipped objective are in play
    torch.testing.assert_close(terms_l, terms_r, rtol=1e-4, atol=1e-6)
    torch.testing.assert_close(total_l, total_r, rtol=1e-4, atol=1e-6)
    grads_l = torch.autograd.grad(_run(ours, data, idx, 7, parts)[0], _parameters(parts, False))
    grads_r = torch.autograd.grad(_run(ref, data, idx, 7, parts)[0], _parameters(parts, True))
    for g_l, g_r in zip(grads_l, grads_r, strict=True):
        torch.testing.assert_close(g_l[0], g_r, rtol=1e-3, atol=1e-6)


def test_the_loss_scores_the_collected_actions_like_the_sampler(setup) -> None:
    """Before any update the ratio is 1: from the stored pre-tanh sample for every action,
    and from the inverted tanh (rollouts without it) for actions away from saturation."""
    cfg, _, _ = setup
    fresh = Learner(cfg, [cfg.seed], torch.device("cpu"))
    try:
        fresh.reseed(0)
        data = fresh.advantage(collect(fresh.batches))
        ours = _loss(cfg, fresh)
        for rollout in (data, data.exclude(PREIMAGE)):
            batch = ours.prepare(rollout)
            with torch.no_grad():
                loc, scale = ours.head.scale_map(fresh.actor(batch["obs"]))
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
    # at composition, before anything trains (sigmarl.compose.validate); torchrl's loss is the tests' oracle only
    for name in ("clipped", "torchrl"):
        with pytest.raises(SigmarlError, match="ppo.loss"):
            compose_config(["tracking.enabled=false", "ppo=smoke", f"ppo.loss={name}", f"run_dir={tmp_path}"])
    assert not any(tmp_path.iterdir())


def test_sampler_draws_what_the_probabilistic_actor_draws(setup) -> None:
    """Same seed, same observations: the collection sampler returns the ProbabilisticActor's
    actions and log-probabilities (torchrl's TanhNormal), and its pre-tanh sample maps onto them."""
    _, parts, data = setup
    obs = data[:, :5].reshape(-1).select(OBS)
    actor, _ = parts.networks(0)
    torch.manual_seed(3)
    with set_exploration_type(ExplorationType.RANDOM):
        ref = actor(obs.clone())
    parts.streams.seed([3])
    ours = make_sampler(parts.head, parts.actor, parts.streams)(obs.clone())
    torch.testing.assert_close(ours[ACTION], ref[ACTION], rtol=0, atol=1e-6)
    torch.testing.assert_close(ours[LOG_PROB], ref[LOG_PROB], rtol=1e-5, atol=1e-4)
    high = parts.dims["action_high"]
    torch.testing.assert_close(ours[PREIMAGE].tanh() * high, ours[ACTION], rtol=0, atol=1e-6)
    assert ours[ACTION].std() > 0.05  # a stochastic policy, not the mean


def test_update_moves_the_weights(setup) -> None:
    from sigmarl.training.mappo import update

    cfg, parts, data = setup
    ppo = replace(cfg.ppo, epochs=1, minibatch_size=64)
    before = [p.detach().clone() for p in parts.actor.parameters()]
    (terms,) = update(data, _loss(cfg, parts, ppo), parts.optimiser, ppo)
    assert set(terms) == set(TERMS) and all(math.isfinite(v) for v in terms.values())
    assert any(not torch.equal(b, p) for b, p in zip(before, parts.actor.parameters(), strict=True))
