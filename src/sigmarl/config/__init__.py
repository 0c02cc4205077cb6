"""Structured configs: the schema Hydra validates every override against, and the typed
objects every function receives. Each dataclass is one config group (conf/<group>/*.yaml picks
values for it), declared in its own module of this package (`sigmarl.config.map`,
`sigmarl.config.ppo`, ...) with its keys' help lines and ranges (`sigmarl.config.ranges`);
this module holds the whole `Config` and its conversions. A typo in an override fails with
Hydra's error naming the key.
A config is an OmegaConf `DictConfig` only while it is composed (`sigmarl.compose`) or handed
over by Hydra (a sweep job, `sigmarl.sweep.job.run_job`); there it becomes a `Config`
(`as_config`), and a config read back from a file (a checkpoint's, a run folder's config.yaml)
becomes one through `config_from_dict`. Its plain-dict form (`as_dict`, as `OmegaConf.to_container`)
is what config.yaml, checkpoints, MLflow params and the evaluation key hold.

Every key has one line of help (the string literal after its field; a group's: its class
docstring's first line), read by `sigmarl.config.help` for `--info KEY`; a key without one fails.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, get_type_hints

from hydra.core.config_store import ConfigStore
from omegaconf import MISSING, DictConfig, OmegaConf
from omegaconf.errors import OmegaConfBaseException

from sigmarl.ablation import model_label
from sigmarl.config.driver import DriverConfig
from sigmarl.config.env import EnvConfig
from sigmarl.config.eval import EvalConfig
from sigmarl.config.map import MapConfig
from sigmarl.config.network import NetworkConfig
from sigmarl.config.obs import ObsConfig
from sigmarl.config.ppo import PPOConfig
from sigmarl.config.ranges import SEED_MAX, ranged
from sigmarl.config.reward import RewardConfig
from sigmarl.config.rules import RulesConfig
from sigmarl.config.study import StudyConfig, SweepConfig
from sigmarl.config.tracking import TrackingConfig
from sigmarl.config.vehicle import VehicleConfig
from sigmarl.errors import SigmarlError

__all__ = ["SEED_MAX", "MAX_THREADS", "Config", "DriverConfig", "EnvConfig", "EvalConfig", "MapConfig",
           "NetworkConfig", "ObsConfig", "PPOConfig", "RewardConfig", "RulesConfig", "StudyConfig", "SweepConfig",
           "TrackingConfig", "VehicleConfig", "as_config", "as_dict", "config_from_dict", "flatten", "to_yaml",
           "register_configs"]
# A generous cap on torch's threads, whatever the machine (where a job runs it is also held to
# that machine's cores, `sigmarl.resources.check_threads`): a million spawned threads ran a
# machine out of process ids and took its other processes down with it.
MAX_THREADS = 1024


@dataclass
class Config:
    """The whole config of one command: the groups and the top-level keys."""

    map: MapConfig = field(default_factory=MapConfig)
    obs: ObsConfig = field(default_factory=ObsConfig)
    env: EnvConfig = field(default_factory=EnvConfig)
    network: NetworkConfig = field(default_factory=NetworkConfig)
    ppo: PPOConfig = field(default_factory=PPOConfig)
    tracking: TrackingConfig = field(default_factory=TrackingConfig)
    eval: EvalConfig = field(default_factory=EvalConfig)
    rules: RulesConfig = field(default_factory=RulesConfig)
    driver: DriverConfig = field(default_factory=DriverConfig)
    seed: int = ranged(0, lo=0, hi=SEED_MAX)
    """The training seed (0..2**32-1)."""
    device: str = ranged("cpu", pattern=r"(cpu|cuda)(:[0-9]+)?", form="cpu, cuda or cuda:N (N: a GPU's number)")
    """Torch device: cpu | cuda | cuda:N."""
    threads: int = ranged(1, lo=1, hi=MAX_THREADS, size=True)
    """Torch threads of every command that computes."""
    resume: bool = False
    """`sigmarl train`: continue the run folder's training from its checkpoint."""
    study: StudyConfig = field(default_factory=StudyConfig)
    sweep: SweepConfig = field(default_factory=SweepConfig)
    model: str = MISSING
    """The run's label: a study's variant, or (a lone train) M0..M5 or custom-<hash> from the obs flags."""
    overrides: list[str] = field(default_factory=list)
    """The variant's overrides (a sweep job's); set by sigmarl."""
    fingerprint: str = ""
    """Hash of the training settings (sigmarl.identity); set at composition."""
    runs_root: str = MISSING
    """The study's run folders: <runs_root>/<model>/seed<seed> (default runs/<experiment>)."""
    run_dir: str = MISSING
    """The run folder, where checkpoints live; set by conf/config.yaml."""


def as_config(cfg: Config | DictConfig) -> Config:
    """The typed config of a composed (resolved) `DictConfig`; a `Config` is returned as it is."""
    if isinstance(cfg, Config):
        return cfg
    config = OmegaConf.to_object(cfg)
    if not isinstance(config, Config):  # a DictConfig not composed on the schema
        raise TypeError(f"expected a config on the Config schema, got {type(config).__name__}")
    return config


def config_from_dict(values: Mapping[str, Any], what: str = "config") -> Config:
    """A saved config (a checkpoint's `config`, a run folder's config.yaml) on the schema.

    Keys the schema lacks (settings removed from sigmarl since) are dropped and settings it
    added since take their defaults, so a file from an older sigmarl still loads (one from
    before `model` and `runs_root` existed: the label derived from its flags, the folders
    ""); a value of the wrong type is a SigmarlError naming `what`.
    """
    try:
        # the schema built once (14 of a load's 24 ms); merge copies it, never changes it
        merged = OmegaConf.merge(_schema(), _known(values, Config))
        for key in ("model", "runs_root", "run_dir"):  # mandatory (MISSING) in the schema
            if OmegaConf.is_missing(merged, key):
                merged[key] = model_label(merged.obs) if key == "model" else ""
        return as_config(merged)
    except OmegaConfBaseException as e:
        raise SigmarlError(f"{what} does not fit sigmarl's config schema: {str(e).splitlines()[0]}") from e


_schema = functools.cache(lambda: OmegaConf.structured(Config))


def _known(values: Mapping[str, Any], schema: type) -> dict[str, Any]:
    """`values` without the keys that `schema` (a config dataclass) lacks, group by group."""
    types = get_type_hints(schema)
    return {key: _known(value, types[key]) if dataclasses.is_dataclass(types[key]) and isinstance(value, Mapping)
            else value for key, value in values.items() if key in types}


def as_dict(node: Any) -> dict[str, Any]:
    """The plain-dict form of a config or of one of its groups (nested dicts and lists)."""
    return dataclasses.asdict(node)


def flatten(d: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """{"ppo": {"lr": 2e-4}} -> {"ppo.lr": 2e-4}; lists stay one value."""
    out: dict[str, Any] = {}
    for k, v in d.items():
        if isinstance(v, Mapping):
            out.update(flatten(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


def to_yaml(cfg: Config) -> str:
    """A run folder's config.yaml: the groups and keys in the schema's order."""
    return OmegaConf.to_yaml(as_dict(cfg))


def _register_resolvers() -> None:
    # `${sigmarl_model:${obs}}` in conf/config.yaml. Registered at import, so that every process
    # that resolves a config (a launcher's worker too) knows it.
    if not OmegaConf.has_resolver("sigmarl_model"):
        OmegaConf.register_new_resolver("sigmarl_model", model_label)


_register_resolvers()


def register_configs() -> None:
    cs = ConfigStore.instance()
    cs.store(name="base_config", node=Config)
    for group, node in [("map", MapConfig), ("obs", ObsConfig), ("network", NetworkConfig), ("ppo", PPOConfig),
                        ("rules", RulesConfig)]:
        cs.store(group=group, name=f"base_{group}", node=node)
