"""The actor and critic of a seed block: S copies of one network, seed k's parameters at index
k of stacked tensors, computed with batched matrix products (`torch.baddbmm`).

Each copy is built as a lone run builds its network (same seed, same initialisation: the lone
modules are made first and their parameters stacked), and can be written back into a lone
module (`unstack`), so a block seed's checkpoints are exactly a lone run's. Parameters keep the
lone module's order, so one Adam over the stacked tensors holds, index for index, the state
of each seed's own Adam (Adam is elementwise).
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn
from torchrl.modules import MultiAgentMLP

from sigmarl.training.networks import ACTIVATIONS


class StackedMLP(nn.Module):
    """S parameter-shared MultiAgentMLPs of one shape (decentralised: each agent's own
    observation; centralised: all agents' observations, one value copied to every agent)."""

    def __init__(self, nets: list[MultiAgentMLP]):
        super().__init__()
        first = nets[0]
        if not first.share_params:
            raise ValueError("a seed block needs parameter-shared networks")
        self.centralised, self.n_agents = bool(first.centralized), int(first.n_agents)
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
                raise ValueError(f"a seed block cannot stack a {type(module).__name__}")
        self.params = nn.ParameterList(params)
        self._names = [(name, kind) for name, m in first._empty_net.named_children() if isinstance(m, nn.Linear)
                       for kind in ("weight", "bias")]

    @property
    def n_seeds(self) -> int:
        return int(self.params[0].shape[0])

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """[S, *batch, A, D] -> [S, *batch, A, out]."""
        s, *batch, a, d = x.shape
        x = x.reshape(s, -1, a * d) if self.centralised else x.reshape(s, -1, d)
        params = list(self.params)
        for layer in self.layers:
            if isinstance(layer, tuple):
                w, b = params[layer[0]], params[layer[1]]
                if s == 1:  # one seed: a plain linear layer (cheaper backward than a batch of one)
                    x = F.linear(x, w.view(w.shape[1:]), b.view(b.shape[1:]))
                else:
                    x = torch.baddbmm(b.unsqueeze(1), x, w.transpose(1, 2))
            else:
                x = layer(x)
        if self.centralised:  # one value per state, shared by the agents
            return x.reshape(s, *batch, 1, x.shape[-1]).expand(s, *batch, a, x.shape[-1])
        return x.reshape(s, *batch, a, x.shape[-1])

    @torch.no_grad()
    def unstack(self, k: int, net: MultiAgentMLP) -> None:
        """Write seed k's parameters into the lone network `net`."""
        for p, (name, kind) in zip(self.params, self._names, strict=True):
            net.params[name, kind].copy_(p[k])

    @torch.no_grad()
    def restack(self, k: int, net: MultiAgentMLP) -> None:
        """Set seed k's parameters from the lone network `net` (a resume)."""
        for p, (name, kind) in zip(self.params, self._names, strict=True):
            p[k].copy_(net.params[name, kind])


def per_seed(fn, n_seeds: int):
    """`fn` on [S, ...] tensors as a function of [S * E, ...] tensors (the environment's
    layout: seed k's environments are rows k*E .. (k+1)*E)."""
    def apply(x: torch.Tensor) -> torch.Tensor:
        out = fn(x.reshape(n_seeds, x.shape[0] // n_seeds, *x.shape[1:]))
        return out.reshape(x.shape[0], *out.shape[2:])
    return apply
