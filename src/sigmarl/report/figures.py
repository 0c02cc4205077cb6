"""Report figures, drawn with matplotlib's object API on the Agg canvas (no pyplot state).

`plot_paper_band` sets the paper's one run a model (its Fig. 5) against our seeds' band. The
paper logs whole episodes; ours logs the batch-cut segment (`reward`) and, in runs trained since,
the complete-episode estimate (`reward_complete`): a panel draws the estimate where every seed
has it, else batch-cut, and then marks our last iterations raised by the measured `OFFSET`
(docs/deviations.md, "The logged training reward").
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.colors import LogNorm
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.ticker import MaxNLocator

from sigmarl.metrics import BY_NAME, COLLISION_COLUMNS, FIGURES, HEADLINE, label, names
from sigmarl.report.compare.verdicts import seed_values
from sigmarl.report.training import LAST
from sigmarl.stats import bootstrap as bs
from sigmarl.stats.bootstrap import scenario_profiles, seed_band

DISTRIBUTION_METRICS = {name: (label(name), BY_NAME[name].scale) for name in names(FIGURES)}
PROFILE_BOOT = 1000
BAND_BOOT = 2000
# panels per row of the performance profiles and of the heatmap: readable at 1280 px
PANELS_PER_ROW = 3
HEATMAP_COLUMNS = 7


def _grid(n: int, per_row: int, size: tuple[float, float], extra: float = 0.0) -> tuple[Figure, np.ndarray]:
    """A figure of `n` panels of `size` inches, `per_row` a row (`extra` inches below for the
    legend), as a flat array; the grid's unused panels hidden."""
    cols = min(per_row, n)
    rows = -(-n // cols)
    fig = Figure(figsize=(size[0] * cols, size[1] * rows + extra), layout="constrained")
    axes = fig.subplots(rows, cols, squeeze=False).ravel()
    for ax in axes[n:]:
        ax.set_visible(False)
    return fig, axes


def _drawn(axes: Iterable) -> dict:
    """Label -> handle of everything the panels drew with a label, each label once."""
    return {name: h for ax in axes for h, name in zip(*ax.get_legend_handles_labels(), strict=True)}


def _legend(fig: Figure, handles: Mapping, most: int = 8, **kwargs) -> None:
    """One legend under the panels, at most `most` entries a row."""
    fig.legend(list(handles.values()), list(handles), loc="outside lower center",
               ncols=min(len(handles), most), **kwargs)


def _save(fig: Figure, path: Path, dpi: int) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi)
    return path


def _per_seed(curves: pd.DataFrame, column: str = "reward") -> pd.DataFrame:
    """One model's curve as iteration x seed (one column where the curves have no seeds)."""
    if "seed" not in curves.columns:
        return curves.groupby("iteration")[column].mean().to_frame()
    return curves.groupby(["iteration", "seed"])[column].mean().unstack("seed")


def _seeds(n: int) -> str:
    return f"{n} seed{'s' if n != 1 else ''}"


def plot_distributions(rows: pd.DataFrame, models: list[str], scenarios: list[str], path: Path) -> Path:
    """Box plots of CR_total, CD and AS over the simulations: a row of panels per scenario.

    Every simulation is also a dot: with 32 simulations and mostly zero collisions a box alone
    hides how many had any. The collision rate's axis is symlog (linear up to 0.1 %), so a model
    at 40 % leaves the others' tenths of a percent visible.
    """
    fig, axes = _grid(len(scenarios) * len(DISTRIBUTION_METRICS), len(DISTRIBUTION_METRICS), (3.6, 2.6))
    rng = np.random.default_rng(0)  # fixed jitter: the same rows give the same picture
    positions = np.arange(1, len(models) + 1)
    panels = ((scenario, metric) for scenario in scenarios for metric in DISTRIBUTION_METRICS)
    for ax, (scenario, metric) in zip(axes, panels, strict=True):
        title, scale = DISTRIBUTION_METRICS[metric]
        sc = rows[rows["scenario"] == scenario]
        data = [(sc.loc[sc["model"] == m, metric].dropna() * scale).to_numpy() for m in models]
        filled = [k for k, d in enumerate(data) if len(d)]
        if filled:
            ax.boxplot([data[k] for k in filled], positions=positions[filled], widths=0.6, showfliers=False)
        for k in filled:
            jitter = rng.uniform(-0.15, 0.15, len(data[k]))
            ax.plot(positions[k] + jitter, data[k], ".", ms=2, alpha=0.5, color="tab:blue")
        ax.set_xticks(positions, models)
        ax.set_xlim(0.4, len(models) + 0.6)
        ax.set_title(f"{scenario}: {title}", fontsize=9)
        ax.grid(axis="y", alpha=0.3)
        if metric in COLLISION_COLUMNS:
            top = max([float(d.max()) for d in data if len(d)] + [0.1]) * 1.6
            ticks = [t for t in (0, 0.1, 1, 10, 100) if t <= top]
            ax.set_yscale("symlog", linthresh=0.1, linscale=0.5)
            ax.set_ylim(0, top)
            ax.set_yticks(ticks, [f"{t:g}" for t in ticks])
    _legend(fig, {"box: quartiles, whiskers: 1.5 IQR": Patch(fc="none", ec="black"),
                  "median": Line2D([], [], color="tab:orange"),
                  "one simulation": Line2D([], [], ls="", marker=".", color="tab:blue")}, fontsize=8, frameon=False)
    return _save(fig, path, 120)


def _reward_lines(path: Path, title: str, lines: list[tuple], lw: float, paper: pd.DataFrame | None = None) -> Path:
    """Training reward per iteration, a line per model: `lines` holds (model, label, centre, band
    or None), `centre` indexed by iteration, the band shaded in its line's colour; `paper`: the
    paper's curve of each model dashed in the same colour."""
    fig = Figure(figsize=(6.4, 4.0), layout="constrained")
    ax = fig.subplots()
    for model, name, centre, band in lines:
        line = ax.plot(centre.index, centre.to_numpy(), label=name, lw=lw)[0]
        if paper is not None and (p := paper[paper["model"] == model]).size:
            ax.plot(p["iteration"], p["reward"], ls="--", lw=0.9, color=line.get_color(), label=f"{model} (paper)")
        if band is not None:
            ax.fill_between(centre.index, *band, color=line.get_color(), alpha=0.2, lw=0)
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))  # a 5-iteration run would get ticks at 1.5
    ax.set_xlabel("iteration")
    ax.set_ylabel("mean episode reward")
    ax.grid(alpha=0.3)
    ax.set_title(title, fontsize=9)
    ax.legend(ncols=2, fontsize=8)
    return _save(fig, path, 120)


def _curves_of(curves: pd.DataFrame, models: list[str]) -> Iterable[tuple[str, pd.DataFrame]]:
    """Each model of `models` with a curve, and its rows."""
    curves = curves.assign(model=curves["model"].astype(str))
    return ((m, c) for m in models if not (c := curves[curves["model"] == m]).empty)


def plot_training_curves(curves: pd.DataFrame, path: Path, models: list[str], paper: pd.DataFrame | None = None) -> Path:
    """Mean episode reward per training iteration, one line per model (paper Fig. 5): with several
    seeds their mean, the band their range; `paper` (same columns) adds the paper's curves."""
    lines = []
    for model, c in _curves_of(curves, models):
        per_seed = _per_seed(c)
        n = per_seed.shape[1]
        band = (per_seed.min(axis=1), per_seed.max(axis=1)) if n > 1 else None
        lines.append((model, f"{model} ({_seeds(n)})", per_seed.mean(axis=1), band))
    banded = any(band is not None for *_, band in lines)
    title = "training reward per iteration" + (": mean over seeds, band: their range" if banded else "")
    return _reward_lines(path, title, lines, 1.2, paper)


def plot_training_band(curves: pd.DataFrame, path: Path, models: list[str]) -> Path:
    """Mean episode reward per iteration over seeds, with the 95% bootstrap band of that mean
    over resampled seeds (`bootstrap.seed_band`); one line per model, no band for one seed (a
    bootstrap over one seed would draw a band of width zero as if it were certain)."""
    lines = []
    for model, c in _curves_of(curves, models):
        if "seed" not in c.columns:
            continue
        per_seed = _per_seed(c)
        mean, lo, hi = seed_band(per_seed.to_numpy(), BAND_BOOT, bs.rng_for("training-band", model))
        n = per_seed.shape[1]
        lines.append((model, f"{model} ({_seeds(n)}{', no band' if n == 1 else ''})",
                      pd.Series(mean, index=per_seed.index), (lo, hi) if n > 1 else None))
    return _reward_lines(path, "mean training reward over seeds, 95% bootstrap band over seeds", lines, 1.1)


@dataclass(frozen=True)
class ProfileAxis:
    """A profile's τ axis (collision rates, %): linear, or symlog where the rates span more than
    LOG_SPREAD (linear up to `linthresh`, a round number at or below the smallest non-zero
    rate); its right end `top` and its `ticks` round numbers."""

    log: bool
    linthresh: float
    top: float
    ticks: tuple[float, ...]


LOG_SPREAD = 20.0  # the largest rate over the smallest non-zero one above which the axis is logarithmic
_ROUND = (1.0, 2.0, 5.0)  # the round numbers of a log axis, per decade
_STEPS = (1.0, 2.0, 2.5, 5.0)  # a linear axis' tick steps, per decade


def _round(x: float, up: bool, steps: tuple[float, ...] = _ROUND) -> float:
    """The round number (steps x 10^k) at or above (up) / at or below x > 0."""
    decade = 10.0 ** np.floor(np.log10(x))
    options = [f * decade * k for k in (0.1, 1.0, 10.0) for f in steps]
    return float(min(o for o in options if o >= x * (1 - 1e-9)) if up else max(o for o in options if o <= x * (1 + 1e-9)))


def profile_axis(values: np.ndarray) -> ProfileAxis:
    """The τ axis for the collision rates (%) a panel shows: every curve spread across it. A
    fixed axis pressed a study of 5-40 % collisions against its right edge; a linear part as
    wide as a decade left half of a panel empty."""
    positive = values[np.isfinite(values) & (values > 0)]
    largest = float(positive.max()) * 1.02 if positive.size else 1.0
    if not positive.size or largest / float(positive.min()) <= LOG_SPREAD:
        step = _round(largest / 5, up=True, steps=_STEPS)  # four to six ticks
        top = round(float(np.ceil(largest / step - 1e-9) * step), 10)
        ticks = np.round(np.arange(0.0, top + step / 2, step), 10)
        return ProfileAxis(False, top, top, tuple(float(t) for t in ticks))
    top = _round(largest, up=True)
    linthresh = _round(min(float(positive.min()), top / 10), up=False)
    decades = [10.0 ** k for k in range(-4, 4) if 3 * linthresh <= 10.0 ** k and 1.5 * 10.0 ** k <= top]
    return ProfileAxis(True, linthresh, top, (0.0, linthresh, *decades, top))


def profile_thresholds(axis: ProfileAxis) -> np.ndarray:
    """Thresholds (%) from 0 to the axis' end, spaced as the axis is drawn: even steps (up to
    `linthresh` on a log axis), then evenly on a log scale."""
    if not axis.log:
        return np.linspace(0.0, axis.top, 201)
    linear = np.linspace(0.0, axis.linthresh, 21)
    return np.unique(np.concatenate([linear, np.geomspace(axis.linthresh, axis.top, 80)]))


def plot_performance_profiles(rows: pd.DataFrame, models: list[str], scenarios: list[str], path: Path) -> Path:
    """rliable-style performance profiles of CR_total: per model, the fraction of simulations
    with CR_total above tau, one panel per scenario and one over all scenarios (their mean),
    with 95% two-level (seeds, then simulations) bootstrap bands. Lower is better."""
    values = seed_values(rows, HEADLINE)  # in %
    panels = [*scenarios, "all scenarios"] if len(scenarios) > 1 else list(scenarios)
    fig, axes = _grid(len(panels), PANELS_PER_ROW, (4.2, 3.2), 0.5)
    for ax, panel in zip(axes, panels, strict=False):
        chosen = scenarios if panel == "all scenarios" else [panel]
        shown = [np.concatenate([np.ravel(g) for g in v]) for (m, s), v in values.items()
                 if s in chosen and m in models]
        axis = profile_axis(np.concatenate(shown) if shown else np.array([]))
        taus = profile_thresholds(axis)
        for model in models:
            per_scenario = {s: values[(model, s)] for s in chosen if (model, s) in values}
            if not per_scenario:
                continue
            point, lo, up = scenario_profiles(per_scenario, taus, PROFILE_BOOT, f"{model}|{panel}")
            line = ax.step(taus, point, where="post", label=model, lw=1.1)[0]
            ax.fill_between(taus, lo, up, step="post", color=line.get_color(), alpha=0.2, lw=0)
        if axis.log:  # the linear part (0 .. linthresh) a quarter decade wide: the curves get the panel
            ax.set_xscale("symlog", linthresh=axis.linthresh, linscale=0.25)
        ax.set_xlim(0, axis.top)
        ax.set_xticks(axis.ticks, [f"{x:g}" for x in axis.ticks])  # round values; symlog's own overlap at 0
        ax.set_ylim(0, 1.02)
        ax.set_title(panel, fontsize=10)
        ax.set_xlabel(f"τ: {label(HEADLINE)}")
        ax.set_ylabel(f"fraction with {HEADLINE} > τ")
        ax.grid(alpha=0.3)
    _legend(fig, _drawn(axes[:1]), fontsize=10, frameon=False, title="model", title_fontsize=10)
    fig.suptitle(f"performance profiles of {HEADLINE} (lower is better; band: 95% bootstrap over seeds "
                 "and simulations)", fontsize=10)
    return _save(fig, path, 110)


def plot_heatmap(summary: pd.DataFrame, models: list[str], scenarios: list[str], path: Path) -> Path:
    """A models x scenarios matrix of CR_total's estimates (the table's cells), each cell annotated
    with its estimate and 95 % interval; colour on a log scale, so that 0.05 % and 5 % both show.
    More than HEATMAP_COLUMNS scenarios are split into stacked panels (readable at 1280 px)."""
    cells = summary[summary["metric"] == HEADLINE].set_index(["model", "scenario"])
    mean, lo, hi = (np.array([[cells[c].get((m, s), np.nan) for s in scenarios] for m in models], dtype=float)
                    for c in ("mean", "ci_low", "ci_high"))
    positive = mean[np.isfinite(mean) & (mean > 0)]
    floor = max(float(positive.min()) if positive.size else 0.01, 0.01)
    top = max(float(np.nanmax(mean)) if np.isfinite(mean).any() else 1.0, floor * 10)
    norm = LogNorm(floor, top)
    chunks = [list(range(i, min(i + HEATMAP_COLUMNS, len(scenarios))))
              for i in range(0, len(scenarios), HEATMAP_COLUMNS)]
    fig, axes = _grid(len(chunks), 1, (1.55 * len(chunks[0]) + 2.6, 0.62 * len(models) + 1.3), 0.6)
    for ax, cols in zip(axes, chunks, strict=True):
        image = ax.imshow(np.clip(mean[:, cols], floor, None), cmap="magma_r", norm=norm, aspect="auto")
        for i in range(len(models)):
            for k, j in enumerate(cols):
                if np.isfinite(mean[i, j]):
                    dark = np.log(max(mean[i, j], floor) / floor) > 0.6 * np.log(top / floor)
                    ax.text(k, i, f"{mean[i, j]:.2f}\n[{lo[i, j]:.2f}, {hi[i, j]:.2f}]", ha="center",
                            va="center", fontsize=8, color="white" if dark else "black")
        ax.set_xticks(range(len(cols)), [scenarios[j] for j in cols], rotation=25, ha="right", fontsize=9)
        ax.set_yticks(range(len(models)), models, fontsize=9)
    fig.colorbar(image, ax=list(axes), label=f"{label(HEADLINE)}, log scale", shrink=0.8)
    fig.suptitle(f"{HEADLINE}: mean over seeds [95% interval over seeds and simulations]", fontsize=10)
    return _save(fig, path, 100)


# the paper's definition minus batch-cut at the end of training, measured on M0 and M5 seed 0
# `best.pt`; marked on those models' panels only (M1, which barely moves, ends episodes otherwise)
OFFSET = (0.50, 0.62)
OFFSET_MODELS = ("M0", "M5")


def definition(curves: pd.DataFrame) -> tuple[str, str]:
    """(column, its name): the complete-episode estimate where every seed logged it, else batch-cut."""
    if "reward_complete" in curves and curves.groupby("seed")["reward_complete"].apply(lambda s: s.notna().all()).all():
        return "reward_complete", "complete-episode estimate"
    return "reward", "batch-cut"


def plot_paper_band(curves: pd.DataFrame, paper: pd.DataFrame, models: list[str], path: Path) -> Path | None:
    """One panel per model of `models` that both have: our seeds' range and median per
    iteration, the paper's curve, its evaluated policy's iteration; None where none has both."""
    models = [m for m in models if (curves["model"] == m).any() and (paper["model"] == m).any()]
    if not models:
        return None
    fig, axes = _grid(len(models), PANELS_PER_ROW, (3.6, 2.9), 0.4)
    for ax, model in zip(axes, models, strict=False):
        _panel(ax, curves[curves["model"] == model], paper[paper["model"] == model].set_index("iteration")["reward"],
               model)
    handles = _drawn(axes)
    _legend(fig, handles, most=len(handles), fontsize=7)
    fig.suptitle("The paper's one run (whole episodes) against our seeds, mean episode reward per iteration",
                 fontsize=9)
    return _save(fig, path, 120)


def _panel(ax, ours: pd.DataFrame, paper: pd.Series, model: str) -> None:
    column, name = definition(ours)
    per_seed = _per_seed(ours, column)
    ax.fill_between(per_seed.index, per_seed.min(axis=1), per_seed.max(axis=1), color="tab:blue", alpha=0.25, lw=0,
                    label=f"ours, range of {per_seed.shape[1]} seeds")
    ax.plot(per_seed.index, per_seed.median(axis=1), color="tab:blue", lw=1.0, label="ours, median")
    ax.plot(paper.index, paper.to_numpy(), color="black", lw=1.0, label="paper (whole episodes)")
    best = int(paper.idxmax())
    ax.plot([best], [paper.loc[best]], marker="v", color="tab:red", ms=6, ls="none",
            label="paper's evaluated policy")
    if column == "reward" and model in OFFSET_MODELS:  # our last iterations on the paper's definition, by the measured offset
        mean = float(per_seed.tail(LAST).mean(axis=1).mean())
        ax.errorbar([per_seed.index[-1] + 4], [mean + sum(OFFSET) / 2], yerr=[[(OFFSET[1] - OFFSET[0]) / 2]], fmt="o",
                    ms=3, color="tab:green", capsize=2,
                    label=f"ours, last {LAST} its., + offset {OFFSET[0]:.2f}–{OFFSET[1]:.2f}")
    ax.set_title(f"{model} (ours: {name})", fontsize=8)
    ax.set_xlabel("iteration", fontsize=8)
    ax.set_ylabel("mean episode reward", fontsize=8)
    ax.tick_params(labelsize=7)
    ax.grid(alpha=0.3)
