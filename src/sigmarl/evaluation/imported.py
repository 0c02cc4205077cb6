"""A policy trained by the paper's own code (SigmaRL, ITSC 2024) evaluated in our evaluator.

Such a file is a plain `state_dict` of one parameter-shared MLP, D -> 256 -> 256 -> 4 with tanh
between the layers, whose four outputs are (loc, scale) of a TanhNormal. Its deterministic action
is the action box times tanh(loc), as our own actor's (`training.networks.PolicyHead`). The file
says nothing of the observation it was trained on, so the user names the model (M0..M5: its
observation flags), and the rules it drives under:

- `paper`: the paper's observation and dynamics; the observation is fed as it is, and the box is
  the paper's command range (1.0 m/s, 35 deg);
- `ours`: the observation is put into the paper's units first (`adapt`): speeds and velocities
  x0.8 (the paper divides them by 1.0, we by 0.8), the own speed unsigned (ego view), and +0.01 on
  every entry (the paper's noise is 0.02 U[0, 1), ours zero-mean); the box is ours (0.8 m/s, the
  settled speed, 35 deg). The reference's FORMAT.md gives these facts as measured.

The rollout is the one every evaluation runs (`rollout.evaluate_policy`); the rows are ordinary
evaluation rows under a label of their own, marked as imported with the file's SHA-256.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pandas as pd
import torch

from sigmarl import crash
from sigmarl.ablation import CORNERS, MODELS, obs_strategies
from sigmarl.config import Config
from sigmarl.env.paper_rules import COMMAND_LIMIT, rules_label
from sigmarl.errors import SigmarlError
from sigmarl.policy_input import neighbours, observation_size
from sigmarl.scenarios import scenario as scenario_of

SOURCE = "SigmaRL"  # the `source` of imported rows (ours have none)
_PREFIX = "module.0.module.0.agent_networks.0."
LAYERS = ("0", "2", "4")  # the Linear layers of the Sequential (tanh at 1 and 3)
HIDDEN = 256
# ours -> the paper's units (FORMAT.md)
SPEED_FACTOR = 0.8  # our speeds are / 0.8 m/s, the paper's / 1.0
NOISE_MEAN = 0.01  # the paper's noise 0.02 U[0, 1) has mean +0.01; ours has none
ADAPTATION = "speeds x0.8, own speed unsigned, +0.01 every entry; box (0.8 m/s, 35 deg)"


def load_weights(path: Path) -> list[tuple[torch.Tensor, torch.Tensor]]:
    """The three layers' (weight, bias) of a SigmaRL policy file, or one line saying why it is none."""
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as e:  # noqa: BLE001 - any unreadable file gets the same one line
        raise SigmarlError(f"{path} is not a SigmaRL policy file (a saved state_dict): "
                           f"{str(e).splitlines()[0] if str(e) else type(e).__name__}") from None
    keys = {f"{_PREFIX}{i}.{kind}" for i in LAYERS for kind in ("weight", "bias")}
    if not isinstance(state, dict) or set(state) != keys:
        found = sorted(state)[:3] if isinstance(state, dict) else type(state).__name__
        raise SigmarlError(f"{path} is not a SigmaRL policy file: expected the keys {_PREFIX}{{0,2,4}}.{{weight,bias}} "
                           f"(an MLP D -> 256 -> 256 -> 4), found {found}")
    layers = [(state[f"{_PREFIX}{i}.weight"].float(), state[f"{_PREFIX}{i}.bias"].float()) for i in LAYERS]
    shapes = [tuple(w.shape) for w, _ in layers]
    d = shapes[0][1] if len(shapes[0]) == 2 else None
    if d is None or shapes != [(HIDDEN, d), (HIDDEN, HIDDEN), (4, HIDDEN)] or \
            any(tuple(b.shape) != (w.shape[0],) for w, b in layers):
        raise SigmarlError(f"{path} is not a SigmaRL policy file: its layers are {shapes}, expected an MLP "
                           f"D -> {HIDDEN} -> {HIDDEN} -> 4")
    return layers


def check_model_size(path: Path, inputs: int, model: str, cfg: Config, scenarios: list[str]) -> None:
    """One line naming both sizes if the policy's input is not the named model's observation."""
    for name in scenarios:
        size = observation_size(cfg.obs, scenario_of(name).n_agents)
        if size != inputs:
            raise SigmarlError(f"{path} takes {inputs} inputs, but model {model}'s observation "
                               f"({MODELS[model]}) has {size} on {name}; the paper's models take "
                               f"{paper_sizes(cfg)}")


def paper_sizes(cfg: Config) -> str:
    """Each paper model's input size with `cfg`'s neighbours and reference points: `M0 32, M1 36, ...`."""
    from dataclasses import replace

    sizes = []
    for model, preset in MODELS.items():
        off = preset.removeprefix("no_") if preset != "full" else None
        obs = replace(cfg.obs, **{flag: flag != off for flag in _FLAGS})
        sizes.append(f"{model} {observation_size(obs, cfg.obs.n_nearest + 1)}")
    return ", ".join(sizes)


_FLAGS = ("ego_view", "vertices", "distance_to_agents", "distance_to_boundaries", "distance_to_center_line")


@dataclass(frozen=True)
class SpeedEntries:
    """Where the observation holds speeds: the own speed (ego view: one entry) or velocity (two),
    and each observed neighbour's velocity (two each)."""

    own: list[int]
    others: list[int]
    own_is_speed: bool  # the ego view's scalar speed (the paper observes it unsigned)


def speed_entries(cfg: Config, n_agents: int) -> SpeedEntries:
    """The observation's speed entries for `cfg`'s flags among `n_agents` agents, in the layout of
    `env.observation.build_observation` (sizes as `policy_input.observation_size` counts them)."""
    obs = cfg.obs
    own = [0] if obs.ego_view else [3, 4]  # after position and heading in a bird's-eye view
    first = observation_size(obs, 1)  # the own block: the size with nobody else to observe
    per_other = observation_size(obs, 2) - first
    before = 2 * CORNERS if obs.vertices else 2 + 1 + 2  # corners, or position, heading and size
    others = [first + j * per_other + before + i for j in range(neighbours(obs, n_agents)) for i in (0, 1)]
    return SpeedEntries(own, others, bool(obs.ego_view))


def adapt(obs: torch.Tensor, entries: SpeedEntries) -> torch.Tensor:
    """Our observation [..., D] in the paper's units (module docstring): speeds x0.8, the own
    speed unsigned, every entry +0.01."""
    out = obs.clone()
    speeds = entries.own + entries.others
    out[..., speeds] = out[..., speeds] * SPEED_FACTOR
    if entries.own_is_speed:
        out[..., entries.own] = out[..., entries.own].abs()
    return out + NOISE_MEAN


class ImportedPolicy(torch.nn.Module):
    """obs [E, A, D] -> deterministic action [E, A, 2]: box x tanh(loc), the observation adapted
    to the paper's units first where `entries` is given (our rules)."""

    def __init__(self, layers, box: tuple[float, float], entries: SpeedEntries | None):
        super().__init__()
        self.layers = layers
        self.entries = entries
        self.register_buffer("box", torch.tensor(box, dtype=torch.float32))
        # as PolicyHead: tanh kept inside +-(1 - resolution), as torchrl's TanhNormal keeps it
        self.tanh_limit = 1.0 - torch.finfo(torch.float32).resolution

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        x = adapt(obs, self.entries) if self.entries is not None else obs
        for i, (w, b) in enumerate(self.layers):
            x = torch.nn.functional.linear(x, w.to(x.device), b.to(x.device))
            x = x.tanh() if i < len(self.layers) - 1 else x
        loc = x[..., :2]
        return self.box.to(x.device) * loc.tanh().clamp(-self.tanh_limit, self.tanh_limit)


def action_box(cfg: Config) -> tuple[float, float]:
    """(speed command, steering) limits of the rules' action box: the paper's command range
    1.0 m/s under its drag dynamics, our top speed otherwise; the vehicle's steering limit."""
    vehicle = cfg.env.vehicle
    speed = COMMAND_LIMIT if cfg.rules.drag_dynamics else float(vehicle.max_speed)
    return speed, float(vehicle.max_steering)


def imported_policy(layers, cfg: Config, n_agents: int) -> ImportedPolicy:
    """The policy as it drives under `cfg.rules`: as it is under the paper's, adapted under ours."""
    entries = None if rules_label(cfg.rules) == "paper" else speed_entries(cfg, n_agents)
    return ImportedPolicy(layers, action_box(cfg), entries)


def evaluate_imported(path: Path, cfg: Config, model: str, label: str, scenarios: list[str],
                      progress: bool = True) -> pd.DataFrame:
    """Per-simulation rows of the SigmaRL policy in `path` as model `model` under `cfg.rules`,
    labelled `label` and marked imported (`source`, `policy_sha256`)."""
    from sigmarl.evaluation.protocol import file_sha256
    from sigmarl.evaluation.rollout import evaluate_policy

    layers = load_weights(path)
    check_model_size(path, layers[0][0].shape[1], model, cfg, scenarios)
    frames = []
    for name in scenarios:
        n_agents = scenario_of(name).n_agents
        policy = imported_policy(layers, cfg, n_agents)
        frames.append(evaluate_policy(policy, cfg, name, n_sims=cfg.eval.n_sims, steps=cfg.eval.steps,
                                      seed=cfg.eval.seed, n_agents=n_agents, device=cfg.device, progress=progress))
        crash.point(f"eval:scenario:{name}")
    rows = pd.concat(frames, ignore_index=True)
    rows.insert(0, "model", label)
    rows.insert(1, "obs", obs_strategies(cfg.obs))
    rows.insert(2, "seed", 0)  # one policy: one "seed" of its column
    rows.insert(3, "rules", rules_label(cfg.rules))
    rows["source"] = SOURCE
    rows["policy_sha256"] = file_sha256(path)
    return rows


def evaluate_rows_of(path: Path, target: str, cfg: Config, model: str, label: str, rows_file: Path) -> pd.DataFrame:
    """The rows of the SigmaRL policy in `path` (named `target`): those saved in `rows_file` for
    the same file, model, label, rules and protocol, or evaluated now and saved there (rows
    first, then their note, `evaluation.json` or `<stem>.json`, as `sigmarl evaluate` keeps them)."""
    from sigmarl.eval_key import eval_key
    from sigmarl.evaluation.protocol import file_sha256, save_rows, saved_rows
    from sigmarl.paths import ensure_writable

    load_weights(path)  # a file that is no such policy is refused before rows are looked up
    identity = {"eval_key": eval_key(cfg.eval), "policy_sha256": file_sha256(path), "source": SOURCE,
                "policy": target, "as_model": model, "label": label, "rules_label": rules_label(cfg.rules),
                "adaptation": "none" if rules_label(cfg.rules) == "paper" else ADAPTATION}
    rows = saved_rows(rows_file, identity)
    if rows is not None:
        return rows
    ensure_writable(rows_file.parent, "cannot write the evaluation rows there; use another --out")
    rows = evaluate_imported(path, cfg, model, label, list(cfg.eval.scenarios))
    save_rows(rows, rows_file, identity, cfg.eval)
    return rows


def animate_imported(path: Path, cfg: Config, model: str, label: str, scenario: str, sims: list[int], steps: int,
                     out_dir: Path, mp4: bool | None = None) -> dict:
    """The SigmaRL policy in `path`, as model `model` under `cfg.rules`, driving `scenario` as it
    does in its evaluation (`animation.animate_policy`): <out_dir>/<label>_<rules>_<scenario>_sim<k>.gif."""
    from sigmarl.evaluation.animation import animate_policy

    layers = load_weights(path)
    check_model_size(path, layers[0][0].shape[1], model, cfg, [scenario])
    policy = imported_policy(layers, cfg, scenario_of(scenario).n_agents)
    rules = rules_label(cfg.rules)
    return animate_policy(policy, cfg, scenario, sims, steps, cfg.eval.n_sims, cfg.eval.seed, out_dir,
                          f"{label}_rules-{rules}", f"{label} (rules={rules})", cfg.device, mp4)
