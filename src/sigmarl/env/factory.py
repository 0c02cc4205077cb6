"""Build the torchrl environment from a config: the one entry point training and evaluation use."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import TYPE_CHECKING

import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Unbounded
from torchrl.envs import EnvBase
from torchrl.envs.libs.vmas import VmasEnv

from sigmarl.env.scenario import ScenarioSettings, TrafficScenario
from sigmarl.env.spawn import MIN_GAP, capacity
from sigmarl.errors import SigmarlError
from sigmarl.maps import RoadMap, load_map

if TYPE_CHECKING:
    from sigmarl.config import Config, MapConfig, ObsConfig


class TrafficEnv(VmasEnv):
    """torchrl's VmasEnv, specialised to our scenario.

    - Steps and resets still go through VMAS, but the output TensorDict is built from the
      scenario's batched [E, A, ...] tensors instead of stacking per-agent results.
    - It counts steps itself and reports a time-out as `truncated` (VmasEnv merges time-outs
      into `terminated`; a StepCounter transform would cost about 1 ms a step).
    - `set_seed` also reseeds the scenario's generators (VMAS seeds only torch's global one).
    """

    def __init__(self, *args, max_steps: int, **kwargs):
        self._max_steps = max_steps
        super().__init__(*args, **kwargs)
        # Cached: `num_envs` is forwarded to VMAS through torchrl's slow __getattr__ (~0.3 ms).
        self._n_envs = int(self.batch_size[0])
        self._steps = torch.zeros(self._n_envs, dtype=torch.long, device=self.device)
        self._timeout_terminal = self._env.scenario.rules.timeout_terminal  # the paper's time-outs
        # the specs above were built from VMAS' per-agent infos; from now on _output reads the
        # scenario's batched infos, so VMAS need not slice and clone them agent by agent
        self._env.scenario.per_agent_infos = False

    def _make_specs(self, env) -> None:
        super()._make_specs(env)
        spec = self.full_done_spec_unbatched.clone()
        spec["terminated"] = spec["done"].clone()
        spec["truncated"] = spec["done"].clone()
        self.full_done_spec_unbatched = spec
        obs = self.full_observation_spec_unbatched.clone()
        obs["step_count"] = Unbounded(shape=(1,), dtype=torch.int64, device=self.device)
        self.full_observation_spec_unbatched = obs

    def _set_seed(self, seed: int | None) -> None:
        super()._set_seed(seed)
        self._env.scenario.seed(0 if seed is None else seed)

    def seed_block(self, seeds: Sequence[int]) -> None:
        """Reseed a seed block's scenario, one seed per seed (torch's global generator, which
        `set_seed` also seeds, draws nothing in a block)."""
        self._env.scenario.seed(list(seeds))

    def _output(self, with_reward: bool) -> TensorDict:
        sc = self._env.scenario
        obs = sc.current_observation()
        agents_shape = obs.shape[:2]
        # _new_unsafe: the shapes and device are ours by construction; TensorDict's per-value
        # validation would cost about 0.3 ms per output
        agents = {"observation": obs, "info": TensorDict._new_unsafe(sc.infos(), batch_size=agents_shape)}
        if with_reward:
            agents["reward"] = sc.rew.unsqueeze(-1)
        terminated = sc.terminated.unsqueeze(-1)
        if self._timeout_terminal:
            terminated = terminated | (self._steps >= self._max_steps).unsqueeze(-1)
        truncated = (self._steps >= self._max_steps).unsqueeze(-1) & ~terminated
        return TensorDict._new_unsafe(
            {
                "agents": TensorDict._new_unsafe(agents, batch_size=agents_shape),
                "done": terminated | truncated,
                "terminated": terminated.clone(),
                "truncated": truncated,
                "step_count": self._steps.unsqueeze(-1).clone(),
            },
            batch_size=self.batch_size,
            device=self.device,
        )

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        action = tensordict.get(("agents", "action"))
        self._env.step(list(action.unbind(1)))
        self._steps += 1
        return self._output(with_reward=True)

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs) -> TensorDictBase:
        mask = None
        if tensordict is not None and "_reset" in tensordict.keys():
            mask = tensordict.get("_reset").reshape(self._n_envs)
        if mask is None or mask.all():
            self._env.reset(return_observations=False)
            self._steps.zero_()
        else:
            # One batched reset of the marked environments (VmasEnv would loop over them).
            self._env.scenario.reset_envs(mask)
            self._env.steps[mask] = 0
            self._steps[mask] = 0
        return self._output(with_reward=False)


def check_agents(n_agents: int, flags: ObsConfig) -> None:
    """What the composed config's one check (`sigmarl.compose.validate.check`, every key in its
    range) cannot know: this environment's agent count, a scenario's rather than env.n_agents."""
    if n_agents < 1:
        raise SigmarlError(f"an environment needs at least 1 agent, got {n_agents}")
    if flags.n_nearest >= n_agents:  # never capped: a policy's input size would change with it
        raise SigmarlError(f"obs.n_nearest={flags.n_nearest} neighbours cannot be observed among {n_agents} agents")


def check_room(road_map: RoadMap, n_agents: int) -> None:
    """Fail at once, not after building (and stepping) worlds of agents that cannot be placed."""
    if n_agents > (room := capacity(road_map.routes)):
        raise SigmarlError(f"could not place {n_agents} agents on map {road_map.name}: its routes hold at "
                           f"most {room} vehicles {MIN_GAP:.2f} m apart (env.n_agents); use fewer agents")


def make_env(
    cfg: Config,
    *,
    num_envs: int = 32,
    n_agents: int | None = None,
    mode: str = "train",
    max_steps: int | None = None,
    map_cfg: MapConfig | None = None,
    road_map: RoadMap | None = None,
    seed: int | None = None,
    device: str | None = None,
    seeds: Sequence[int] = (),
) -> EnvBase:
    """A VmasEnv over TrafficScenario; keyword arguments override the config's values
    (`map_cfg` its map, `road_map` an already loaded one). `seeds`: a seed block, its
    `num_envs` environments split evenly between them in order (`sigmarl.env.streams`).

    A time-out is reported as `truncated` (bootstrapped by GAE), never as `terminated`
    (unless `rules.timeout_terminal`, the paper's way).
    """
    env_cfg = cfg.env
    n_agents = int(n_agents if n_agents is not None else env_cfg.n_agents)
    max_steps = int(max_steps if max_steps is not None else env_cfg.max_steps)
    seed = int(seed if seed is not None else cfg.seed)
    device = device or cfg.device
    check_agents(n_agents, cfg.obs)
    road_map = road_map or load_map(map_cfg if map_cfg is not None else cfg.map)
    check_room(road_map, n_agents)
    return TrafficEnv(
        scenario=TrafficScenario(),
        num_envs=num_envs,
        device=device,
        continuous_actions=True,
        max_steps=max_steps,
        seed=seed,
        settings=replace(_settings(cfg, road_map, n_agents, mode, seed), seeds=tuple(int(s) for s in seeds)),
    )


def _settings(cfg: Config, road_map: RoadMap, n_agents: int, mode: str, seed: int) -> ScenarioSettings:
    env_cfg = cfg.env
    return ScenarioSettings(
        road_map=road_map,
        flags=cfg.obs,
        n_agents=n_agents,
        mode=mode,
        noise=float(cfg.obs.noise),
        ref_point_stride=int(cfg.obs.ref_point_stride),
        spawn_start_m=float(env_cfg.spawn_start_m),
        spawn_end_fraction=float(env_cfg.spawn_end_fraction),
        spawn_margin_m=float(env_cfg.spawn_margin_m),
        seed=seed,  # VmasEnv keeps its own `seed` argument for itself
        rules=cfg.rules,
        reward=cfg.env.reward,
        vehicle=cfg.env.vehicle,
    )


def make_scenario(
    cfg: Config,
    *,
    num_envs: int,
    n_agents: int,
    mode: str = "test",
    map_cfg: MapConfig | None = None,
    road_map: RoadMap | None = None,
    seed: int | None = None,
    device: str | None = None,
) -> TrafficScenario:
    """The TrafficScenario `make_env` would wrap, without VMAS' environment and torchrl's
    wrapper around it: for loops that step it themselves (`step_scenario`), as the evaluation
    does. Built and reset as VMAS' constructor does, so the same seed gives the same
    spawns and noise as `make_env(...).reset()`."""
    seed = int(seed if seed is not None else cfg.seed)
    check_agents(n_agents, cfg.obs)
    road_map = road_map or load_map(map_cfg if map_cfg is not None else cfg.map)
    check_room(road_map, n_agents)
    scenario = TrafficScenario()
    scenario.env_make_world(num_envs, torch.device(device or cfg.device),
                            settings=_settings(cfg, road_map, n_agents, mode, seed))
    scenario.reset_world_at(None)  # VMAS resets (and observes) once when it builds an environment
    scenario.current_observation()
    return scenario


def step_scenario(scenario: TrafficScenario, action: torch.Tensor) -> torch.Tensor:
    """One step of every environment with actions [E, A, 2], as VMAS' `step` carries it
    out for this scenario (its world holds no physics of ours); returns the new
    observation [E, A, D]."""
    # VMAS rejects NaN and out-of-range actions (it does not clamp them), then scales them by
    # u_multiplier in float32
    agent = scenario.world.agents[0]  # every agent has the same action range
    bound = agent.action.u_range_tensor
    if bool(action.isnan().any()) or bool((action.abs() > bound).any()):
        raise SigmarlError(f"the policy gave actions outside the action box +-{[round(b, 4) for b in bound.tolist()]} "
                           "(or NaN)")
    scenario.action = action.to(torch.float32) * agent.action.u_multiplier_tensor
    scenario.post_step()
    return scenario.current_observation()
