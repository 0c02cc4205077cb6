"""Structured configs: the schema Hydra validates every override against, and the typed
objects every function receives.

Each dataclass is one config group (conf/<group>/*.yaml picks values for it),
so a typo in an override fails with Hydra's error naming the key.

A config is an OmegaConf `DictConfig` only while it is composed (`sigmarl.compose`) or
handed over by Hydra (a sweep job, `sigmarl.sweep.run_job`); there it becomes a `Config`
(`as_config`), and a config read back from a file (a checkpoint's, a run folder's
config.yaml) becomes one through `config_from_dict`. Its plain-dict form (`as_dict`: the
same keys, order and values as `OmegaConf.to_container`) is what config.yaml, checkpoints,
MLflow params and the evaluation key hold.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, get_type_hints

from hydra.core.config_store import ConfigStore
from omegaconf import MISSING, DictConfig, OmegaConf
from omegaconf.errors import OmegaConfBaseException

from sigmarl.ablation import model_label
from sigmarl.errors import SigmarlError
from sigmarl.scenarios import PAPER_SCENARIOS


@dataclass
class MapConfig:
    """A road map: the CPM Lab map, a procedural test map, or a user's OSM file."""

    name: str = "cpm_intersection"
    kind: str = "cpm"  # cpm | intersection | on_ramp | roundabout | osm
    route_set: str = "intersection"  # cpm only: intersection | loops
    lane_width: float = 0.20  # procedural and OSM maps (CPM is fixed at 0.15)
    # intersection and roundabout builders: arms at angles 2*pi*k/n_arms (k=0 east);
    # arm k's straight lanes are arm_lengths[k % len] long (empty: arm_length for all)
    arm_length: float = 1.25
    arm_lengths: list[float] = field(default_factory=list)
    n_arms: int = 4
    junction_offset: float = 0.45  # intersection: junction center to where the arms start
    # roundabout builder
    radius: float = 0.55  # ring center-line radius
    entry_radius: float = 0.35  # arcs joining the arms to the ring
    # on-ramp builder
    n_ramps: int = 2
    main_length: float = 4.1
    ramp_drop: float = 1.63  # ramp start below the main road's center line
    ramp_angle: float = 45.0  # degrees
    ramp_radius: float = 0.8  # bend onto the main road
    # OSM file (kind=osm): path, and optional explicit routes as lists of way/lanelet ids
    path: str = ""
    routes: list[Any] = field(default_factory=list)


@dataclass
class ObsConfig:
    """Observation design: the paper's five strategies as flags (all on = M0)."""

    preset: str = "full"
    ego_view: bool = True  # E
    vertices: bool = True  # V
    distance_to_agents: bool = True  # DA
    distance_to_boundaries: bool = True  # DB
    distance_to_center_line: bool = True  # DC
    n_nearest: int = 2  # K observed neighbours
    n_ref_points: int = 3  # short-term reference points
    ref_point_stride: int = 2  # resampled points between reference points (2 x 0.08 m)
    noise: float = 0.02  # total width of the zero-mean uniform noise on every entry


@dataclass
class EnvConfig:
    """The training environment (evaluation sets its own agent counts, mode and length from
    `eval.*` and the scenarios; the number of training environments is `ppo.num_envs`)."""

    n_agents: int = 4
    max_steps: int = 128  # training episode length (evaluation: eval.steps)
    # Where vehicles start: training on non-loop routes from spawn_start_m up
    # to spawn_end_fraction of the route; testing anywhere but spawn_margin_m at either end.
    spawn_start_m: float = 0.5
    spawn_end_fraction: float = 0.5
    spawn_margin_m: float = 0.25


@dataclass
class NetworkConfig:
    """The actor and critic MLPs (the paper's: 256x256 tanh, a centralised critic: MAPPO)."""

    hidden: list[int] = field(default_factory=lambda: [256, 256])
    """hidden layer sizes of the actor and of the critic"""
    activation: str = "tanh"
    """the hidden layers' activation: tanh | relu | elu"""
    scale_floor: float = 1e-4
    """the smallest standard deviation of the policy's Gaussian"""
    centralised_critic: bool = True
    """true (MAPPO, the paper's): the critic sees all agents' observations; false (IPPO): each agent's value from its own observation only"""
    shared_critic_value: bool = True
    """true (the paper's): one critic network for all agents (centralised: one value, copied to each); false: one output head (centralised) or one network (decentralised) per agent"""


@dataclass
class PPOConfig:
    iterations: int = 250
    frames_per_iteration: int = 4096  # num_envs x rollout steps (128, one training episode)
    num_envs: int = 32  # parallel environments while training
    epochs: int = 60
    minibatch_size: int = 512
    lr: float = 2e-4
    lr_final: float = 1e-5
    max_grad_norm: float = 1.0
    clip_epsilon: float = 0.2
    gamma: float = 0.99
    lmbda: float = 0.9
    entropy_coef: float = 1e-4
    normalize_advantage: bool = False
    loss: str = "lean"  # lean: the PPO loss on plain tensors | torchrl: torchrl's ClipPPOLoss (same maths)
    # fp32 | bf16: the networks' forward passes in the PPO update under bfloat16 autocast
    # (log-probabilities, ratios, advantages, losses stay fp32; lean loss only) | auto: bf16
    # where the CPU has native bf16 (avx512_bf16 / amx_bf16) or the GPU supports it
    precision: str = "fp32"
    checkpoint_every: int = 5
    stop_after: int = 0  # >0: stop (as if interrupted) once this many iterations are done


@dataclass
class EvalConfig:
    """Evaluation protocol: every model faces the same scenarios, simulations and seed."""

    # scenario names (conf/scenario/<name>.yaml); conf/config.yaml takes the study's
    scenarios: list[str] = field(default_factory=lambda: list(PAPER_SCENARIOS))
    n_sims: int = 32
    steps: int = 1200
    seed: int = 2024
    checkpoint: str = "best"  # best (the paper's choice) | final


@dataclass
class TrackingConfig:
    tracking_uri: str = ""  # empty: MLflow's default (a local SQLite mlflow.db)
    experiment: str = "sigmarl-ablation"
    enabled: bool = True  # false: the run folders are the only record
    backend: str = "mlflow"  # or package.module:Class, a sigmarl.tracking.Tracker of your own


@dataclass
class StudyConfig:
    """An ablation study as data (conf/study/<name>.yaml): which training configs it compares,
    with which seeds, on which scenarios, and how it decides."""

    name: str = "paper"
    # label -> Hydra overrides of the training config, in table order; a label names the
    # run folders (<runs_root>/<label>/seed<k>) and the table's column
    variants: dict[str, list[str]] = field(default_factory=dict)
    baseline: str = "M0"  # what every other variant is compared with
    # variant -> its own baseline, where it is not `baseline` (e.g. a factorial study compares
    # within each level of the other factor: {M4-paper: M0-paper, M4: M0})
    baselines: dict[str, str] = field(default_factory=dict)
    # name -> [x, y]: does x's comparison with its baseline differ from y's with its own?
    # (e.g. {M4: [M4-paper, M4]}: do the paper's rules change what M4 leaves out?)
    interactions: dict[str, list[str]] = field(default_factory=dict)
    seeds: list[int] = field(default_factory=lambda: [0])
    scenarios: list[str] = field(default_factory=lambda: list(PAPER_SCENARIOS))
    metrics: list[str] = field(default_factory=lambda: ["CR_total"])  # the metrics decided on
    # equivalence margins in the table's units (percentage points, cm, m/s)
    margins: dict[str, float] = field(default_factory=lambda: {"CR_total": 0.1, "CD": 0.1, "AS": 0.01})
    max_seeds: int = 10  # seeds=auto adds seeds up to this many per variant
    # a folder of trained runs (<label>/seed<k>/) that the study evaluates instead of training
    # (the same label, seed and training config; e.g. results/paper-budget)
    checkpoints_from: str = ""
    # set by `sigmarl sweep` for its jobs: the plan file and this job's key in it
    job: str = ""
    plan: str = ""


@dataclass
class RulesConfig:
    """The paper's code where ours differs, one switch per difference: all off (`rules=ours`)
    is our environment, all on (`rules=paper`) the paper's. Evaluation keeps the dynamics and
    observation switches of the checkpoint it evaluates; it always measures with our
    contacts, per-agent flags and fresh observations (`sigmarl.env.paper_rules`)."""

    # paper: speed command in [-1, 1]; VMAS drag 0.25 makes v = delta/dt - 0.25 v_prev (steady
    # 0.8 c through an alternating transient c, 0.75 c, 0.81 c, ...); the yaw rate likewise
    drag_dynamics: bool = False
    speed_normaliser_one: bool = False  # paper: observed speeds and velocities / 1.0 (ours / 0.8)
    unsigned_speed: bool = False  # paper: ego view observes |v| (ours the signed forward speed)
    # paper: ego view observes another's velocity as |v_j| (cos, sin)(psi_j - psi_i), along its
    # heading and unsigned (ours: its velocity vector along its course, in the ego frame)
    others_velocity_heading: bool = False
    unwrapped_headings: bool = False  # paper: headings and relative headings never wrapped
    one_sided_noise: bool = False  # paper: + obs.noise x U[0, 1) (mean +0.01; ours zero-mean)
    # paper: center line at raw map vertices; reference points the vertices +2, +4, +6 from
    # the start of the closest segment; center-line distance and progress on that polyline
    raw_center_line: bool = False
    # paper (M4): 5 raw boundary vertices, one before to three after the start of the
    # boundary's own closest segment (ours: resampled, through the center-line index)
    own_boundary_index: bool = False
    test_world_size: bool = False  # paper: bird's-eye view / the test map's size in evaluation
    # paper: collisions are strict crossings of edges (agent-agent: the rectangles' edges;
    # agent-lane: rectangle edges against the whole raw boundary polylines); touching and
    # containment do not count
    strict_crossings: bool = False
    env_lane_flag: bool = False  # paper: the lane-collision info flag is per environment
    lagged_steering: bool = False  # paper: steering penalty on delta_{t-1} - delta_{t-2}
    timeout_terminal: bool = False  # paper: a training time-out is terminal (ours: truncated)
    stale_respawn_obs: bool = False  # paper: test-mode respawns return the pre-respawn observation


@dataclass
class Config:
    map: MapConfig = field(default_factory=MapConfig)
    obs: ObsConfig = field(default_factory=ObsConfig)
    env: EnvConfig = field(default_factory=EnvConfig)
    network: NetworkConfig = field(default_factory=NetworkConfig)
    ppo: PPOConfig = field(default_factory=PPOConfig)
    tracking: TrackingConfig = field(default_factory=TrackingConfig)
    eval: EvalConfig = field(default_factory=EvalConfig)
    rules: RulesConfig = field(default_factory=RulesConfig)
    seed: int = 0
    device: str = "cpu"
    threads: int = 1
    resume: bool = False
    study: StudyConfig = field(default_factory=StudyConfig)
    # The run's label: a study's variant, or (a lone `sigmarl train`) M0..M5 or custom-<hash>
    # from the obs flags (conf/config.yaml)
    model: str = MISSING
    overrides: list[str] = field(default_factory=list)  # the variant's overrides (a sweep job's)
    fingerprint: str = ""  # of the training settings (sigmarl.identity), set at composition
    runs_root: str = MISSING  # the study's run folders: <runs_root>/<model>/seed<seed>
    run_dir: str = MISSING  # where checkpoints live; set by conf/config.yaml


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
        merged = OmegaConf.merge(OmegaConf.structured(Config), _known(values, Config))
        for key in ("model", "runs_root", "run_dir"):  # mandatory (MISSING) in the schema
            if OmegaConf.is_missing(merged, key):
                merged[key] = model_label(merged.obs) if key == "model" else ""
        return as_config(merged)
    except OmegaConfBaseException as e:
        raise SigmarlError(f"{what} does not fit sigmarl's config schema: {str(e).splitlines()[0]}") from e


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
