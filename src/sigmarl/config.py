"""Structured configs: the schema Hydra validates every override against, and the typed
objects every function receives. Each dataclass is one config group (conf/<group>/*.yaml picks
values for it), so a typo in an override fails with Hydra's error naming the key.
A config is an OmegaConf `DictConfig` only while it is composed (`sigmarl.compose`) or handed
over by Hydra (a sweep job, `sigmarl.sweep.job.run_job`); there it becomes a `Config`
(`as_config`), and a config read back from a file (a checkpoint's, a run folder's config.yaml)
becomes one through `config_from_dict`. Its plain-dict form (`as_dict`, as `OmegaConf.to_container`)
is what config.yaml, checkpoints, MLflow params and the evaluation key hold.

Every key has one line of help (the string literal after its field; a group's: its class
docstring's first line), read by `sigmarl.config_help` for `--info KEY`; a key without one fails.
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

from sigmarl.ablation import PAPER_SCENARIOS, model_label, strategy_flags
from sigmarl.driver_config import DriverConfig
from sigmarl.errors import SigmarlError
from sigmarl.ranges import ranged
from sigmarl.reward_config import RewardConfig
from sigmarl.rules_config import RulesConfig
from sigmarl.vehicle_config import VehicleConfig

# numpy's legacy generator (np.random.seed) takes seeds in 0..2**32-1, torch any up to 2**64-1
SEED_MAX = 2**32 - 1
# A generous cap on torch's threads, whatever the machine (where a job runs it is also held to
# that machine's cores, `sigmarl.resources.check_threads`): a million spawned threads ran a
# machine out of process ids and took its other processes down with it.
MAX_THREADS = 1024


@dataclass
class MapConfig:
    """A road map: the CPM Lab map, a procedural test map, or a user's OSM file."""

    name: str = "cpm_intersection"
    """The map's name (conf/map/<name>.yaml); labels figures and `sigmarl maps`."""
    kind: str = ranged("cpm", choices=("cpm", "intersection", "on_ramp", "roundabout", "osm"))
    """Which builder makes it: cpm | intersection | on_ramp | roundabout | osm."""
    route_set: str = ranged("intersection", choices=("intersection", "loops"))
    """cpm only: the central intersection's 24 routes (intersection) or the whole map's 7 loops (loops)."""
    lane_width: float = ranged(0.20, lo=0, lo_open=True)
    """Lane width in m of procedural and OSM maps (the CPM map is fixed at 0.15)."""
    # intersection and roundabout builders: arms at angles 2*pi*k/n_arms (k=0 east)
    arm_length: float = ranged(1.25, lo=0, lo_open=True)
    """Intersection and roundabout: length in m of each arm's straight lanes."""
    arm_lengths: list[float] = ranged(factory=list, lo=0, lo_open=True)
    """Per-arm lengths in m: arm k is arm_lengths[k % len] long (empty: arm_length for all)."""
    n_arms: int = ranged(4, lo=3, hi=6)
    """Intersection and roundabout: number of arms, at angles 2 pi k / n_arms (k = 0 east)."""
    junction_offset: float = ranged(0.45, lo=0, lo_open=True)
    """Intersection: distance in m from the junction's center to where the arms start."""
    radius: float = ranged(0.55, lo=0, lo_open=True)
    """Roundabout: the ring's center-line radius in m."""
    entry_radius: float = ranged(0.35, lo=0, lo_open=True)
    """Roundabout: radius in m of the arcs joining the arms to the ring."""
    n_ramps: int = ranged(2, lo=1, hi=64, size=True)
    """On-ramp: number of ramps joining the main road."""
    main_length: float = ranged(4.1, lo=0, lo_open=True)
    """On-ramp: length in m of the main road."""
    ramp_drop: float = ranged(1.63, lo=0, lo_open=True)
    """On-ramp: how far in m below the main road's center line a ramp starts."""
    ramp_angle: float = ranged(45.0, lo=10, hi=80, unit="degrees")
    """On-ramp: the ramps' angle to the main road, in degrees."""
    ramp_radius: float = ranged(0.8, lo=0, lo_open=True)
    """On-ramp: radius in m of the bend onto the main road."""
    path: str = ""
    """kind=osm: the OSM file (SigmaRL center-line ways or Lanelet2 relations)."""
    routes: list[Any] = field(default_factory=list)
    """kind=osm: routes as lists of way/lanelet ids (last id = first: a loop); empty: all from the lanelet graph."""


@dataclass
class ObsConfig(strategy_flags()):  # a flag per declared strategy (`sigmarl.ablation.STRATEGIES`)
    """Observation design: the strategies as flags (the paper's five on, any later one off = M0)."""

    preset: str = "full"
    """The conf/obs preset this started from (full, no_ego_view, ...); only a starting point, the flags decide."""
    n_nearest: int = ranged(2, lo=0, hi=1024, size=True)
    """K: how many nearest other vehicles are observed."""
    n_ref_points: int = ranged(3, lo=1, hi=3)
    """How many short-term reference points on the center line are observed."""
    ref_point_stride: int = ranged(2, lo=1, hi=6)
    """Resampled center-line points between reference points (2 x 0.08 m)."""
    noise: float = ranged(0.02, lo=0)
    """Total width of the zero-mean uniform noise added to every observation entry."""


@dataclass
class EnvConfig:
    """The training environment (evaluation sets its own agent counts, mode and length from
    `eval.*` and the scenarios; the number of training environments is `ppo.num_envs`)."""

    n_agents: int = ranged(4, lo=1, hi=10**5, size=True)
    """Vehicles per training environment."""
    max_steps: int = ranged(128, lo=1, hi=10**6, size=True)
    """Training episode length in steps (evaluation: eval.steps)."""
    spawn_start_m: float = ranged(0.5, lo=0)
    """Training spawns on non-loop routes start this many m after a route's start."""
    spawn_end_fraction: float = ranged(0.5, lo=0, hi=1, lo_open=True)
    """Training spawns on non-loop routes end at this fraction of the route's length."""
    spawn_margin_m: float = ranged(0.25, lo=0)
    """Test spawns keep this many m from either end of a route."""
    reward: RewardConfig = field(default_factory=RewardConfig)
    """The reward's weights and shaping scales (the paper's by default)."""
    vehicle: VehicleConfig = field(default_factory=VehicleConfig)
    """The vehicle's limits (the CPM Lab vehicle's by default)."""


@dataclass
class NetworkConfig:
    """The actor and critic MLPs (the paper's: 256x256 tanh, a centralised critic: MAPPO)."""

    hidden: list[int] = ranged(factory=lambda: [256, 256], lo=1, hi=65536, size=True)
    """hidden layer sizes of the actor and of the critic"""
    activation: str = ranged("tanh", choices=("tanh", "relu", "elu"))
    """the hidden layers' activation: tanh | relu | elu"""
    scale_floor: float = ranged(1e-4, lo=0, lo_open=True)
    """the smallest standard deviation of the policy's Gaussian"""
    centralised_critic: bool = True
    """true (MAPPO, the paper's): the critic sees all agents' observations; false (IPPO): each agent's value from its own observation only"""
    shared_critic_value: bool = True
    """true (the paper's): one critic network for all agents (centralised: one value, copied to each); false: one output head (centralised) or one network (decentralised) per agent"""


@dataclass
class PPOConfig:
    """MAPPO's training budget and update (the paper's settings by default)."""

    iterations: int = ranged(250, lo=1)
    """Training iterations (collection + update)."""
    frames_per_iteration: int = ranged(4096, lo=1, hi=2**30, size=True)
    """Frames collected per iteration: num_envs x rollout steps (128, one training episode)."""
    num_envs: int = ranged(32, lo=1, hi=2**20, size=True)
    """Parallel environments while training."""
    epochs: int = ranged(60, lo=1)
    """PPO epochs over each iteration's frames."""
    minibatch_size: int = ranged(512, lo=1, hi=2**30, size=True)
    """Frames per minibatch of the PPO update."""
    lr: float = ranged(2e-4, lo=0)
    """Learning rate at the first iteration (linear decay to lr_final)."""
    lr_final: float = ranged(1e-5, lo=0)
    """Learning rate at the last iteration."""
    max_grad_norm: float = ranged(1.0, lo=0)
    """Gradients are clipped to this norm."""
    clip_epsilon: float = ranged(0.2, lo=0, hi=1, lo_open=True, hi_open=True)
    """PPO's clipping of the probability ratio."""
    gamma: float = ranged(0.99, lo=0, hi=1)
    """Discount factor."""
    lmbda: float = ranged(0.9, lo=0, hi=1)
    """GAE's lambda."""
    entropy_coef: float = ranged(1e-4, lo=0)
    """Weight of the entropy bonus in the loss."""
    normalize_advantage: bool = False
    """Normalise advantages per minibatch."""
    loss: str = ranged("lean", choices=("lean",))
    """lean: the PPO loss on plain tensors (the one loss; checked against torchrl's ClipPPOLoss in the tests)."""
    precision: str = ranged("fp32", choices=("fp32", "bf16", "auto"))
    """fp32 | bf16: the update's forward passes under bfloat16 autocast | auto: bf16 where native."""
    # bf16 keeps log-probabilities, ratios, advantages and losses in fp32; auto picks bf16 where
    # the CPU has native bf16 (avx512_bf16 / amx_bf16) or the GPU supports it
    checkpoint_every: int = ranged(5, lo=1)
    """Write the resume point checkpoint.pt every this many iterations."""
    stop_after: int = ranged(0, lo=0)
    """>0: stop (as if interrupted, resumable) once this many iterations are done."""


@dataclass
class EvalConfig:
    """Evaluation protocol: every model faces the same scenarios, simulations and seed."""

    scenarios: list[str] = field(default_factory=lambda: list(PAPER_SCENARIOS))
    """Scenario names (conf/scenario/<name>.yaml); conf/config.yaml takes the study's."""
    n_sims: int = ranged(32, lo=1, hi=2**16, size=True)
    """Simulations per scenario."""
    steps: int = ranged(1200, lo=1, hi=10**6, size=True)
    """Steps per simulation."""
    seed: int = ranged(2024, lo=0, hi=SEED_MAX)
    """Seed of every evaluation, so every model faces the same initial states."""
    checkpoint: str = ranged("best", choices=("best", "final"))
    """Which checkpoint is evaluated: best (the paper's choice) | final."""


@dataclass
class TrackingConfig:
    """Where runs are recorded."""

    tracking_uri: str = ""
    """The MLflow store or server (empty: MLflow's default, a local SQLite mlflow.db)."""
    experiment: str = "sigmarl-ablation"
    """The experiment's name; also names runs/<experiment>/ and reports/<experiment>/."""
    enabled: bool = True
    """false: no tracker; the run folders are the only record."""
    backend: str = "mlflow"
    """mlflow, or package.module:Class naming a sigmarl.tracking.Tracker of your own."""


@dataclass
class StudyConfig:
    """An ablation study as data (conf/study/<name>.yaml): which training configs it compares,
    with which seeds, on which scenarios, and how it decides."""

    name: str = "paper"
    """The study's name (conf/study/<name>.yaml)."""
    variants: dict[str, list[str]] = field(default_factory=dict)
    """Label -> Hydra overrides of the training config, in table order; a label names run folders and a column."""
    baseline: str = "M0"
    """The variant every other variant is compared with."""
    baselines: dict[str, str] = field(default_factory=dict)
    """Variant -> its own baseline where it is not `baseline` (a factorial study: {M4-paper: M0-paper})."""
    interactions: dict[str, list[str]] = field(default_factory=dict)
    """Name -> [x, y]: does x's comparison with its baseline differ from y's with its own?"""
    seeds: list[int] = ranged(factory=lambda: [0], lo=0, hi=SEED_MAX)
    """Seeds of every variant (seeds=[0,1,2] on the command line)."""
    scenarios: list[str] = field(default_factory=lambda: list(PAPER_SCENARIOS))
    """The scenarios every variant is evaluated on."""
    metrics: list[str] = field(default_factory=lambda: ["CR_total"])
    """The metrics each comparison decides on."""
    margins: dict[str, float] = ranged(factory=lambda: {"CR_total": 0.1, "CD": 0.1, "AS": 0.01}, lo=0, lo_open=True)
    """Equivalence margins per metric, in the table's units (percentage points, cm, m/s)."""
    max_seeds: int = ranged(10, lo=2, hi=10**4, size=True)
    """seeds=auto adds seeds up to this many per variant."""
    slow_seed: float = ranged(0.0, lo=0, hi=100)
    """A seed whose worst CR_total (%) over the scenarios exceeds this is slow; the report counts them per variant and tests each against its baseline (Fisher's exact). 0: off."""
    checkpoints_from: str = ""
    """A folder of trained runs (<label>/seed<k>/) to evaluate instead of training (e.g. results/paper-budget)."""
    job: str = ""
    """Set by `sigmarl sweep` for its jobs: this job's key in the plan file."""
    plan: str = ""
    """Set by `sigmarl sweep` for its jobs: the plan file."""


@dataclass
class SweepConfig:
    """How `sigmarl sweep` packs its jobs (not a training setting: no fingerprint sees it)."""

    seeds_per_job: int = ranged(0, lo=0, hi=4096, size=True)
    """Seeds of one variant each sweep job trains as one seed block (`sigmarl train seeds=[...]`). 0: by device, 1 on cpu (measured: a block seed costs 0.88-1.07 of a lone one there, benchmarks/bench_blocks.py), 64 on cuda (estimated; not yet measured)."""


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
