"""A run's identity: its label (the study's variant), its seed, and a fingerprint of the
training settings it was trained with.

Two runs with the same fingerprint and seed train the same policy. The fingerprint covers
every setting that shapes training (map, observation, environment, network, PPO, rules) and
nothing that does not (the seed, which names the run folder on its own; where and how it is
tracked, evaluated, checkpointed or stopped). It is always recomputed from a config read on the
current schema, so a config.yaml written before a setting existed (which then takes its
default) still matches.
"""

from __future__ import annotations

import hashlib
import json
import re
from typing import TYPE_CHECKING, Any

from sigmarl.ablation import later_flags
from sigmarl.config import as_dict, flatten
from sigmarl.config.driver import ADDED_KEYS as DRIVER_KEYS
from sigmarl.config.map import later_map_keys
from sigmarl.config.reward import ADDED_KEYS as REWARD_KEYS
from sigmarl.config.rules import ADDED_KEYS as RULES_KEYS
from sigmarl.config.vehicle import ADDED_KEYS as VEHICLE_KEYS
from sigmarl.errors import SigmarlError

if TYPE_CHECKING:
    from sigmarl.config import Config

TRAINING_GROUPS = ("map", "obs", "env", "network", "ppo", "rules", "driver")
# names only, or what neither changes the policy nor the numbers it is trained on
NOT_TRAINING = frozenset({"obs.preset", "map.name", "ppo.checkpoint_every", "ppo.stop_after"})
# Settings added after fingerprints were first recorded, each with the value every earlier run
# had. At that value a setting is left out, so that a new key does not change every recorded
# fingerprint (and split a published study in two); at any other value it counts. A new
# training setting goes here with its default; an observation strategy declared after the
# paper's five is here by its declaration (off).
ADDED_LATER: dict[str, Any] = {"network.centralised_critic": True, **REWARD_KEYS, **VEHICLE_KEYS, **RULES_KEYS,
                               **DRIVER_KEYS}


def added_later() -> dict[str, Any]:
    """ADDED_LATER, the later observation strategies and the keys of later kinds of map, as
    declared now."""
    return {**ADDED_LATER, **{f"obs.{flag}": off for flag, off in later_flags().items()}, **later_map_keys()}

# a label names a folder and a table column: letters, digits, '.', '_', '-'
_LABEL = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,63}")


def training_settings(cfg: Config) -> dict[str, Any]:
    """The flat training settings the fingerprint covers."""
    values = as_dict(cfg)
    flat = flatten({g: values[g] for g in TRAINING_GROUPS if g in values})
    later = added_later()
    return {k: v for k, v in flat.items() if k not in NOT_TRAINING and not (k in later and v == later[k])}


def fingerprint(cfg: Config) -> str:
    blob = json.dumps(training_settings(cfg), sort_keys=True, default=str)
    return hashlib.sha1(blob.encode()).hexdigest()[:12]


def changed_keys(a: Config, b: Config) -> list[str]:
    """The training settings in which two configs differ, sorted."""
    x, y = training_settings(a), training_settings(b)
    return [k for k in sorted(set(x) | set(y)) if x.get(k) != y.get(k)]


def differences(a: Config, b: Config, limit: int = 4) -> str:
    """The training settings in which two configs differ, as 'key: a -> b, ...'."""
    x, y = training_settings(a), training_settings(b)
    keys = changed_keys(a, b)
    text = ", ".join(f"{k}: {x.get(k, '(none)')} -> {y.get(k, '(none)')}" for k in keys[:limit])
    return text + (f" and {len(keys) - limit} more" if len(keys) > limit else "")


LABEL_RULE = "up to 64 letters, digits, '.', '_' or '-', starting with a letter or digit"


def is_label(name: object) -> bool:
    """Whether `name` may name a folder (of runs or of a run) and a table column."""
    return isinstance(name, str) and _LABEL.fullmatch(name) is not None


def check_label(label: str) -> str:
    if not is_label(label):
        raise SigmarlError(f"bad run label {label!r}: use {LABEL_RULE} (it names a folder and a table column)")
    return label
