"""The critic as an axis: centralised (MAPPO, the paper's) or decentralised (IPPO), checked on
the networks' shapes and on what each agent's value can depend on."""

from __future__ import annotations

import pytest
import torch

from sigmarl.compose import compose_config
from sigmarl.config import NetworkConfig
from sigmarl.training.networks import OBS, make_critic, plain_forward

D, A = 7, 4


def _values(critic, obs: torch.Tensor) -> torch.Tensor:
    from tensordict import TensorDict

    return critic(TensorDict({OBS: obs}, batch_size=obs.shape[:1]))[("agents", "state_value")]


def _first_layer(critic) -> torch.Size:
    return critic.module.params["0", "weight"].shape


@pytest.mark.parametrize("shared", [True, False])
def test_a_decentralised_critic_values_each_agent_on_its_own_observation(shared) -> None:
    torch.manual_seed(0)
    critic = make_critic(NetworkConfig(hidden=[16, 16], centralised_critic=False, shared_critic_value=shared), D, A)
    # input D (its own observation), one output per agent; shared: one MLP (no agent dimension)
    assert _first_layer(critic) == ((16, D) if shared else (A, 16, D))
    obs = torch.randn(5, A, D)
    before = _values(critic, obs)
    assert before.shape == (5, A, 1)
    changed = obs.clone()
    changed[:, 2] += 1.0  # agent 2's observation only
    after = _values(critic, changed)
    keep = [0, 1, 3]
    assert torch.equal(after[:, keep], before[:, keep])
    assert not torch.allclose(after[:, 2], before[:, 2])
    if shared:  # one MLP: agent 0 seeing agent 2's observation values it as agent 2
        swapped = obs.clone()
        swapped[:, 0] = changed[:, 2]
        assert torch.allclose(_values(critic, swapped)[:, 0], after[:, 2])


def test_the_centralised_critic_sees_every_agents_observation() -> None:
    torch.manual_seed(0)
    critic = make_critic(NetworkConfig(hidden=[16, 16]), D, A)
    assert _first_layer(critic) == (16, A * D)  # all agents' observations, flattened
    obs = torch.randn(5, A, D)
    before = _values(critic, obs)
    assert torch.equal(before, before[:, :1].expand_as(before))  # one value, copied to each agent
    changed = obs.clone()
    changed[:, 2] += 1.0
    assert not torch.allclose(_values(critic, changed)[:, 0], before[:, 0])


@pytest.mark.parametrize("centralised", [True, False])
def test_plain_forward_computes_the_critics_values(centralised) -> None:
    torch.manual_seed(1)
    critic = make_critic(NetworkConfig(hidden=[8], centralised_critic=centralised), D, A)
    obs = torch.randn(3, A, D)
    assert torch.allclose(plain_forward(critic.module)(obs), _values(critic, obs), atol=1e-6)


def test_the_critic_switch_is_a_training_setting() -> None:
    base = compose_config(["tracking.enabled=false"])
    ippo = compose_config(["tracking.enabled=false", "network.centralised_critic=false"])
    assert base.network.centralised_critic is True
    assert ippo.fingerprint != base.fingerprint
