"""The paper's actor and critic: as torchrl modules (what checkpoints hold and evaluation runs),
and as the S stacked copies a training of S seeds computes with (S = 1 for one seed).

Actor: one MLP shared by all agents, observation D -> hidden -> 4 = (mean, scale) of a Gaussian
squashed by tanh into the action box. Critic (the paper's, MAPPO): one centralised MLP over all
agents' observations (N*D -> hidden -> 1); its single value is shared by all agents. With
`network.centralised_critic=false` (IPPO) it sees only each agent's own observation.

Training: `StackedMLP` holds seed k's parameters at index k of stacked tensors, computed with
batched matrix products (`torch.baddbmm`). Each copy is built from a torchrl module initialised
as that seed initialises it, and is written back into it (`unstack`) for a checkpoint, so the
checkpoint format is the torchrl modules' `state_dict`. Parameters keep the module's order, so
one Adam over the stacked tensors holds, index for index, each seed's own Adam (Adam is
elementwise).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import torch
import torch.nn.functional as F
from tensordict.nn import NormalParamExtractor, TensorDictModule
from torch import nn
from torchrl.modules import MultiAgentMLP, ProbabilisticActor, TanhNormal

from sigmarl.config import NetworkConfig
from sigmarl.env.streams import SeedStreams

OBS = ("agents", "observation")
ACTION = ("agents", "action")
LOG_PROB = ("agents", "action_log_prob")
PREIMAGE = ("agents", "action_preimage")  # the Gaussian sample before tanh
LOC, SCALE = ("agents", "loc"), ("agents", "scale")
VALUE = ("agents", "state_value")

# the choices of network.activation (sigmarl.compose.validate.Activation, checked at composition)
ACTIVATIONS: dict[str, type[nn.Module]] = {"tanh": nn.Tanh, "relu": nn.ReLU, "elu": nn.ELU}


def make_actor(
    net: NetworkConfig,
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
    mlp = _mlp(net, obs_dim, 2 * action_low.shape[-1], n_agents, False, True, device)
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
    net: NetworkConfig, obs_dim: int, n_agents: int, device: str | torch.device = "cpu"
) -> TensorDictModule:
    """The value of each agent's state, [..., A, D] observations -> [..., A, 1] values.

    `centralised_critic=True` (MAPPO, the paper's): the MLP's input is all agents'
    observations (A*D). With `shared_critic_value=True` (the paper's) it is one MLP evaluated
    once per state, its value copied to every agent; False: every agent its own output head
    on that input. `centralised_critic=False` (IPPO): the input is the agent's own observation
    (D); `shared_critic_value=True` gives one MLP applied to each agent (its parameters do not
    depend on A), False one MLP per agent.
    """
    centralised, shared = bool(net.centralised_critic), bool(net.shared_critic_value)
    mlp = _mlp(net, obs_dim, 1, n_agents, centralised, shared, device)
    return TensorDictModule(mlp, in_keys=[OBS], out_keys=[VALUE])


def _mlp(net: NetworkConfig, obs_dim: int, n_outputs: int, n_agents: int, centralised: bool,
         share_params: bool, device: str | torch.device) -> MultiAgentMLP:
    """A MultiAgentMLP of the configured hidden layers and activation."""
    return MultiAgentMLP(n_agent_inputs=obs_dim, n_agent_outputs=n_outputs, n_agents=n_agents,
                         centralised=centralised, share_params=share_params, device=device,
                         depth=len(net.hidden), num_cells=list(net.hidden),
                         activation_class=ACTIVATIONS[net.activation])


def plain_forward(net: MultiAgentMLP) -> Callable[[torch.Tensor], torch.Tensor]:
    """A parameter-shared MultiAgentMLP as plain layer calls on its own Parameters: the same
    outputs and gradients, without MultiAgentMLP swapping its parameters into a module on
    every call. Networks it does not cover (one MLP per agent) are returned as they are."""
    layers: list = []
    for name, module in net._empty_net.named_children():
        if isinstance(module, nn.Linear):
            layers.append((net.params[name, "weight"], net.params[name, "bias"]))
        elif isinstance(module, tuple(ACTIVATIONS.values())):
            layers.append(module)
        else:
            return net
    if not net.share_params:
        return net

    def forward(x: torch.Tensor) -> torch.Tensor:
        if net.centralized:
            x = x.flatten(-2)  # [..., A, D] -> [..., A * D]
        for layer in layers:
            x = F.linear(x, *layer) if isinstance(layer, tuple) else layer(x)
        if net.centralized:  # one value, shared by all agents
            x = x.unsqueeze(-2).expand(*x.shape[:-1], net.n_agents, x.shape[-1])
        return x

    return forward


HALF_LOG_2PI = 0.5 * math.log(2 * math.pi)


def gaussian_log_prob(z: torch.Tensor, log_scale: torch.Tensor) -> torch.Tensor:
    """log N(loc + scale z; loc, scale), summed over the action."""
    return (-0.5 * z * z - log_scale - HALF_LOG_2PI).sum(-1)


def tanh_log_jacobian(u: torch.Tensor, log_half: torch.Tensor) -> torch.Tensor:
    """log |d(mid + half tanh u)/du|, summed over the action; log(1 - tanh^2 u) written stably
    as 2 (log 2 - u - softplus(-2u)), as torch's TanhTransform does."""
    return (log_half + 2 * (math.log(2) - u - F.softplus(-2 * u))).sum(-1)


class PolicyHead:
    """The actor's pieces as plain tensor functions: (loc, scale) of the Gaussian and the box."""

    def __init__(self, actor: ProbabilisticActor):
        head = actor.module[0].module  # Sequential(MultiAgentMLP, NormalParamExtractor)
        self.net, self.scale_map = plain_forward(head[0]), head[1]
        box = actor.module[1].distribution_kwargs
        low, high = box["low"], box["high"]
        self.mid, self.half = (high + low) / 2, (high - low) / 2
        self.log_half = self.half.log()
        # torchrl's TanhNormal keeps tanh inside +-(1 - resolution)
        self.tanh_limit = 1.0 - torch.finfo(self.half.dtype).resolution

    def deterministic_action(self, obs: torch.Tensor) -> torch.Tensor:
        """The actor's action under ExplorationType.DETERMINISTIC: the TanhNormal's
        deterministic sample, the box's affine map of the clamped tanh of the mean, in the
        same order of operations (so the same bits); the scale is not needed."""
        loc = self.net(obs).chunk(2, -1)[0]
        return self.mid + self.half * loc.tanh().clamp(-self.tanh_limit, self.tanh_limit)


class StackedMLP(nn.Module):
    """S MultiAgentMLPs of one shape: parameter-shared (each agent's input through one MLP) or
    one MLP per agent (parameters [S, A, ...]); decentralised (each agent's own observation) or
    centralised (all agents' observations; shared: one value copied to every agent)."""

    def __init__(self, nets: list[MultiAgentMLP]):
        super().__init__()
        first = nets[0]
        self.centralised, self.shared = bool(first.centralized), bool(first.share_params)
        self.n_agents = int(first.n_agents)
        self.layers: list[tuple[int, int] | nn.Module] = []  # (weight, bias) slots or an activation
        params = []
        for name, module in first._empty_net.named_children():
            if isinstance(module, nn.Linear):
                for kind in ("weight", "bias"):
                    params.append(nn.Parameter(torch.stack([n.params[name, kind].detach() for n in nets]).clone()))
                self.layers.append((len(params) - 2, len(params) - 1))
            elif isinstance(module, tuple(ACTIVATIONS.values())):
                self.layers.append(module)
            else:
                raise ValueError(f"a StackedMLP cannot stack a {type(module).__name__}")
        self.params = nn.ParameterList(params)
        self._names = [(name, kind) for name, m in first._empty_net.named_children() if isinstance(m, nn.Linear)
                       for kind in ("weight", "bias")]

    @property
    def n_seeds(self) -> int:
        return int(self.params[0].shape[0])

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """[S, *batch, A, D] -> [S, *batch, A, out]. One MLP per agent runs as S * A batched ones."""
        s, *batch, a, d = x.shape
        if self.shared:
            x = x.reshape(s, -1, a * d) if self.centralised else x.reshape(s, -1, d)
        elif self.centralised:  # every agent's own MLP on the joint observation
            x = x.reshape(s, 1, -1, a * d).expand(s, a, -1, a * d).reshape(s * a, -1, a * d)
        else:
            x = x.reshape(s, -1, a, d).transpose(1, 2).reshape(s * a, -1, d)
        params, one = list(self.params), s == 1 and self.shared
        for layer in self.layers:
            if isinstance(layer, tuple):
                w, b = params[layer[0]], params[layer[1]]
                if one:  # one seed: a plain linear layer, a cheaper backward than a batch of one
                    x = F.linear(x, w.view(w.shape[1:]), b.view(b.shape[1:]))
                else:
                    x = torch.baddbmm(b.reshape(-1, 1, b.shape[-1]), x, w.reshape(-1, *w.shape[-2:]).transpose(1, 2))
            else:
                x = layer(x)
        out = x.shape[-1]
        if not self.shared:
            return x.reshape(s, a, -1, out).transpose(1, 2).reshape(s, *batch, a, out)
        if self.centralised:  # one value per state, shared by the agents
            return x.reshape(s, *batch, 1, out).expand(s, *batch, a, out)
        return x.reshape(s, *batch, a, out)

    @torch.no_grad()
    def unstack(self, k: int, net: MultiAgentMLP) -> None:
        """Write seed k's parameters into the torchrl network `net`."""
        for p, (name, kind) in zip(self.params, self._names, strict=True):
            net.params[name, kind].copy_(p[k])

    @torch.no_grad()
    def restack(self, k: int, net: MultiAgentMLP) -> None:
        """Set seed k's parameters from the torchrl network `net` (a resume)."""
        for p, (name, kind) in zip(self.params, self._names, strict=True):
            p[k].copy_(net.params[name, kind])


def per_seed(fn, n_seeds: int):
    """`fn` on [S, ...] tensors as a function of [S * E, ...] tensors (the environment's
    layout: seed k's environments are rows k*E .. (k+1)*E)."""
    def apply(x: torch.Tensor) -> torch.Tensor:
        out = fn(x.reshape(n_seeds, x.shape[0] // n_seeds, *x.shape[1:]))
        return out.reshape(x.shape[0], *out.shape[2:])
    return apply


class Sampler(nn.Module):
    """The exploration policy that collects training rollouts, as plain tensor maths: the
    ProbabilisticActor's TanhNormal, each seed's Gaussian noise from its own generator, drawn as
    `torch.normal(loc, scale)` draws it (N(0, 1) scaled and shifted), so a seed draws the actor's
    actions. It also returns the pre-tanh sample, so that the loss scores an action exactly
    instead of inverting a saturated tanh. Evaluation uses the actor itself."""

    def __init__(self, head: PolicyHead, actor: StackedMLP, streams: SeedStreams):
        super().__init__()
        self.head, self.actor, self.streams = head, actor, streams

    def forward(self, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        h = self.head
        loc, scale = h.scale_map(per_seed(self.actor, self.actor.n_seeds)(obs))
        z = self.streams.randn((loc.shape[0] // self.actor.n_seeds, *loc.shape[1:]))
        u = z * scale + loc
        action = h.mid + h.half * u.tanh().clamp(-h.tanh_limit, h.tanh_limit)
        log_prob = gaussian_log_prob((u - loc) / scale, scale.log()) - tanh_log_jacobian(u, h.log_half)
        return action, log_prob, u


def make_sampler(head: PolicyHead, actor: StackedMLP, streams: SeedStreams) -> TensorDictModule:
    return TensorDictModule(Sampler(head, actor, streams), in_keys=[OBS], out_keys=[ACTION, LOG_PROB, PREIMAGE])
