"""Compose the Hydra config for a command from the user's overrides, and read map configs.

The boundary between Hydra and the rest of sigmarl: what leaves here is typed (`Config`,
`MapConfig`), never an OmegaConf `DictConfig`.
"""

from __future__ import annotations

from collections.abc import Sequence

from hydra import compose, initialize_config_dir
from hydra.core.global_hydra import GlobalHydra
from hydra.errors import HydraException
from omegaconf import DictConfig, OmegaConf
from omegaconf.errors import OmegaConfBaseException

from sigmarl.ablation import SCENARIOS
from sigmarl.config import Config, MapConfig, as_config, register_configs
from sigmarl.errors import SigmarlError
from sigmarl.paths import conf_dir
from sigmarl.suggest import hydra_error_message, unknown_keys_message


def compose_config(overrides: Sequence[str] = (), config_name: str = "config") -> Config:
    """The resolved config; a bad override raises SigmarlError with Hydra's message (which names the key)."""
    register_configs()
    # After a Hydra app (the sweep) has run in this process its global state lingers.
    GlobalHydra.instance().clear()
    try:
        with initialize_config_dir(config_dir=str(conf_dir()), version_base=None):
            cfg = compose(config_name=config_name, overrides=list(overrides))
        OmegaConf.resolve(cfg)
    except (HydraException, OmegaConfBaseException) as e:
        raise SigmarlError(f"bad config override: {hydra_error_message(e)}") from e
    # `+key=value` adds keys the schema does not know (Hydra's own error message even suggests
    # it): a misspelt flag would be silently ignored.
    unknown = _unknown_keys(cfg, OmegaConf.structured(Config))
    if unknown:
        raise SigmarlError(unknown_keys_message(unknown))
    return as_config(cfg)


def hydra_config(overrides: Sequence[str] = (), config_name: str = "config") -> DictConfig:
    """Hydra's own settings (the `hydra` node) for these overrides, unresolved as Hydra prints them."""
    register_configs()
    GlobalHydra.instance().clear()
    try:
        with initialize_config_dir(config_dir=str(conf_dir()), version_base=None):
            return compose(config_name=config_name, overrides=list(overrides), return_hydra_config=True).hydra
    except (HydraException, OmegaConfBaseException) as e:
        raise SigmarlError(f"bad config override: {hydra_error_message(e)}") from e


def _unknown_keys(cfg: DictConfig, schema: DictConfig, prefix: str = "") -> list[str]:
    out = []
    for key in cfg:
        if key not in schema.keys():
            out.append(prefix + str(key))
        elif isinstance(cfg[key], DictConfig) and isinstance(schema[key], DictConfig):
            out += _unknown_keys(cfg[key], schema[key], f"{prefix}{key}.")
    return out


def map_config(name: str) -> MapConfig:
    """conf/map/<name>.yaml on the MapConfig schema, without Hydra's global state, so that
    code running inside a Hydra job (a sweep's evaluation) can read it. The one reader of
    a map config file outside Hydra's composition."""
    path = conf_dir() / "map" / f"{name}.yaml"
    if not path.is_file():
        raise SigmarlError(f"no map config {path}")
    values = OmegaConf.load(path)
    values.pop("defaults", None)
    return OmegaConf.to_object(OmegaConf.merge(OmegaConf.structured(MapConfig), values))


def scenario_map_config(scenario: str) -> MapConfig:
    """The map config of a study scenario (sigmarl.ablation.SCENARIOS: conf/map/<name>.yaml)."""
    if scenario not in SCENARIOS:
        raise SigmarlError(f"unknown scenario {scenario!r}; choose from {', '.join(SCENARIOS)}")
    return map_config(SCENARIOS[scenario][0])
