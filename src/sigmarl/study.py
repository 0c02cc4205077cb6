"""The ablation study's fixed vocabulary: models, their observation presets, the test scenarios.

A run's model label is derived from its observation flags here and nowhere else: training
tags, run folders, evaluation rows and the report all call `model_label`.
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from typing import Any

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

# Scenario name -> (map config name, number of agents), study.md section 3.
SCENARIOS: dict[str, tuple[str, int]] = {
    "CPM": ("cpm", 15),
    "Intersection": ("intersection", 6),
    "On-Ramp": ("on_ramp", 8),
    "Roundabout": ("roundabout", 8),
}

# Columns of one evaluation row: one (model, seed, scenario, simulation); `obs` lists the
# strategies that were on (e.g. "V,DA,DB,DC" for M1).
# Collision rates are fractions of environment steps (0..1); the report shows percent.
METRIC_COLUMNS = ["CR_AA", "CR_AL", "CR_total", "CD", "AS"]  # CD in real centimetres, AS in m/s
ROW_KEYS = ["model", "obs", "seed", "scenario", "simulation"]


def obs_strategies(obs: Mapping[str, Any]) -> str:
    """The strategies switched on, in the paper's order: "E,V,DA,DB,DC" for M0."""
    return ",".join(short for flag, short in OBS_FLAGS.items() if bool(obs[flag]))


def model_label(obs: Mapping[str, Any]) -> str:
    """M0 with all five strategies on, M1..M5 with exactly the paper's one left out, and
    "custom-<6 hex>" (a hash of the strategies that are on) for any other combination."""
    off = [flag for flag in OBS_FLAGS if not bool(obs[flag])]
    if not off:
        return "M0"
    if len(off) == 1:
        return PRESET_TO_MODEL[f"no_{off[0]}"]
    return "custom-" + hashlib.sha1(obs_strategies(obs).encode()).hexdigest()[:6]
