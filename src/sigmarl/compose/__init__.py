"""Compose the Hydra config for a command from the user's overrides.

The boundary between Hydra and the rest of sigmarl: what leaves here is typed (`Config`), never
an OmegaConf `DictConfig`. A map's config is read by `sigmarl.maps.map_config`.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path

import yaml
from hydra import compose, initialize_config_dir
from hydra.core.global_hydra import GlobalHydra
from hydra.errors import HydraException
from omegaconf import DictConfig, OmegaConf
from omegaconf.errors import OmegaConfBaseException

from sigmarl.compose.validate import check
from sigmarl.config import Config, as_config, register_configs
from sigmarl.config.study import seed_list
from sigmarl.config.suggest import hydra_error_message, unknown_keys_message
from sigmarl.errors import SigmarlError
from sigmarl.identity import fingerprint
from sigmarl.paths import conf_dir, user_conf_dirs
from sigmarl.readers import check_config_dir


def search_path_override() -> list[str]:
    """The users' config folders for Hydra (`--config-dir`), searched before the package's."""
    dirs = user_conf_dirs()
    if not dirs:
        return []
    return ["hydra.searchpath=[" + ",".join(f"'file://{d}'" for d in dirs) + "]"]


def compose_config(overrides: Sequence[str] = (), config_name: str = "config") -> Config:
    """The resolved config, checked (`sigmarl.compose.validate.check`) and fingerprinted; a bad override
    or value raises SigmarlError with a message that names the key."""
    return _finish(_compose(overrides, config_name), OmegaConf.structured(Config))


def compose_seeds(overrides: Sequence[str], seeds: Sequence[int]) -> list[Config]:
    """`compose_config([*overrides, f"seed={s}"])` for each seed, at the cost of one Hydra
    composition: the seed is set on the composed tree before its interpolations
    (`run_dir: ...seed${seed}`) are resolved, as Hydra's own `seed=` override sets it."""
    tree, schema = _compose(overrides), OmegaConf.structured(Config)
    configs = []
    for seed in seeds:
        one = copy.deepcopy(tree)  # resolving changes the tree in place
        one.seed = seed
        configs.append(_finish(one, schema))
    return configs


def _compose(overrides: Sequence[str], config_name: str = "config") -> DictConfig:
    """Hydra's composition of the overrides, its interpolations not yet resolved."""
    register_configs()
    _check_user_dirs(tuple(user_conf_dirs()))
    # After a Hydra app (the sweep) has run in this process its global state lingers.
    GlobalHydra.instance().clear()
    with _bad_override():
        with initialize_config_dir(config_dir=str(conf_dir()), version_base=None):
            return compose(config_name=config_name, overrides=[*search_path_override(), *overrides])


def _finish(cfg: DictConfig, schema: DictConfig) -> Config:
    """A composed tree resolved, held against the schema, checked and fingerprinted."""
    with _bad_override():
        OmegaConf.resolve(cfg)
    # `+key=value` adds keys the schema does not know (Hydra's own error message even suggests
    # it): a misspelt flag would be silently ignored.
    unknown = _unknown_keys(cfg, schema)
    if unknown:
        raise SigmarlError(unknown_keys_message(unknown))
    config = check(as_config(cfg))
    return replace(config, fingerprint=fingerprint(config))


@functools.cache
def _check_user_dirs(folders: tuple[Path, ...]) -> None:
    """Every file of the users' config folders read by sigmarl's checked reader, once a process,
    before Hydra's own loader sees one: a folder named by $SIGMARL_CONFIG_PATH, not by
    --config-dir (which checks it), may hold a duplicate key or an alias bomb too."""
    for folder in folders:
        if folder.is_dir():
            check_config_dir(folder)


@contextmanager
def _bad_override() -> Iterator[None]:
    try:
        yield
    except (HydraException, OmegaConfBaseException) as e:
        raise SigmarlError(f"bad config override: {hydra_error_message(e)}") from e
    except yaml.YAMLError as e:  # a broken file in a folder of $SIGMARL_CONFIG_PATH
        for folder in user_conf_dirs():
            check_config_dir(folder)  # names the file and line
        raise SigmarlError(f"a config file is not valid YAML: {str(e).splitlines()[0]}") from e
    except ValueError as e:  # e.g. an integer too long for Python to parse (over 4300 digits)
        raise SigmarlError(f"bad config override: {str(e).splitlines()[0]}") from e


def hydra_config(overrides: Sequence[str] = (), config_name: str = "config") -> DictConfig:
    """Hydra's own settings (the `hydra` node) for these overrides, unresolved as Hydra prints them."""
    register_configs()
    _check_user_dirs(tuple(user_conf_dirs()))
    GlobalHydra.instance().clear()
    try:
        with initialize_config_dir(config_dir=str(conf_dir()), version_base=None):
            return compose(config_name=config_name, overrides=[*search_path_override(), *overrides],
                           return_hydra_config=True).hydra
    except (HydraException, OmegaConfBaseException) as e:
        raise SigmarlError(f"bad config override: {hydra_error_message(e)}") from e


def _unknown_keys(cfg: DictConfig, schema: DictConfig, prefix: str = "") -> list[str]:
    out = []
    for key in cfg:
        if key not in schema.keys():
            out.append(prefix + str(key))
        elif isinstance(cfg[key], DictConfig) and isinstance(schema[key], DictConfig) \
                and dataclasses.is_dataclass(OmegaConf.get_type(schema[key])):  # not a free dict
            out += _unknown_keys(cfg[key], schema[key], f"{prefix}{key}.")
    return out


def compose_block(overrides: Sequence[str] = ()) -> list[Config]:
    """`sigmarl train`'s configs: one, or with `seeds=[a,b,...]` (or `seeds=range(a,b)`) one per
    seed of a seed block, each composed as `seed=<k>` would compose it alone (its own run folder,
    config.yaml and record)."""
    seeds, rest = None, []
    for override in overrides:
        if override.split("=", 1)[0].strip() == "seeds":
            seeds = block_seeds(override)
        else:
            rest.append(override)
    if seeds is None:
        return [compose_config(rest)]
    if any(o.split("=", 1)[0].strip().lstrip("+~") == "seed" for o in rest):
        raise SigmarlError("give either seeds=[...] (a seed block) or seed=..., not both")
    cfgs = compose_seeds(rest, seeds)
    if len({c.run_dir for c in cfgs}) < len(cfgs):
        raise SigmarlError(f"the seeds of a block need a run folder each, but run_dir={cfgs[0].run_dir} names one "
                           "for all: set runs_root=... instead (seed k trains in <runs_root>/<label>/seed<k>)")
    return cfgs


def block_seeds(override: str) -> list[int]:
    """The seeds of `seeds=[0,1,2]` or `seeds=range(0,3)` (`sigmarl.config.study.seed_list`)."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    try:
        parsed = OverridesParser.create().parse_override(override)
        values = list(parsed.sweep_iterator()) if parsed.is_sweep_override() else parsed.value()
    except HydraException as e:
        raise SigmarlError(f"bad seeds=...: {hydra_error_message(e)}") from e
    return seed_list(values if isinstance(values, list) else [values])
