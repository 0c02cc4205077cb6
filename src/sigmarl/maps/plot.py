"""Map figures: lanes in grey, routes in colour (`sigmarl maps show`, the docs pictures).

Figures are built on matplotlib's object API with the Agg canvas, never
pyplot, so drawing works headless and leaves the global backend alone.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib as mpl
import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from sigmarl.maps.model import RoadMap

_ROAD = "#e6e6e6"
_EDGE = "#555555"


def _route_colors(n: int) -> list:
    cmap = mpl.colormaps["tab10" if n <= 10 else "turbo"]
    if n <= 10:
        return [cmap(i) for i in range(n)]
    return [cmap(0.05 + 0.9 * i / max(n - 1, 1)) for i in range(n)]


def plot_map(roadmap: RoadMap, ax: Axes | None = None, show_ids: bool = False, routes: bool = True) -> Axes:
    """Draw lanes (filled grey, dark boundaries, dashed center lines) and routes on `ax`."""
    if ax is None:
        ax = Figure().add_subplot()
    for la in roadmap.lanelets.values():
        outline = np.concatenate([la.left, la.right[::-1]])
        ax.fill(outline[:, 0], outline[:, 1], color=_ROAD, lw=0, zorder=0)
    for la in roadmap.lanelets.values():
        for b in (la.left, la.right):
            ax.plot(b[:, 0], b[:, 1], color=_EDGE, lw=0.6, zorder=1)
        c = la.center
        ax.plot(c[:, 0], c[:, 1], color="#b0b0b0", lw=0.5, ls=(0, (4, 4)), zorder=1)
    if routes and roadmap.routes:
        for r, color in zip(roadmap.routes, _route_colors(len(roadmap.routes)), strict=True):
            c = r.center[: r.n_points].numpy()
            ax.plot(c[:, 0], c[:, 1], color=color, lw=1.1, alpha=0.85, zorder=2, solid_capstyle="round")
            if not r.is_loop:  # a dot where the route enters the map, an arrow head where it leaves
                ax.plot(*c[0], "o", color=color, ms=3.0, zorder=3)
            ax.annotate(
                "", xy=c[-1], xytext=c[-2], zorder=3,
                arrowprops={"arrowstyle": "-|>", "color": color, "lw": 1.1, "mutation_scale": 9},
            )
    if show_ids:
        for la in roadmap.lanelets.values():
            x, y = la.center[len(la.center) // 2]
            ax.text(
                x, y, str(la.id), fontsize=5.5, ha="center", va="center", zorder=4,
                bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.8},
            )
    ax.set_aspect("equal")
    ax.set_title(f"{roadmap.name}: {len(roadmap.lanelets)} lanelets, {len(roadmap.routes)} routes", fontsize=9)
    ax.set_xlabel("x (m)", fontsize=8)
    ax.set_ylabel("y (m)", fontsize=8)
    ax.tick_params(labelsize=7)
    xmin, ymin, xmax, ymax = roadmap.bounds
    pad = 0.1
    ax.set_xlim(xmin - pad, xmax + pad)
    ax.set_ylim(ymin - pad, ymax + pad)
    return ax


def _save(fig: Figure, path: str | Path, dpi: int = 200) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    FigureCanvasAgg(fig)
    fig.savefig(path, dpi=dpi)
    return path


def save_map_figure(roadmap: RoadMap, path: str | Path, show_ids: bool = False) -> Path:
    """Write one map as a PNG sized to the map's aspect ratio."""
    w, h = roadmap.size
    scale = 6.0 / max(w, h)
    fig = Figure(figsize=(max(w * scale, 3.0) + 0.8, max(h * scale, 2.0) + 0.8), layout="constrained")
    plot_map(roadmap, fig.add_subplot(), show_ids=show_ids)
    return _save(fig, path)


def save_scenario_maps(path: str | Path, scenarios: Sequence[tuple[str, RoadMap, int]]) -> Path:
    """Scenario maps, two or three to a row: (scenario name, its map, its number of agents)
    each; for the paper's four scenarios, the paper's Fig. 4 (the whole CPM map with its loops
    and the paper's intersection, on-ramp and roundabout)."""
    cols = 2 if len(scenarios) <= 4 else 3
    rows = -(-len(scenarios) // cols)
    fig = Figure(figsize=(5 * cols, 4.25 * rows), layout="constrained")
    axes = fig.subplots(rows, cols, squeeze=False)
    for ax, (scenario, m, n_agents) in zip(axes.flat, scenarios, strict=False):
        plot_map(m, ax)
        ax.set_title(f"{scenario} ({m.name}): {len(m.lanelets)} lanelets, {len(m.routes)} routes, "
                     f"{n_agents} agents", fontsize=9)
    for ax in list(axes.flat)[len(scenarios):]:
        ax.set_axis_off()
    return _save(fig, path)


def save_map_grid(path: str | Path, maps: Sequence[tuple[str, RoadMap]], cols: int = 4) -> Path:
    """Several maps with their routes in a grid, `cols` to a row: (title, map) each."""
    rows = -(-len(maps) // cols)
    fig = Figure(figsize=(4.2 * cols, 4.2 * rows), layout="constrained")
    axes = fig.subplots(rows, cols, squeeze=False)
    for ax, (title, m) in zip(axes.flat, maps, strict=False):
        plot_map(m, ax)
        ax.set_title(title, fontsize=9)
    for ax in list(axes.flat)[len(maps):]:
        ax.set_axis_off()
    return _save(fig, path, dpi=120)  # twelve maps at 200 dpi make a 1.5 MB picture
