"""Where and when a trained policy touches the corridor boundary in a test scenario.

Runs the evaluation protocol (test mode, deterministic actions, the evaluation seed) and
logs every agent-lane contact with the agent's age since its (re)spawn, its speed at
spawn and at contact, its offset from the center line, which side it touched and the
road's curvature there. Used to look for the cause of the CPM lane-collision gap (docs/changelog.md,
"The CPM lane-collision gap was ours"): `python scripts/lane_contacts.py results/paper-budget/M0/seed0/best.pt`.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import pandas as pd
import torch
from torchrl.envs.utils import ExplorationType, set_exploration_type

from sigmarl.env import make_env
from sigmarl.env.paper_rules import for_evaluation
from sigmarl.errors import SigmarlError
from sigmarl.maps import scenario_map_config
from sigmarl.scenarios import scenario as scenario_of
from sigmarl.scenarios import scenario_names
from sigmarl.training.checkpoint import config_of
from sigmarl.training.loop import load_policy


def curvature(bank, route: torch.Tensor, index: torch.Tensor, span: int = 3) -> torch.Tensor:
    """|heading change| per metre over +-span center points (0.08 m apart)."""
    last = bank.n_center[route] - 1
    a = (index - span).clamp(min=0)
    b = torch.minimum(index + span, last)
    dh = bank.heading[route, b] - bank.heading[route, a]
    dh = torch.atan2(dh.sin(), dh.cos()).abs()
    return dh / ((b - a).clamp(min=1) * 0.08)


@torch.no_grad()
def contacts(checkpoint: Path, scenario: str, n_sims: int, steps: int, seed: int,
             noise: float | None = None) -> pd.DataFrame:
    n_agents = scenario_of(scenario).n_agents
    actor, state = load_policy(checkpoint, n_agents=n_agents)
    cfg = for_evaluation(config_of(state, checkpoint))  # measured as the evaluation measures
    if noise is not None:
        cfg.obs.noise = noise
    env = make_env(cfg, num_envs=n_sims, n_agents=n_agents, mode="test", max_steps=steps,
                   map_cfg=scenario_map_config(scenario), seed=seed)
    sc = env._env.scenario
    respawn = sc._respawn
    before = {}

    def keep_then_respawn(place):  # respawns run inside the step: keep where the agents were
        before.update(route=sc.route.clone(), index=sc.index.clone(), side_hit=sc.geo.side_hit.clone())
        respawn(place)

    sc._respawn = keep_then_respawn
    td = env.reset()
    age = torch.zeros(n_sims, n_agents, dtype=torch.long)
    spawn_speed = sc.speed.clone()
    events = []
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        for t in range(steps):
            before.clear()
            td = env.step(actor(td))
            info = td.get(("next", "agents", "info"))
            lane = info["lane_collision"].squeeze(-1) > 0
            agent = info["agent_collision"].squeeze(-1) > 0
            route = before.get("route", sc.route)
            index = before.get("index", sc.index)
            side_hit = before.get("side_hit", sc.geo.side_hit)
            age += 1
            curv = curvature(sc.bank, route, index)
            for e, a in lane.nonzero().tolist():
                events.append({
                    "sim": e, "agent": a, "step": t, "age": int(age[e, a]),
                    "spawn_speed": float(spawn_speed[e, a]), "speed": float(info["speed"][e, a, 0]),
                    "d_center_cm": 100 * float(info["distance_to_center_line"][e, a, 0]),
                    "side": "left" if bool(side_hit[e, a, 0]) else "right",
                    "also_agent": bool(agent[e, a]), "route": int(route[e, a]), "index": int(index[e, a]),
                    "x": float(sc.step_pos[e, a, 0]), "y": float(sc.step_pos[e, a, 1]),
                    "heading": float(sc.step_heading[e, a]),
                    "curvature": float(curv[e, a]),
                })
            respawned = info["respawned"].squeeze(-1) > 0
            age = torch.where(respawned, torch.zeros_like(age), age)
            spawn_speed = torch.where(respawned, sc.speed, spawn_speed)
            td = env.step_mdp(td)
    env.close()
    return pd.DataFrame(events)


def summary(ev: pd.DataFrame, n_sims: int, steps: int, n_agents: int) -> str:
    lines = [f"{len(ev)} agent-lane contacts in {n_sims} x {steps} steps x {n_agents} agents "
             f"({len(ev) / (n_sims * steps * n_agents):.5f} per agent-step; "
             f"CR_AL {ev.groupby(['sim', 'step']).ngroups / (n_sims * steps):.4f})"]
    if ev.empty:
        return lines[0]
    for k in (5, 10, 20, 40, 80):
        lines.append(f"  age <= {k:3d} steps: {(ev.age <= k).mean():.2f}")
    lines.append(f"  speed at contact: mean {ev.speed.mean():.3f} m/s; d_center {ev.d_center_cm.mean():.1f} cm")
    lines.append(f"  side: {ev.side.value_counts().to_dict()}; with an agent collision too: {ev.also_agent.mean():.2f}")
    lines.append(f"  curvature at contact (1/m): median {ev.curvature.median():.2f}, "
                 f"share above 2/m {(ev.curvature > 2).mean():.2f}")
    return "\n".join(lines)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("checkpoint", type=Path)
    p.add_argument("--scenario", default="CPM", choices=scenario_names())
    p.add_argument("--sims", type=int, default=32)
    p.add_argument("--steps", type=int, default=1200)
    p.add_argument("--seed", type=int, default=2024)
    p.add_argument("--noise", type=float, default=None, help="override obs.noise")
    p.add_argument("--out", type=Path, default=None, help="CSV of the contacts")
    a = p.parse_args()
    torch.set_num_threads(1)
    try:
        ev = contacts(a.checkpoint, a.scenario, a.sims, a.steps, a.seed, a.noise)
    except SigmarlError as e:  # a missing or broken checkpoint, an unknown scenario
        sys.exit(f"lane_contacts: error: {e}")
    print(summary(ev, a.sims, a.steps, scenario_of(a.scenario).n_agents))
    if a.out:
        ev.to_csv(a.out, index=False)


if __name__ == "__main__":
    main()
