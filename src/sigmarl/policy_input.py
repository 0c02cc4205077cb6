"""The size of the policy's input, from the config alone (no environment is built or stepped).

The observation (`sigmarl.env.observation.build_observation`) is a fixed layout: the agent's
own state, its reference points, its center-line and boundary distances (or boundary
points), then one block per observed neighbour. Only the neighbour count depends on the
scenario, through its agent count: an agent observes `obs.n_nearest` others where that many
exist. A policy trained on one size cannot act on another, so a study whose variant would
meet another size in an evaluation scenario is refused before anything trains.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from sigmarl.errors import SigmarlError

if TYPE_CHECKING:
    from sigmarl.config import Config, ObsConfig

BOUNDARY_POINTS = 5  # observed points of each corridor boundary (env.ego.SIDE_WINDOW)
CORNERS = 4


def neighbours(obs: ObsConfig, n_agents: int) -> int:
    """How many others an agent of an `n_agents` scenario can observe."""
    return min(int(obs.n_nearest), n_agents - 1)


def observation_size(obs: ObsConfig, n_agents: int) -> int:
    """The observation's length for `obs`'s flags among `n_agents` agents."""
    ego = obs.ego_view
    own = (1 if ego else 2 + 1 + 2)  # forward speed; or position, heading and velocity
    own += 2 * int(obs.n_ref_points)
    own += 1 if obs.distance_to_center_line else 0
    own += 2 * (1 if obs.distance_to_boundaries else 2 * BOUNDARY_POINTS)
    # per neighbour: its corners, or its position, heading and size; its velocity; its distance
    other = (2 * CORNERS if obs.vertices else 2 + 1 + 2) + 2 + (1 if obs.distance_to_agents else 0)
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
