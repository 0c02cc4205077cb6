"""Test-mode rollouts of a policy on one scenario, reduced to the study's metrics on the fly.

Only per-simulation sums are kept (no trajectory storage), so 32 simulations
x 1200 steps x 15 agents run in constant memory.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass

import pandas as pd
import torch
from tensordict import TensorDict
from tensordict.nn import NormalParamExtractor, TensorDictModuleBase
from torchrl.envs.utils import ExplorationType, set_exploration_type
from torchrl.modules import MultiAgentMLP, ProbabilisticActor, TanhNormal

from sigmarl.config import Config, EvalConfig
from sigmarl.env.factory import make_scenario, step_scenario
from sigmarl.env.paper_rules import for_evaluation
from sigmarl.errors import SigmarlError
from sigmarl.evaluation.benchmark import BenchmarkSums, lap_goals
from sigmarl.maps import scenario_map_config
from sigmarl.metrics import AS, CD, CR_AA, CR_AL, CR_TOTAL, MEASURED
from sigmarl.progress import Progress
from sigmarl.scenarios import scenario as scenario_of
from sigmarl.training.networks import PolicyHead

OBS = ("agents", "observation")
ACTION = ("agents", "action")

Policy = Callable[[torch.Tensor], torch.Tensor]


def as_tensor_policy(policy) -> Policy:
    """A function obs [E, A, D] -> action [E, A, 2] acting as `policy` does in evaluation
    (deterministically): `make_actor`'s actor becomes plain tensor maths, any other TensorDict
    module is called on a TensorDict, and modules or functions on tensors are used as given."""
    if isinstance(policy, ProbabilisticActor) and _is_tanh_normal_actor(policy):
        return PolicyHead(policy).deterministic_action
    if isinstance(policy, TensorDictModuleBase):
        def run(obs: torch.Tensor) -> torch.Tensor:
            td = TensorDict({OBS: obs}, batch_size=obs.shape[:1])
            with set_exploration_type(ExplorationType.DETERMINISTIC):
                return policy(td).get(ACTION)

        return run
    return policy


def _is_tanh_normal_actor(actor: ProbabilisticActor) -> bool:
    """Built by `make_actor`: Sequential(parameter-shared MultiAgentMLP, NormalParamExtractor)
    feeding a TanhNormal, whose deterministic action PolicyHead computes."""
    try:
        head = actor.module[0].module
        dist = actor.module[1].distribution_class
    except (AttributeError, IndexError, TypeError):
        return False
    return (dist is TanhNormal and isinstance(head, torch.nn.Sequential) and len(head) == 2
            and isinstance(head[0], MultiAgentMLP) and head[0].share_params and not head[0].centralized
            and isinstance(head[1], NormalParamExtractor))


@torch.inference_mode()
def evaluate_policy(
    policy,
    cfg: Config,
    scenario: str,
    n_sims: int = EvalConfig.n_sims,
    steps: int = EvalConfig.steps,
    seed: int = EvalConfig.seed,
    n_agents: int | None = None,
    device: str | None = None,
    progress: bool = True,
) -> pd.DataFrame:
    """One row per simulation: CR_AA, CR_AL, CR_total (fractions of steps), CD (cm), AS (m/s),
    and the CPM Lab benchmark's TS (fraction of tries), CAA_100m, CAL_100m, LV_100m
    (`sigmarl.evaluation.benchmark`).

    `cfg` supplies the observation design (it must be the one the policy was trained
    with); the scenario supplies map and agent count. The same `seed` gives every
    model the same initial states. The policy acts under the dynamics and observation of its
    `cfg.rules`; what is measured is always ours (`paper_rules.for_evaluation`).
    """
    sums = None
    bar = Progress(steps, f"{cfg.model} seed {cfg.seed}", f"evaluate {scenario}", enabled=progress)
    for sc in rollout_steps(policy, cfg, scenario, n_sims, steps, seed, n_agents, device):
        bar.update(1)
        sums = sums or _Sums.zeros(n_sims, sc)
        sums.add(sc)
    bar.close()
    return sums.rows(scenario, steps, sc.n_agents)


def rollout_steps(policy, cfg: Config, scenario: str, n_sims: int, steps: int, seed: int,
               n_agents: int | None = None, device: str | None = None) -> Iterator:
    """The evaluation's rollout of `n_sims` simulations: yields the scenario after each of
    `steps` steps (its tensors hold the state that step ended in, before anyone respawned).
    The animation walks the same steps, so its simulation k is the rows' simulation k.

    The scenario is stepped directly, as VMAS would step it (`step_scenario`): a test
    rollout never resets an environment and reads only the scenario's own tensors, so the
    per-step TensorDicts of torchrl and VMAS' per-agent calls would only add time.
    """
    cfg = for_evaluation(cfg)
    n_agents = n_agents or scenario_of(scenario).n_agents
    sc = make_scenario(cfg, num_envs=n_sims, n_agents=n_agents, mode="test", map_cfg=scenario_map_config(scenario),
                       seed=seed, device=device)
    sc.compute_reward = False
    # a driver that reads the scenario's state (the rule-based one) is bound to it
    act = policy.bind(sc) if hasattr(policy, "bind") else as_tensor_policy(policy)
    sc.reset_world_at(None)  # the rollout's own reset, as env.reset() does
    obs = sc.current_observation()
    for _ in range(steps):
        obs = step_scenario(sc, _action(act, obs, (n_sims, n_agents), scenario, cfg))
        yield sc


def _action(act: Policy, obs: torch.Tensor, shape: tuple[int, int], scenario: str, cfg: Config) -> torch.Tensor:
    """The policy's actions [E, A, 2], or one line saying why it cannot drive this scenario."""
    try:
        action = act(obs)
    except RuntimeError as e:  # typically a shape mismatch in the first layer
        raise SigmarlError(
            f"the policy cannot act on {scenario}'s observations (size {obs.shape[-1]}, "
            f"observation preset {cfg.obs.preset!r}): {e}"
        ) from e
    if tuple(action.shape) != (*shape, 2):
        raise SigmarlError(f"policy gave actions of shape {tuple(action.shape)}, expected [{shape[0]}, {shape[1]}, 2]")
    return action


@dataclass
class _Sums:
    """Per-simulation sums over the steps, [E] each: all the metrics need."""

    aa_steps: torch.Tensor  # steps with an agent-agent collision
    al_steps: torch.Tensor  # steps with an agent-lane collision
    distance: torch.Tensor  # center-line deviations, summed over agents and steps
    speed: torch.Tensor
    benchmark: BenchmarkSums
    goals: torch.Tensor  # per route: a lap's distance, inf where the route has an exit

    @classmethod
    def zeros(cls, n_sims: int, sc) -> _Sums:
        device = sc.pos.device
        return cls(*(torch.zeros(n_sims, device=device) for _ in range(4)),
                   BenchmarkSums(n_sims, sc.n_agents, device), lap_goals(sc.road_map, device))

    def add(self, sc) -> None:
        """One step, as its infos report it: the state it ended in, before anyone respawned."""
        self.aa_steps += sc.agent_collision.any(-1)
        self.al_steps += sc.lane_collision.any(-1)
        self.distance += sc.step_d_center.sum(-1)
        self.speed += sc.step_speed.sum(-1)
        self.benchmark.add(sc.agent_collision, sc.lane_collision, sc.step_speed, sc.respawned, self.goals[sc.route])

    def rows(self, scenario: str, steps: int, n_agents: int) -> pd.DataFrame:
        agent_steps = steps * n_agents
        rows = pd.DataFrame({
            "scenario": scenario,
            "simulation": range(len(self.speed)),
            CR_AA: (self.aa_steps / steps).cpu().numpy(),
            CR_AL: (self.al_steps / steps).cpu().numpy(),
            CD: (100 * self.distance / agent_steps).cpu().numpy(),
            AS: (self.speed / agent_steps).cpu().numpy(),
        })
        rows.insert(4, CR_TOTAL, rows[CR_AA] + rows[CR_AL])
        for name, values in self.benchmark.columns().items():
            rows[name] = values.cpu().numpy()
        return rows[["scenario", "simulation", *MEASURED]]
