"""The paper's actor and critic as torchrl modules.

Actor: one MLP shared by all agents, observation D -> hidden -> 4 = (mean, scale) of a Gaussian
squashed by tanh into the action box. Critic: one centralised MLP over all agents' observations
(N*D -> hidden -> 1); its single value is shared by all agents.
"""

from __future__ import annotations

import torch
from omegaconf import DictConfig
from tensordict.nn import NormalParamExtractor, TensorDictModule
from torch import nn
from torchrl.modules import MultiAgentMLP, ProbabilisticActor, TanhNormal

OBS = ("agents", "observation")
ACTION = ("agents", "action")
LOC, SCALE = ("agents", "loc"), ("agents", "scale")
VALUE = ("agents", "state_value")

_ACTIVATIONS: dict[str, type[nn.Module]] = {"tanh": nn.Tanh, "relu": nn.ReLU, "elu": nn.ELU}


def _activation(name: str) -> type[nn.Module]:
    from sigmarl.errors import SigmarlError

    if name not in _ACTIVATIONS:
        raise SigmarlError(f"unknown network.activation {name!r}; choose from {sorted(_ACTIVATIONS)}")
    return _ACTIVATIONS[name]


def make_actor(
    net: DictConfig,
    obs_dim: int,
    n_agents: int,
    action_low: torch.Tensor,
    action_high: torch.Tensor,
    device: str | torch.device = "cpu",
) -> ProbabilisticActor:
    """Decentralised, parameter-shared policy; its deterministic action is box * tanh(mean).

    The parameters do not depend on `n_agents`, so a policy trained with 4 agents loads into an
    actor built for any other number of agents.
    """
    n_actions = action_low.shape[-1]
    mlp = MultiAgentMLP(
        n_agent_inputs=obs_dim,
        n_agent_outputs=2 * n_actions,
        n_agents=n_agents,
        centralised=False,
        share_params=True,
        device=device,
        depth=len(net.hidden),
        num_cells=list(net.hidden),
        activation_class=_activation(net.activation),
    )
    # scale = softplus shifted so that a zero input gives 1, floored at scale_floor
    params = NormalParamExtractor(scale_mapping=f"biased_softplus_1.0_{net.scale_floor}")
    module = TensorDictModule(nn.Sequential(mlp, params), in_keys=[OBS], out_keys=[LOC, SCALE])
    return ProbabilisticActor(
        module,
        in_keys=[LOC, SCALE],
        out_keys=[ACTION],
        distribution_class=TanhNormal,
        distribution_kwargs={"low": action_low.to(device), "high": action_high.to(device)},
        return_log_prob=True,
    )


def make_critic(
    net: DictConfig, obs_dim: int, n_agents: int, device: str | torch.device = "cpu"
) -> TensorDictModule:
    """Centralised value over all agents' observations.

    `shared_critic_value=True` (the paper): one MLP evaluated once per state, its value copied to
    every agent. False: every agent gets its own output head on the same centralised input.
    """
    shared = bool(net.shared_critic_value)
    mlp = MultiAgentMLP(
        n_agent_inputs=obs_dim,
        n_agent_outputs=1,
        n_agents=n_agents,
        centralised=True,
        share_params=shared,
        device=device,
        depth=len(net.hidden),
        num_cells=list(net.hidden),
        activation_class=_activation(net.activation),
    )
    return TensorDictModule(mlp, in_keys=[OBS], out_keys=[VALUE])
