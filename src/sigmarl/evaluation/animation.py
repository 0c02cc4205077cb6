"""Animated evaluation rollouts: a checkpoint driving each scenario under the evaluation
protocol (test mode, deterministic actions, the evaluation seed), one GIF per scenario."""

from __future__ import annotations

from pathlib import Path

from torchrl.envs.utils import ExplorationType, set_exploration_type

from sigmarl.env import make_env
from sigmarl.env.render import render_rollout
from sigmarl.maps import scenario_map_config
from sigmarl.scenarios import scenario as scenario_of
from sigmarl.training import checkpoint as ckpt
from sigmarl.training.loop import load_policy


def animate_checkpoint(path: Path, scenarios: list[str], steps: int, seed: int, out_dir: Path,
                       prefix: str = "M0", device: str = "cpu") -> dict[str, Path]:
    """{"animation_<scenario>": <out_dir>/animations/<prefix>_<scenario>.gif} for each scenario.

    Policy and environment run on `device`, the command's (as `sigmarl evaluate` does), never
    on the device the checkpoint was trained on: a GPU-trained model animates on a CPU machine."""
    out = {}
    for scenario in scenarios:
        n_agents = scenario_of(scenario).n_agents
        actor, state = load_policy(path, n_agents=n_agents, device=device)
        train_cfg = ckpt.config_of(state, path)
        env = make_env(train_cfg, num_envs=1, n_agents=n_agents, mode="test", max_steps=steps,
                       map_cfg=scenario_map_config(scenario), seed=seed, device=device)
        with set_exploration_type(ExplorationType.DETERMINISTIC):
            gif = render_rollout(env, actor, steps=steps,
                                 path=out_dir / "animations" / f"{prefix}_{scenario}.gif",
                                 title=f"{scenario} · {prefix} seed {train_cfg.seed}")
        out[f"animation_{scenario}"] = gif
    return out
