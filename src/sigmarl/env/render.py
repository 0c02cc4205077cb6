"""Headless pictures of the traffic scenario: one state as a figure, a rollout as GIF/MP4.

Figures use matplotlib's object API on the Agg canvas (never pyplot), so rendering works
without a display and leaves the global backend alone. A rollout reuses one figure: the
map is drawn once and only the vehicle patches, reference points and title change.
"""

from __future__ import annotations

import importlib.util
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import matplotlib as mpl
import numpy as np
import torch
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Polygon
from tensordict import TensorDictBase
from torchrl.envs import EnvBase, TransformedEnv
from torchrl.envs.libs.vmas import VmasEnv
from torchrl.envs.utils import step_mdp

from sigmarl.env.geometry import rect_corners
from sigmarl.env.scenario import LENGTH, WIDTH, TrafficScenario
from sigmarl.errors import SigmarlError
from sigmarl.maps.model import RoadMap
from sigmarl.maps.plot import plot_map

Policy = Callable[[TensorDictBase], TensorDictBase]
COLLISION = (1.0, 0.0, 0.0)  # pure red: no agent colour comes close (see _agent_colors)
LABEL = (0.7, 0.0, 0.0)
FIGSIZE = (6.0, 5.4)
DPI = 100


def _agent_colors(n: int) -> list[tuple[float, float, float, float]]:
    """Qualitative colours without the palettes' reds, so that red always means a collision."""
    if n <= 9:
        cmap, keep = mpl.colormaps["tab10"], [i for i in range(10) if i != 3]
    else:
        cmap, keep = mpl.colormaps["tab20"], [i for i in range(20) if i not in (6, 7)]
    return [cmap(keep[i % len(keep)]) for i in range(n)]


@dataclass
class Snapshot:
    """What a frame shows of one environment, as numpy arrays."""

    pos: np.ndarray  # [A, 2]
    corners: np.ndarray  # [A, 4, 2]
    ref_points: np.ndarray  # [A, P, 2]
    collided: np.ndarray  # [A] bool: agent-agent or agent-lane
    agent_hit: np.ndarray  # [A] bool: in contact with another agent
    lane_hit: np.ndarray  # [A] bool: in contact with a lane boundary
    n_agent_collisions: int
    n_lane_collisions: int
    step: int | None


def _unwrap(obj) -> tuple[TrafficScenario, object | None, RoadMap | None]:
    """(scenario, the VMAS Environment or None, the RoadMap the env was built with or None)."""
    if isinstance(obj, TrafficScenario):
        return obj, None, None
    base = obj.base_env if isinstance(obj, TransformedEnv) else obj  # -> a VmasEnv (subclass)
    vmas_env = base._env if isinstance(base, VmasEnv) else base  # -> the vmas Environment
    scenario = getattr(vmas_env, "scenario", None)
    if not isinstance(scenario, TrafficScenario):
        raise SigmarlError(f"cannot render {type(obj).__name__}: expected a TrafficScenario env")
    return scenario, vmas_env, scenario.road_map


def scenario_of(env) -> TrafficScenario:
    """The TrafficScenario behind an env from `make_env` (transformed or not)."""
    return _unwrap(env)[0]


def snapshot(scenario: TrafficScenario, env_index: int = 0, step: int | None = None) -> Snapshot:
    """The state of environment `env_index` as the scenario holds it now."""
    s = scenario
    pos, heading = s.pos[env_index].detach().cpu(), s.heading[env_index].detach().cpu()
    ref = getattr(s, "ref_points", None)
    ref = ref[env_index].detach().cpu() if ref is not None else pos.unsqueeze(-2)
    agent_hit = s.agent_collision[env_index].cpu()
    lane_hit = s.lane_collision[env_index].cpu()
    shown = agent_hit | lane_hit
    # In test mode colliders respawn within the step: draw them where they collided (the pose
    # the step ended in), without look-ahead points; the next frame shows their new start.
    moved = shown & s.respawned[env_index].cpu()
    if moved.any():
        m = moved.unsqueeze(-1)
        pos = torch.where(m, s.step_pos[env_index].detach().cpu(), pos)
        heading = torch.where(moved, s.step_heading[env_index].detach().cpu(), heading)
        ref = torch.where(m.unsqueeze(-1), pos.unsqueeze(-2), ref)
    return Snapshot(
        pos=pos.numpy(),
        corners=rect_corners(pos, heading, LENGTH, WIDTH).numpy(),
        ref_points=ref.numpy(),
        collided=shown.numpy(),
        agent_hit=agent_hit.numpy(),
        lane_hit=lane_hit.numpy(),
        n_agent_collisions=int(agent_hit.sum()),
        n_lane_collisions=int(lane_hit.sum()),
        step=step,
    )


class Scene:
    """One figure with the map drawn once and per-agent artists updated frame by frame."""

    def __init__(
        self,
        scenario: TrafficScenario,
        road_map: RoadMap | None = None,
        ax: Axes | None = None,
        show_ref_points: bool = True,
        figsize: tuple[float, float] = FIGSIZE,
        dpi: int = DPI,
        title: str | None = None,
    ):
        if ax is None:
            fig = Figure(figsize=figsize, dpi=dpi, layout="constrained")
            ax = fig.add_subplot()
        self.ax, self.fig = ax, ax.figure
        if self.fig.canvas is None or not isinstance(self.fig.canvas, FigureCanvasAgg):
            FigureCanvasAgg(self.fig)
        road_map = road_map or getattr(scenario, "road_map", None)
        if road_map is None:
            raise SigmarlError("rendering a bare scenario needs its map: pass road_map=...")
        plot_map(road_map, ax, routes=False)
        self.name = title or road_map.name  # e.g. the scenario, model and seed of an evaluation
        n = scenario.n_agents
        self.colors = _agent_colors(n)
        self.vehicles = [
            ax.add_patch(Polygon(np.zeros((4, 2)), closed=True, fc=c, ec="black", lw=0.6, zorder=5))
            for c in self.colors
        ]
        self.show_ref_points = show_ref_points
        n_ref = scenario.n_ref
        self.ref_dots = ax.scatter(
            np.zeros(n * n_ref),
            np.zeros(n * n_ref),
            s=6,
            zorder=4,
            c=np.repeat(np.array(self.colors), n_ref, axis=0),
            visible=show_ref_points,
        )
        # a colliding vehicle's label: what it hit ("agent", "lane" or both), in a darker red
        # than the vehicle's edge, so that pure red stays where the vehicle is
        self.labels = [ax.text(0, 0, "", color=LABEL, fontsize=7, fontweight="bold", zorder=6,
                               visible=False) for _ in range(n)]

    def update(self, snap: Snapshot, so_far: tuple[int, int, int] | None = None) -> None:
        """Draw `snap`. With `so_far` = (steps, steps with an agent-agent contact, steps with
        a lane contact) up to this one, the title counts the simulation's collisions so far,
        as its evaluation rows count them (CR_AA = the second / the first)."""
        for patch, corners, hit in zip(self.vehicles, snap.corners, snap.collided, strict=True):
            patch.set_xy(corners)
            patch.set_edgecolor(COLLISION if hit else "black")
            patch.set_linewidth(1.8 if hit else 0.6)
            patch.set_hatch("////" if hit else None)
        for label, corners, agent, lane in zip(self.labels, snap.corners, snap.agent_hit, snap.lane_hit, strict=True):
            label.set_visible(bool(agent or lane))
            label.set_text(" + ".join(w for w, on in (("agent", agent), ("lane", lane)) if on))
            label.set_position(corners.max(0))  # beside the vehicle's upper right corner
        if self.show_ref_points:
            self.ref_dots.set_offsets(snap.ref_points.reshape(-1, 2))
        step = "" if snap.step is None else f" · step {snap.step}"
        now = f"this step: {snap.n_agent_collisions} agent, {snap.n_lane_collisions} lane contacts"
        if so_far is None:
            title = f"{self.name}{step} · {now}"
        else:
            steps, aa, al = so_far
            title = (f"{self.name}{step}\nsteps with a collision so far: {aa} agent-agent "
                     f"(CR_AA {aa / steps:.3f}), {al} agent-lane (CR_AL {al / steps:.3f})\n{now}")
        self.ax.set_title(title, fontsize=8 if so_far else 9)

    def _dynamic(self) -> list:
        return [*self.vehicles, *self.labels, self.ref_dots, self.ax.title]

    def _cache_background(self) -> None:
        """Draw everything once (fixing the layout), then keep a picture of the static part."""
        canvas = self.fig.canvas
        canvas.draw()
        self.fig.set_layout_engine("none")  # the layout would otherwise be redone every frame
        visible = [a.get_visible() for a in self._dynamic()]
        for a in self._dynamic():
            a.set_visible(False)
        canvas.draw()
        self.background = canvas.copy_from_bbox(self.fig.bbox)
        for a, v in zip(self._dynamic(), visible, strict=True):
            a.set_visible(v)

    def frame(self) -> np.ndarray:
        """The figure as an RGB array [H, W, 3]; blits the changing artists onto the cached map."""
        canvas = self.fig.canvas
        if getattr(self, "background", None) is None:
            self._cache_background()
        canvas.restore_region(self.background)
        for a in self._dynamic():
            self.fig.draw_artist(a)
        return np.asarray(canvas.buffer_rgba())[..., :3].copy()


def _step_count(vmas_env, env_index: int) -> int | None:
    steps = getattr(vmas_env, "steps", None)  # VMAS counts steps since each env's reset
    return None if steps is None else int(steps[env_index])


def render_state(
    env_or_scenario,
    env_index: int = 0,
    ax: Axes | None = None,
    road_map: RoadMap | None = None,
    show_ref_points: bool = True,
    figsize: tuple[float, float] = FIGSIZE,
    dpi: int = DPI,
    title: str | None = None,
) -> Figure:
    """Draw one environment's current state: map, vehicles, reference points, collisions.

    `env_or_scenario` is the env `make_env` returns (or its VmasEnv) or the TrafficScenario
    itself; the map comes from `road_map`, else from the env's constructor arguments (or a
    `road_map` attribute of the scenario).
    """
    scenario, vmas_env, env_map = _unwrap(env_or_scenario)
    scene = Scene(scenario, road_map or env_map, ax, show_ref_points, figsize, dpi, title)
    scene.update(snapshot(scenario, env_index, _step_count(vmas_env, env_index)))
    return scene.fig


def _writer_for(path: Path) -> Callable[[Path, list[np.ndarray], int], None]:
    """A function writing frames to `path`, chosen by suffix; fails before any stepping."""
    suffix = path.suffix.lower()
    if suffix == ".gif":
        return _write_gif
    if suffix == ".mp4":
        if importlib.util.find_spec("imageio_ffmpeg") or importlib.util.find_spec("av"):
            return _write_mp4
        raise SigmarlError(
            f"cannot write {path}: MP4 needs an ffmpeg writer (pip install imageio-ffmpeg, or av); "
            "use a .gif path instead"
        )
    raise SigmarlError(f"cannot write {path}: use a .gif or .mp4 path")


def _write_gif(path: Path, frames: list[np.ndarray], fps: int) -> None:
    # optional: only GIF output needs Pillow
    from PIL import Image

    # Fast octree quantisation per frame: ~2.5x faster than Pillow's default median cut, and
    # a frame's own palette keeps the collision red however few pixels carry it.
    images = [
        Image.fromarray(f).quantize(256, method=Image.Quantize.FASTOCTREE, dither=Image.Dither.NONE)
        for f in frames
    ]
    images[0].save(path, save_all=True, append_images=images[1:], duration=1000 / fps, loop=0)


def _write_mp4(path: Path, frames: list[np.ndarray], fps: int) -> None:
    # optional: only MP4 output needs imageio
    import imageio.v2 as imageio

    # yuv420p needs even sizes; macro_block_size=2 pads at most one pixel instead of 16.
    with imageio.get_writer(path, fps=fps, macro_block_size=2) as writer:
        for f in frames:
            writer.append_data(f)


def render_rollout(
    env: EnvBase,
    policy: Policy | None = None,
    steps: int = 100,
    path: str | Path = "rollout.gif",
    env_index: int = 0,
    fps: int = 20,
    road_map: RoadMap | None = None,
    show_ref_points: bool = True,
    title: str | None = None,
) -> Path:
    """Run `env` for `steps` steps and write one frame per step (the state after it).

    `policy` maps a TensorDict to one with ("agents", "action"); None draws random actions.
    Done environments are reset as `step_and_maybe_reset` would, but each frame is drawn
    before that reset, so the step that ends an episode (a collision) is visible.
    """
    path = Path(path)
    write = _writer_for(path)
    scenario, vmas_env, env_map = _unwrap(env)
    scene = Scene(scenario, road_map or env_map, show_ref_points=show_ref_points, title=title)
    frames = []
    td = env.reset()
    with torch.no_grad():
        for _ in range(steps):
            td = policy(td) if policy is not None else env.rand_action(td)
            td = env.step(td)
            scene.update(snapshot(scenario, env_index, _step_count(vmas_env, env_index)))
            frames.append(scene.frame())
            td = env.maybe_reset(
                step_mdp(
                    td,
                    reward_keys=env.reward_keys,
                    done_keys=env.done_keys,
                    action_keys=env.action_keys,
                )
            )
    path.parent.mkdir(parents=True, exist_ok=True)
    write(path, frames, fps)
    return path
