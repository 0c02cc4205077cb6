"""One check of a composed config, before any run folder, MLflow run or environment exists.

Every command and every sweep job goes through `compose.compose_config`, which calls `check`:
a bad value ends there in one `SigmarlError` naming the key, instead of deep inside the
environment, the training loop or MLflow (where it left a FAILED run behind).

The config's string choices stay plain `str` fields (OmegaConf's structured configs do not
take `Literal`, and an `Enum` would change what config.yaml, checkpoints and MLflow params
hold); their allowed values are the `Literal` types below, checked here.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from functools import cache
from pathlib import Path
from typing import Literal, get_args

from sigmarl.config import Config, EvalConfig, MapConfig
from sigmarl.config.driver import check_driver
from sigmarl.config.map import kind_of
from sigmarl.config.ranges import check_ranges
from sigmarl.config.reward import check_reward
from sigmarl.errors import SigmarlError
from sigmarl.identity import LABEL_RULE, check_label, is_label
from sigmarl.metrics import metric
from sigmarl.paths import conf_dir, config_files
from sigmarl.scenarios import Scenario, scenario, scenario_names
from sigmarl.tracking.tracker import tracker_class

DeviceType = Literal["cpu", "cuda"]
# Reference points are slots of the environment's center-line window, which reaches 6
# resampled points ahead of the vehicle's own (env.ego.LINE_WINDOW).
MAX_REF_REACH = 6


def choice(key: str, value: str, allowed: type) -> str:
    """`value` if it is one of the `Literal` type's values, else one line naming `key`."""
    options = get_args(allowed)
    if value not in options:
        raise SigmarlError(f"{key}={value!r} is not one of {', '.join(options)}")
    return value


def device_type(device: str) -> str:
    """cpu or cuda for `device` (`cuda:1` is cuda). Whether a GPU exists is checked where the
    device is used, not here: a sweep composes its jobs on a machine that may have none."""
    return choice("device", device.split(":", 1)[0], DeviceType)


def check(cfg: Config) -> Config:
    """`cfg` if every value is usable; otherwise one SigmarlError naming the key."""
    check_finite(cfg)
    check_ranges(cfg)  # each key's own range, declared on its field (`sigmarl.config.ranges`)
    kind_of(cfg.map)  # the keys its kind of map needs (the ranges are checked above)
    obs = cfg.obs
    if obs.n_ref_points * obs.ref_point_stride > MAX_REF_REACH:
        raise SigmarlError(
            f"obs.n_ref_points x obs.ref_point_stride must be at most {MAX_REF_REACH} (the reference "
            f"points lie in the {MAX_REF_REACH} center-line points ahead), got "
            f"{obs.n_ref_points} x {obs.ref_point_stride}")
    if obs.n_nearest >= cfg.env.n_agents:
        raise SigmarlError(f"obs.n_nearest={obs.n_nearest} needs more than env.n_agents={cfg.env.n_agents} "
                           f"training agents (an agent observes at most the {cfg.env.n_agents - 1} others)")
    check_reward(cfg.env.reward)
    if not cfg.network.hidden:
        raise SigmarlError("network.hidden is empty: give the layer sizes, e.g. network.hidden=[256,256]")
    check_driver(cfg.driver)
    _check_ppo(cfg)
    check_eval(cfg.eval)
    _check_experiment(cfg.tracking.experiment)

    tracker_class(cfg.tracking.backend)  # a backend that cannot be imported ends here, not after training
    _check_study(cfg)
    return cfg


CUDA_SEEDS_PER_JOB = 64  # estimated from the FLOPs of a minibatch step; no GPU has measured it yet


def seeds_per_job(cfg: Config) -> int:
    """The seeds one sweep job trains as a block: `sweep.seeds_per_job`, or by device (0). On
    this CPU a block seed costs 0.88-1.07 of a lone one (benchmarks/bench_blocks.py, two runs),
    so two lone jobs on two cores do as well; on a GPU many seeds cost little more than one."""
    if cfg.sweep.seeds_per_job:
        return cfg.sweep.seeds_per_job
    return 1 if device_type(cfg.device) == "cpu" else CUDA_SEEDS_PER_JOB


def check_finite(node: object, prefix: str = "") -> None:
    """Every float of a config (in records, lists and dicts) is a finite number: a NaN passes
    every range check (all comparisons with it are false) and fails deep inside training."""
    if dataclasses.is_dataclass(node):
        items = [(f.name, getattr(node, f.name)) for f in dataclasses.fields(node)]
    elif isinstance(node, dict):
        items = list(node.items())
    elif isinstance(node, list | tuple):
        items = list(enumerate(node))
    else:
        return
    for key, value in items:
        name = f"{prefix}[{key}]" if isinstance(key, int) else f"{prefix}.{key}".lstrip(".")
        if isinstance(value, float) and not math.isfinite(value):
            raise SigmarlError(f"{name} must be a finite number, got {value}")
        check_finite(value, name)


def _check_study(cfg: Config) -> None:
    """The study's declaration (conf/study/*.yaml) and the run's label."""
    study = cfg.study
    check_label(cfg.model)
    for label, overrides in study.variants.items():
        check_label(label)
        if not isinstance(overrides, list) or not all(isinstance(o, str) for o in overrides):
            raise SigmarlError(f"study.variants.{label} must be a list of overrides, e.g. [obs=full]")
    # a sweep's sub-study may be compared with a label it swept from a variant (M0_max_speed-0.6)
    if study.variants and not any(study.baseline == v or study.baseline.startswith(v + "_") for v in study.variants):
        raise SigmarlError(f"study.baseline {study.baseline!r} is not one of the study's variants "
                           f"({', '.join(study.variants)}) nor a label a sweep derived from one")
    for variant, base in study.baselines.items():
        for key, label in (("", variant), (".value", base)):
            if study.variants and label not in study.variants:
                raise SigmarlError(f"study.baselines{key and '.' + variant}: {label!r} is not one of the study's "
                                   f"variants ({', '.join(study.variants)})")
        if variant == base:
            raise SigmarlError(f"study.baselines.{variant}: a variant cannot be its own baseline")
    for name, pair in study.interactions.items():
        if not isinstance(pair, list) or len(pair) != 2 or not all(isinstance(v, str) for v in pair):
            raise SigmarlError(f"study.interactions.{name} must be two variants, e.g. [M4-paper, M4]")
        groups = [g for v in pair for g in (v, study.baselines.get(v, study.baseline))]
        if study.variants and not set(groups) <= set(study.variants):
            raise SigmarlError(f"study.interactions.{name}: {', '.join(sorted(set(groups) - set(study.variants)))} "
                               "not among the study's variants")
        if len(set(groups)) != 4:
            raise SigmarlError(f"study.interactions.{name}: {pair[0]} and {pair[1]} and their baselines must be "
                               f"four different variants, got {', '.join(groups)}")
    if not study.metrics:
        raise SigmarlError("study.metrics is empty: a study's verdicts, plans and composite score need at least "
                           "one metric, e.g. study.metrics=[CR_total]")
    for name in [*study.metrics, *study.margins]:
        metric(name)  # an unknown metric name ends here


def check_map(m: MapConfig) -> MapConfig:
    """`m` if its values are usable (a map config read on its own, e.g. by `sigmarl maps list`)."""
    check_finite(m, "map")
    check_ranges(m, "map.")
    kind_of(m)  # the keys its kind needs (an OSM map: its file)
    return m


def _check_ppo(cfg: Config) -> None:
    ppo = cfg.ppo
    if ppo.frames_per_iteration % ppo.num_envs:
        raise SigmarlError(f"ppo.frames_per_iteration={ppo.frames_per_iteration} is not a multiple of "
                           f"ppo.num_envs={ppo.num_envs}")
    if ppo.minibatch_size > ppo.frames_per_iteration:
        raise SigmarlError(f"ppo.minibatch_size={ppo.minibatch_size} exceeds ppo.frames_per_iteration="
                           f"{ppo.frames_per_iteration}")


def _check_experiment(name: str) -> None:
    """An experiment names a folder (runs/<experiment>) and a row in MLflow's store: the rule of
    run labels, so that no name is hidden (`.x`), read as an option (`-rf`) or leaves runs/."""
    if not name.strip():
        raise SigmarlError("tracking.experiment is empty")
    if not is_label(name):
        shown = repr(name if len(name) <= 40 else name[:40] + "...")
        raise SigmarlError(f"tracking.experiment={shown} names the folder runs/<experiment>: use {LABEL_RULE}, "
                           "e.g. my-study")


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
        raise SigmarlError(f"eval.scenarios is empty; choose from {', '.join(scenario_names())}")
    for name in names:
        _check_fits(name)  # an unknown name, a malformed file, a missing map or too many agents: one line
    if len(set(names)) != len(names):
        raise SigmarlError(f"eval.scenarios names a scenario twice: {', '.join(names)}")
    return names


def _check_fits(name: str) -> Scenario:
    """Scenario `name`, if it can run: its map has a config, and (for a user's scenario; the
    package's are tested) its agents fit on the map's routes. Otherwise one line naming the
    file, before anything trains."""
    found = scenario(name)
    path, maps = config_files("scenario")[name], config_files("map")
    if found.map not in maps:
        raise SigmarlError(f"{path}: scenario {name} names map {found.map!r}, which has no conf/map/{found.map}.yaml "
                           f"in any config folder; known maps: {', '.join(sorted(maps))}")
    if not path.is_relative_to(conf_dir()):
        room = _room(found.map, maps[found.map])
        if found.n_agents > room:
            raise SigmarlError(f"{path}: scenario {name} has {found.n_agents} agents, but map {found.map}'s routes "
                               f"hold at most {room} vehicles at the spawn spacing; use fewer n_agents")
    return found


@cache
def _room(map_name: str, path: Path) -> int:
    """How many vehicles the map's routes hold (`sigmarl.env.spawn.capacity`); loads the map once."""
    # lazy: a map is loaded only for a user's scenario, and the environment's modules cost seconds
    from sigmarl.env.spawn import capacity
    from sigmarl.maps import load_map, map_config

    return capacity(load_map(map_config(map_name)).routes)
