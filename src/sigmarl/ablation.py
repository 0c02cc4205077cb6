"""The ablation study's fixed vocabulary: models, their observation presets, the test scenarios.

A run's model label is derived from its observation flags here and nowhere else: training
tags, run folders, evaluation rows and the report all call `model_label`.
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

from sigmarl.errors import SigmarlError

if TYPE_CHECKING:  # sigmarl.config imports this module
    from sigmarl.config import EvalConfig, ObsConfig

# Model name -> observation preset (conf/obs/<preset>.yaml).
MODELS: dict[str, str] = {
    "M0": "full",
    "M1": "no_ego_view",
    "M2": "no_vertices",
    "M3": "no_distance_to_agents",
    "M4": "no_distance_to_boundaries",
    "M5": "no_distance_to_center_line",
}
PRESET_TO_MODEL = {preset: model for model, preset in MODELS.items()}

# The paper's five observation strategies: config flag -> the paper's short name.
OBS_FLAGS: dict[str, str] = {
    "ego_view": "E",
    "vertices": "V",
    "distance_to_agents": "DA",
    "distance_to_boundaries": "DB",
    "distance_to_center_line": "DC",
}

# Scenario name -> (map config name, number of agents), as the paper evaluated them. The first
# four are the paper's Table I: the CPM map and the paper's own hand-drawn maps.
# The "Proc-" ones are this project's procedural builders, for generalisation beyond the
# paper (`study=extended`); they have no numbers in the paper.
SCENARIOS: dict[str, tuple[str, int]] = {
    "CPM": ("cpm", 15),
    "Intersection": ("paper_intersection", 6),
    "On-Ramp": ("paper_on_ramp", 8),
    "Roundabout": ("paper_roundabout", 8),
    "Proc-Intersection": ("intersection", 6),
    "Proc-On-Ramp": ("on_ramp", 8),
    "Proc-Roundabout": ("roundabout", 8),
}
PAPER_SCENARIOS = ("CPM", "Intersection", "On-Ramp", "Roundabout")  # Table I, the default

# A run folder's evaluation: one row per (scenario, simulation), and beside it what measured
# them (protocol key, checkpoint hash, environment rules revision).
ROWS_FILE = "evaluation_rows.csv"
ROWS_META = "evaluation.json"
# a training iteration's timed phases (metrics.csv columns and MLflow metrics); their sum is its compute time
TIMINGS = ("time_collect_s", "time_advantage_s", "time_optimise_s")

# Columns of one evaluation row: one (model, seed, scenario, simulation); `obs` lists the
# strategies that were on (e.g. "V,DA,DB,DC" for M1).
# Collision rates are fractions of environment steps (0..1); the report shows percent.
METRIC_COLUMNS = ["CR_AA", "CR_AL", "CR_total", "CD", "AS"]  # CD in real centimetres, AS in m/s
ROW_KEYS = ["model", "obs", "seed", "scenario", "simulation"]


def _on(obs: ObsConfig | Mapping[str, Any], flag: str) -> bool:
    return bool(obs[flag] if isinstance(obs, Mapping) else getattr(obs, flag))


def obs_strategies(obs: ObsConfig | Mapping[str, Any]) -> str:
    """The strategies switched on, in the paper's order: "E,V,DA,DB,DC" for M0."""
    return ",".join(short for flag, short in OBS_FLAGS.items() if _on(obs, flag))


def model_label(obs: ObsConfig | Mapping[str, Any]) -> str:
    """M0 with all five strategies on, M1..M5 with exactly the paper's one left out, and
    "custom-<6 hex>" (a hash of the strategies that are on) for any other combination.

    `obs` is an ObsConfig, or the flags as a mapping (the `obs` node that the config's
    `${sigmarl_model:${obs}}` resolver receives while Hydra composes)."""
    off = [flag for flag in OBS_FLAGS if not _on(obs, flag)]
    if not off:
        return "M0"
    if len(off) == 1:
        return PRESET_TO_MODEL[f"no_{off[0]}"]
    return "custom-" + hashlib.sha1(obs_strategies(obs).encode()).hexdigest()[:6]


def check_eval(eval_cfg: EvalConfig, scenarios: Sequence[str] | None = None) -> list[str]:
    """The scenarios to evaluate on, after checking the evaluation settings: one clear
    SigmarlError for a bad value, so a sweep can refuse before it trains anything."""
    for key in ("n_sims", "steps"):
        if int(getattr(eval_cfg, key)) <= 0:
            raise SigmarlError(f"eval.{key} must be positive, got {getattr(eval_cfg, key)}")
    if str(eval_cfg.checkpoint) not in ("best", "final"):
        raise SigmarlError(f"eval.checkpoint must be 'best' or 'final', got {eval_cfg.checkpoint!r}")
    names = [str(s) for s in (scenarios if scenarios is not None else eval_cfg.scenarios)]
    if not names:
        raise SigmarlError(f"eval.scenarios is empty; choose from {', '.join(SCENARIOS)}")
    unknown = [s for s in names if s not in SCENARIOS]
    if unknown:
        raise SigmarlError(f"unknown scenario(s) {', '.join(map(repr, unknown))}; choose from {', '.join(SCENARIOS)}")
    if len(set(names)) != len(names):
        raise SigmarlError(f"eval.scenarios names a scenario twice: {', '.join(names)}")
    return names
