"""The size of the policy's input, from the config alone (no environment is built or stepped).

The observation (`sigmarl.env.observation.build_observation`) is a fixed layout of declared
blocks (`sigmarl.ablation.layout`), each with its size formula: the agent's own blocks, then
one set per observed neighbour. Only the neighbour count depends on the scenario, through its
agent count: an agent observes `obs.n_nearest` others where that many
exist. A policy trained on one size cannot act on another, so a study whose variant would
meet another size in an evaluation scenario is refused before anything trains.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from sigmarl.ablation import OWN, layout
from sigmarl.errors import SigmarlError

if TYPE_CHECKING:
    from sigmarl.config import Config, ObsConfig


def neighbours(obs: ObsConfig, n_agents: int) -> int:
    """How many others an agent of an `n_agents` scenario can observe."""
    return min(int(obs.n_nearest), n_agents - 1)


def observation_size(obs: ObsConfig, n_agents: int) -> int:
    """The observation's length for `obs`'s flags among `n_agents` agents."""
    blocks = [block for _, block in layout()]
    own = sum(b.size(obs) for b in blocks if b.part == OWN)
    other = sum(b.size(obs) for b in blocks if b.part != OWN)
    return own + neighbours(obs, n_agents) * other


def check_evaluable(obs: ObsConfig, trained: int, scenarios: list[str], what: str) -> None:
    """One line naming `what` (a variant, a checkpoint), the scenario and both sizes if a
    policy whose input has `trained` entries cannot act on a scenario's observations."""
    from sigmarl.scenarios import scenario

    for name in scenarios:
        n = scenario(name).n_agents
        size = observation_size(obs, n)
        if size != trained:
            raise SigmarlError(
                f"{what} cannot be evaluated on {name}: its policy takes {trained} inputs, {name}'s "
                f"observations have {size} ({n} agents, {neighbours(obs, n)} observed neighbours, "
                f"obs.n_nearest={obs.n_nearest}); use fewer obs.n_nearest or leave {name} out")


def check_variant(cfg: Config, scenarios: list[str], label: str) -> None:
    """`check_evaluable` for the policy `cfg` trains."""
    check_evaluable(cfg.obs, observation_size(cfg.obs, cfg.env.n_agents), scenarios, f"variant {label}")
