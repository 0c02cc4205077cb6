"""Animated evaluation rollouts: a checkpoint driving a scenario under the evaluation protocol
(test mode, deterministic actions, the evaluation's seed and simulation count), one GIF (and
an MP4 where an ffmpeg writer is installed) per scenario and chosen simulation.

The animation walks the evaluation's own steps (`rollout.rollout_steps`), so simulation k of an
animation is simulation k of the evaluation rows, and its titles' running collision counts
reach the rows' CR_AA and CR_AL times the steps.
"""

from __future__ import annotations

import importlib.util
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from sigmarl.env.render import Scene, snapshot
from sigmarl.errors import SigmarlError
from sigmarl.evaluation.rollout import rollout_steps
from sigmarl.scenarios import scenario as scenario_of
from sigmarl.training import checkpoint as ckpt
from sigmarl.training.loop import load_policy

FPS = 20


def mp4_writer_installed() -> bool:
    """Whether imageio can write MP4 here (its ffmpeg plugin or PyAV)."""
    return bool(importlib.util.find_spec("imageio_ffmpeg") or importlib.util.find_spec("av"))


class _Frames:
    """One animation's frames, kept small: each GIF frame quantised at once (a byte a pixel),
    each MP4 frame handed to the encoder as it comes."""

    def __init__(self, stem: Path, mp4: bool):
        stem.parent.mkdir(parents=True, exist_ok=True)
        self.gif, self.images = stem.with_suffix(".gif"), []
        self.mp4 = stem.with_suffix(".mp4") if mp4 else None
        if self.mp4:
            # optional: only MP4 output needs imageio's ffmpeg; yuv420p needs even sizes, and
            # macro_block_size=2 pads at most one pixel instead of 16
            import imageio.v2 as imageio

            self.encoder = imageio.get_writer(self.mp4, fps=FPS, macro_block_size=2)

    def add(self, frame: np.ndarray) -> None:
        from PIL import Image  # optional: only animations need Pillow

        # a frame's own palette keeps the collision red however few pixels carry it
        self.images.append(Image.fromarray(frame).quantize(256, method=Image.Quantize.FASTOCTREE,
                                                           dither=Image.Dither.NONE))
        if self.mp4:
            self.encoder.append_data(frame)

    def close(self) -> list[Path]:
        self.images[0].save(self.gif, save_all=True, append_images=self.images[1:], duration=1000 / FPS, loop=0)
        if self.mp4:
            self.encoder.close()
        return [self.gif, *([self.mp4] if self.mp4 else [])]


@dataclass
class Film:
    """One simulation's animation: its files, each frame's title, and its collision counts
    (steps with an agent-agent contact, steps with a lane contact), as its rows count them."""

    files: list[Path]
    titles: list[str] = field(default_factory=list)
    agent: int = 0
    lane: int = 0


def animate(path: Path, scenario: str, sims: list[int], steps: int, n_sims: int, seed: int, out_dir: Path,
            name: str | None = None, device: str = "cpu", mp4: bool | None = None) -> dict[int, Film]:
    """{k: its Film (a GIF, and an MP4 where one can be written)} for each simulation k in `sims` of checkpoint `path` driving `scenario`:
    the evaluation's first `steps` steps of its `n_sims` simulations from `seed`.

    Files are <out_dir>/<name>_<scenario>_sim<k>.gif (name: <model>_seed<seed> of the run).
    Policy and environment run on `device`, the command's, never on the device the checkpoint
    was trained on: a GPU-trained model animates on a CPU machine."""
    check_sims(sims, n_sims)
    actor, state = load_policy(path, n_agents=scenario_of(scenario).n_agents, device=device)
    cfg = ckpt.config_of(state, path)
    return animate_policy(actor, cfg, scenario, sims, steps, n_sims, seed, out_dir,
                          name or f"{cfg.model}_seed{cfg.seed}", f"{cfg.model} seed {cfg.seed}", device, mp4)


def check_sims(sims: list[int], n_sims: int) -> None:
    if bad := [k for k in sims if not 0 <= k < n_sims]:
        raise SigmarlError(f"simulation {bad[0]} does not exist: the evaluation runs simulations 0..{n_sims - 1} "
                           "(eval.n_sims)")


@torch.inference_mode()
def animate_policy(policy, cfg, scenario: str, sims: list[int], steps: int, n_sims: int, seed: int, out_dir: Path,
                   name: str, who: str, device: str = "cpu", mp4: bool | None = None) -> dict[int, Film]:
    """`animate` for any policy the evaluation drives (`rollout.rollout_steps`) under `cfg`:
    files <out_dir>/<name>_<scenario>_sim<k>.gif, each frame titled with `who`."""
    check_sims(sims, n_sims)
    n_agents = scenario_of(scenario).n_agents
    mp4 = mp4_writer_installed() if mp4 is None else mp4
    writers = {k: _Frames(out_dir / f"{name}_{scenario}_sim{k}", mp4) for k in sims}
    scenes, films = {}, {k: Film([]) for k in sims}
    for t, sc in enumerate(rollout_steps(policy, cfg, scenario, n_sims, steps, seed, n_agents, device), start=1):
        for k, film in films.items():
            if k not in scenes:
                scenes[k] = Scene(sc, title=f"{scenario} · {who} · simulation {k}")
            # counted as the rows count: a step with any agent in such a contact (rollout._Sums)
            film.agent += bool(sc.agent_collision[k].any())
            film.lane += bool(sc.lane_collision[k].any())
            scenes[k].update(snapshot(sc, k, step=t), so_far=(t, film.agent, film.lane))
            film.titles.append(scenes[k].ax.get_title())
            writers[k].add(scenes[k].frame())
    for k, film in films.items():
        film.files = writers[k].close()
    return films


def animate_checkpoint(path: Path, scenarios: list[str], steps: int, seed: int, out_dir: Path,
                       prefix: str = "M0", device: str = "cpu", n_sims: int = 1) -> dict[str, Path]:
    """{"animation_<scenario>": <out_dir>/animations/<prefix>_<scenario>.gif}: simulation 0 of
    each scenario (the report's animations of its baseline)."""
    out = {}
    for scenario in scenarios:
        files = animate(path, scenario, [0], steps, n_sims, seed, out_dir / "animations", device=device, mp4=False)
        gif = out_dir / "animations" / f"{prefix}_{scenario}.gif"
        files[0].files[0].replace(gif)
        out[f"animation_{scenario}"] = gif
    return out
