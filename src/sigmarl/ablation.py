"""The paper's vocabulary: its observation strategies, declared once (`STRATEGIES`, the one
table every module reads), its six models' presets, its four scenarios (Table I's), and the
labels of a lone run derived from its flags (`model_label`). It imports no config module
(sigmarl.config imports it, for the flags, the label resolver and the default scenarios): the
flags are read from an ObsConfig, or the mapping Hydra hands the resolver, by name.

A study's own labels are its variants (`conf/study/*.yaml`); M0..M5 name the paper's models
and label a `sigmarl train` outside a study.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from sigmarl.errors import SigmarlError
from sigmarl.params import NORMALISERS as N

OWN, OTHER = "own", "other"  # a block's part: once per agent, or once per observed neighbour


@dataclass(frozen=True)
class Block:
    """A block of the observation vector (`sigmarl.env.observation`). `size` reads the obs
    config; `build` reads a view of the batched state (`observation.View`: its inputs `x`, flags,
    `ego`, `frame`, `take` and the geometry helpers) and returns the block's tensors, [E, A, n]
    (own) or [E, A, K, n] (other), none where its size is 0."""

    part: str  # OWN or OTHER
    size: Callable[[Any], int]
    build: Callable[[Any], list[Any]]


@dataclass(frozen=True)
class Strategy:
    """One observation strategy: its config flag (`obs.<flag>`), the paper's short name, its help
    line and its block (None: it changes how every block is observed)."""

    flag: str
    short: str
    help: str
    block: Block | None
    paper: bool = False  # one of the paper's five: on by default and in M0. Any other is off by
    # default, so a run trained before it was declared reads as off and keeps its fingerprint


def _own_state(v) -> list[Any]:
    x = v.x
    parts = [] if v.ego else [x.pos / x.pos.new_tensor(x.world), (x.heading / N.heading).unsqueeze(-1)]
    return [*parts, x.speed.unsqueeze(-1) / x.speed_scale if v.ego else x.vel / x.speed_scale]


def _boundaries(v) -> list[Any]:
    x, on = v.x, v.flags.distance_to_boundaries
    return [d.unsqueeze(-1) / N.distance if on else v.frame(pts)
            for d, pts in ((x.d_left, x.left_points), (x.d_right, x.right_points))]


def _shape(v) -> list[Any]:
    """The neighbours' corners (V), or their position, heading and size."""
    x, nb = v.x, v.x.neighbours
    n_env, n_agents, k = nb.shape
    if v.flags.vertices:
        return [v.frame(v.take(x.corners).flatten(2, 3)).view(n_env, n_agents, k, 8)]
    pos, heading = v.take(x.pos), v.take(x.heading)
    if v.ego:
        pos = v.to_local(pos, x.pos, x.heading) / N.ego
        heading = heading - x.heading.unsqueeze(-1)
        heading = v.wrap_angle(heading) if x.wrap_headings else heading
    else:
        pos = pos / pos.new_tensor(x.world)
    size = pos.new_tensor([x.length / N.ego, x.width / N.ego]).expand(n_env, n_agents, k, 2)
    return [pos, (heading / N.heading).unsqueeze(-1), size]


def _velocity(v) -> list[Any]:
    vel = v.take(v.x.vel)
    return [(v.rotate(vel, -v.x.heading.unsqueeze(-1)) if v.ego else vel) / v.x.speed_scale]


def when_on(flag: str, build: Callable[[Any], list[Any]]) -> Callable[[Any], list[Any]]:
    """A block that is there only while its strategy is on."""
    return lambda v: build(v) if getattr(v.flags, flag) else []


BOUNDARY_POINTS = 5  # observed points of each corridor boundary (env.ego.SIDE_WINDOW)
CORNERS = 4

# The observation's blocks that no strategy switches (their form may follow ego_view).
BASE_BLOCKS: dict[str, Block] = {
    "own_state": Block(OWN, lambda o: 1 if o.ego_view else 2 + 1 + 2, _own_state),  # speed; or pose and velocity
    "ref_points": Block(OWN, lambda o: 2 * int(o.n_ref_points), lambda v: [v.frame(v.x.ref_points)]),
    "velocity": Block(OTHER, lambda o: 2, _velocity),
}

# Every observation strategy, the paper's five in the paper's order (M<k> leaves out the k-th).
# A new one is declared here, with its block; its preset (conf/obs/) is optional.
STRATEGIES: list[Strategy] = [
    Strategy("ego_view", "E", "observe in the ego vehicle's frame (false: a bird's-eye view)", None, paper=True),
    Strategy("vertices", "V", "observe the other vehicles' corner vertices",
             Block(OTHER, lambda o: 2 * CORNERS if o.vertices else 2 + 1 + 2, _shape), paper=True),
    Strategy("distance_to_agents", "DA", "observe the distances to the nearest other vehicles",
             Block(OTHER, lambda o: int(o.distance_to_agents), when_on("distance_to_agents", lambda v: [
                 (v.x.distances.gather(2, v.x.neighbours) / N.distance).unsqueeze(-1)])), paper=True),
    Strategy("distance_to_boundaries", "DB", "observe the distances to the lane boundaries (false: boundary "
             "points instead)", Block(OWN, lambda o: 2 * (1 if o.distance_to_boundaries else 2 * BOUNDARY_POINTS),
                                       _boundaries), paper=True),
    Strategy("distance_to_center_line", "DC", "observe the distance to the route's center line",
             Block(OWN, lambda o: int(o.distance_to_center_line), when_on("distance_to_center_line", lambda v: [
                 v.x.d_center.unsqueeze(-1) / N.distance])), paper=True),
]
# Where the paper's blocks sit in the vector (by base block or flag); a later strategy's block
# follows these in its part, in declaration order.
PAPER_LAYOUT = ("own_state", "ref_points", "distance_to_center_line", "distance_to_boundaries",
                "vertices", "velocity", "distance_to_agents")


def layout() -> list[tuple[str, Block]]:
    """The vector's blocks in order, own blocks before the neighbours'."""
    blocks = {**BASE_BLOCKS, **{s.flag: s.block for s in STRATEGIES if s.block is not None}}
    names = [*PAPER_LAYOUT, *(n for n in blocks if n not in PAPER_LAYOUT)]
    return sorted(((n, blocks[n]) for n in names), key=lambda nb: nb[1].part != OWN)


def strategy_flags() -> type:
    """The flags as a dataclass (ObsConfig's base): each with its default and its help line."""
    for what in ("flag", "short"):
        names = [getattr(s, what) for s in STRATEGIES]
        if len(set(names)) < len(names):
            raise ValueError(f"two observation strategies share a {what}: {names}")
    flags = dataclasses.make_dataclass("StrategyFlags", [(s.flag, bool, s.paper) for s in STRATEGIES])
    flags.FIELD_HELP = {s.flag: f"{s.short}: {s.help}." for s in STRATEGIES}
    return flags


def later_flags() -> dict[str, bool]:
    """The strategies declared after the paper's, at the value every earlier run had (off)."""
    return {s.flag: False for s in STRATEGIES if not s.paper}


# The paper's five observation strategies: config flag -> the paper's short name.
OBS_FLAGS: dict[str, str] = {s.flag: s.short for s in STRATEGIES if s.paper}

# The paper's six models: M0 with all five strategies, M<k> leaving out the k-th (the order
# above); model -> observation preset (conf/obs/<preset>.yaml).
MODELS: dict[str, str] = {"M0": "full", **{f"M{k}": f"no_{flag}" for k, flag in enumerate(OBS_FLAGS, 1)}}
PRESET_TO_MODEL = {preset: model for model, preset in MODELS.items()}

# Table I's four scenarios, in the paper's order: the default evaluation, and the one order tables use.
PAPER_SCENARIOS = ("CPM", "Intersection", "On-Ramp", "Roundabout")

# a training iteration's timed phases (metrics.csv columns and MLflow metrics); their sum is its compute time
TIMINGS = ("time_collect_s", "time_advantage_s", "time_optimise_s")


def _on(obs: object | Mapping[str, Any], flag: str) -> bool:
    """A flag's value; a strategy the config does not know (declared after it was written) is off."""
    value = obs.get(flag, False) if isinstance(obs, Mapping) else getattr(obs, flag, False)
    return bool(value)


def obs_strategies(obs: object | Mapping[str, Any]) -> str:
    """The strategies switched on, in declaration order: "E,V,DA,DB,DC" for M0."""
    return ",".join(s.short for s in STRATEGIES if _on(obs, s.flag))


def flags_of(strategies: str) -> dict[str, bool]:
    """Every declared flag from a row's `obs` column ("E,V,DA,DB,DC"): the strategies it lists
    are on, any other is off (a row written before a strategy was declared lists it nowhere)."""
    on = set(strategies.split(",")) if strategies else set()
    unknown = on - {s.short for s in STRATEGIES}
    if unknown:
        raise SigmarlError(f"observation strategies {', '.join(sorted(unknown))} in {strategies!r} are not "
                           "declared here (sigmarl.ablation.STRATEGIES): rows of a newer sigmarl?")
    return {s.flag: s.short in on for s in STRATEGIES}


def paper_model(obs: object | Mapping[str, Any]) -> str | None:
    """The paper's model (M0..M5) these flags are, None for any other design."""
    label = model_label(obs)
    return label if label in MODELS else None


def model_label(obs: object | Mapping[str, Any]) -> str:
    """M0 with the paper's five strategies on (and no other), M1..M5 with exactly the paper's
    one left out, and "custom-<6 hex>" (a hash of the strategies that are on) for any other.

    `obs` is an ObsConfig (any object with the flags), or the flags as a mapping (the `obs` node that the config's
    `${sigmarl_model:${obs}}` resolver receives while Hydra composes)."""
    off = [flag for flag in OBS_FLAGS if not _on(obs, flag)]
    if not any(_on(obs, flag) for flag in later_flags()):
        if not off:
            return "M0"
        if len(off) == 1:
            return PRESET_TO_MODEL[f"no_{off[0]}"]
    import hashlib  # here: OpenSSL's load would cost `sigmarl --help` (which reads PAPER_SCENARIOS) 7 ms

    return "custom-" + hashlib.sha1(obs_strategies(obs).encode()).hexdigest()[:6]
