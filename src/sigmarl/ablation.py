"""The paper's vocabulary: its five observation strategies (the one list every module reads),
its six models' presets, its four scenarios (Table I's), and the labels of a lone run derived
from its flags (`model_label`). It imports no config module (sigmarl.config imports it, for the
label resolver and the default scenarios): the flags are read from an ObsConfig, or the
mapping Hydra hands the resolver, by name.

A study's own labels are its variants (`conf/study/*.yaml`); M0..M5 name the paper's models
and label a `sigmarl train` outside a study.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

# The paper's five observation strategies: config flag -> the paper's short name.
OBS_FLAGS: dict[str, str] = {
    "ego_view": "E",
    "vertices": "V",
    "distance_to_agents": "DA",
    "distance_to_boundaries": "DB",
    "distance_to_center_line": "DC",
}

# The paper's six models: M0 with all five strategies, M<k> leaving out the k-th (the order
# above); model -> observation preset (conf/obs/<preset>.yaml).
MODELS: dict[str, str] = {"M0": "full", **{f"M{k}": f"no_{flag}" for k, flag in enumerate(OBS_FLAGS, 1)}}
PRESET_TO_MODEL = {preset: model for model, preset in MODELS.items()}

# Table I's four scenarios, in the paper's order: the default evaluation, and the one order tables use.
PAPER_SCENARIOS = ("CPM", "Intersection", "On-Ramp", "Roundabout")

# a training iteration's timed phases (metrics.csv columns and MLflow metrics); their sum is its compute time
TIMINGS = ("time_collect_s", "time_advantage_s", "time_optimise_s")

def _on(obs: object | Mapping[str, Any], flag: str) -> bool:
    return bool(obs[flag] if isinstance(obs, Mapping) else getattr(obs, flag))


def obs_strategies(obs: object | Mapping[str, Any]) -> str:
    """The strategies switched on, in the paper's order: "E,V,DA,DB,DC" for M0."""
    return ",".join(short for flag, short in OBS_FLAGS.items() if _on(obs, flag))


def model_label(obs: object | Mapping[str, Any]) -> str:
    """M0 with all five strategies on, M1..M5 with exactly the paper's one left out, and
    "custom-<6 hex>" (a hash of the strategies that are on) for any other combination.

    `obs` is an ObsConfig (any object with the five flags), or the flags as a mapping (the `obs` node that the config's
    `${sigmarl_model:${obs}}` resolver receives while Hydra composes)."""
    off = [flag for flag in OBS_FLAGS if not _on(obs, flag)]
    if not off:
        return "M0"
    if len(off) == 1:
        return PRESET_TO_MODEL[f"no_{off[0]}"]
    import hashlib  # here: OpenSSL's load would cost `sigmarl --help` (which reads PAPER_SCENARIOS) 7 ms

    return "custom-" + hashlib.sha1(obs_strategies(obs).encode()).hexdigest()[:6]
