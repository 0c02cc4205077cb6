"""Build the torchrl environment from a config: the one entry point training and evaluation use."""

from __future__ import annotations

from torchrl.envs import EnvBase, StepCounter, TransformedEnv
from torchrl.envs.libs.vmas import VmasEnv

from sigmarl.env.observation import ObsFlags
from sigmarl.env.scenario import TrafficScenario
from sigmarl.errors import SigmarlError
from sigmarl.maps import RoadMap, load_map


class TrafficEnv(VmasEnv):
    """torchrl's VmasEnv whose `set_seed` also reseeds our scenario's generators (VMAS
    seeds only torch's global generator, which the scenario does not use)."""

    def _set_seed(self, seed: int | None) -> None:
        super()._set_seed(seed)
        self._env.scenario.seed(0 if seed is None else seed)


def validate(n_agents: int, mode: str, noise: float, num_envs: int, max_steps: int, flags: ObsFlags) -> None:
    """Reject impossible settings before any stepping."""
    if n_agents < 1:
        raise SigmarlError(f"env.n_agents must be at least 1, got {n_agents}")
    if mode not in ("train", "test"):
        raise SigmarlError(f"env.mode must be 'train' or 'test', got {mode!r}")
    if noise < 0:
        raise SigmarlError(f"obs.noise must be >= 0 (total width of the uniform noise), got {noise}")
    if num_envs < 1 or max_steps < 1:
        raise SigmarlError(f"env.num_envs and env.max_steps must be positive, got {num_envs}, {max_steps}")
    if flags.n_nearest < 0 or flags.n_ref_points < 1 or flags.n_ref_points > 3:
        raise SigmarlError("obs.n_nearest must be >= 0 and obs.n_ref_points in 1..3")


def make_env(
    cfg,
    *,
    num_envs: int | None = None,
    n_agents: int | None = None,
    mode: str | None = None,
    max_steps: int | None = None,
    map_cfg=None,
    road_map: RoadMap | None = None,
    seed: int | None = None,
    device: str | None = None,
) -> EnvBase:
    """A VmasEnv over TrafficScenario; keyword arguments override the config's values.

    The episode limit is torchrl's StepCounter, so a time-out is reported as `truncated`
    (bootstrapped by GAE) and never as `terminated` (VmasEnv would merge the two).
    """
    env_cfg = cfg.env
    num_envs = int(num_envs if num_envs is not None else env_cfg.num_envs)
    n_agents = int(n_agents if n_agents is not None else env_cfg.n_agents)
    mode = mode or env_cfg.mode
    max_steps = int(max_steps if max_steps is not None else env_cfg.max_steps)
    seed = int(seed if seed is not None else cfg.seed)
    device = device or cfg.device
    flags = ObsFlags.from_config(cfg.obs)
    validate(n_agents, mode, float(cfg.obs.noise), num_envs, max_steps, flags)
    road_map = road_map or load_map(map_cfg if map_cfg is not None else cfg.map)
    base = TrafficEnv(
        scenario=TrafficScenario(),
        num_envs=num_envs,
        device=device,
        continuous_actions=True,
        seed=seed,
        road_map=road_map,
        flags=flags,
        n_agents=n_agents,
        mode=mode,
        scenario_seed=seed,  # VmasEnv keeps `seed` for itself
        noise=float(cfg.obs.noise),
        ref_point_stride=int(cfg.obs.ref_point_stride),
        spawn_start_m=float(env_cfg.spawn_start_m),
        spawn_end_fraction=float(env_cfg.spawn_end_fraction),
        spawn_margin_m=float(env_cfg.spawn_margin_m),
    )
    return TransformedEnv(base, StepCounter(max_steps=max_steps))
