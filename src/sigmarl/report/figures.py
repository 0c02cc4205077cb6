"""Report figures, drawn with matplotlib's object API on the Agg canvas (no pyplot state).

`plot_paper_band`: the paper's training curves (its Fig. 5, one seed a model) against our seeds'
band, a panel per model: where the paper's one run lies among ours at each iteration, and the iteration of the
policy its Table I evaluated (the best mean episode reward of its run).

The two are logged differently. The paper's collector never resets, so its curve is the mean
return of whole episodes. Ours resets each batch and logs the cut segment as an episode
(`episode_reward_mean`, "batch-cut"); runs trained since also log the estimate of the paper's
quantity (`episode_reward_mean_complete`). A panel draws our seeds on that estimate where every
seed of the model has it, else batch-cut, and says which. Batch-cut at the end of training sits
`OFFSET` below the paper's definition (two fixed policies, `benchmarks/paper_episode_reward.py`,
docs/deviations.md): the batch-cut panels of those two models mark our last iterations' mean
raised by it, the comparison on one definition that the runs allow.
"""

from __future__ import annotations

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


def plot_distributions(rows: pd.DataFrame, models: list[str], scenarios: list[str], path: Path) -> Path:
    """Box plots of CR_total, CD and AS over the simulations: a row of panels per scenario.

    Every simulation is also drawn as a dot, since with 32 simulations and mostly zero
    collisions a box alone hides how many simulations had any. The collision rate's axis is
    symlog, so a model that collides in 40 % of steps leaves the others' tenths of a percent
    visible.
    """
    fig = Figure(figsize=(3.6 * len(DISTRIBUTION_METRICS), 2.6 * len(scenarios)), layout="constrained")
    axes = np.atleast_2d(fig.subplots(len(scenarios), len(DISTRIBUTION_METRICS), squeeze=False))
    rng = np.random.default_rng(0)  # fixed jitter: the same rows give the same picture
    positions = np.arange(1, len(models) + 1)
    for i, scenario in enumerate(scenarios):
        sc = rows[rows["scenario"] == scenario]
        for j, (metric, (title, scale)) in enumerate(DISTRIBUTION_METRICS.items()):
            ax = axes[i, j]
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
                # linear up to 0.1 %, logarithmic above: one model at 40 % would otherwise
                # flatten the others' 0-2 % onto the axis
                top = max([float(d.max()) for d in data if len(d)] + [0.1]) * 1.6
                ticks = [t for t in (0, 0.1, 1, 10, 100) if t <= top]
                ax.set_yscale("symlog", linthresh=0.1, linscale=0.5)
                ax.set_ylim(0, top)
                ax.set_yticks(ticks, [f"{t:g}" for t in ticks])
    fig.legend(handles=[Patch(fc="none", ec="black", label="box: quartiles, whiskers: 1.5 IQR"),
                        Line2D([], [], color="tab:orange", label="median"),
                        Line2D([], [], ls="", marker=".", color="tab:blue", label="one simulation")],
               loc="outside lower center", ncols=3, fontsize=8, frameon=False)
    return _save(fig, path, 120)


def plot_training_curves(curves: pd.DataFrame, path: Path, models: list[str] | None = None,
                         paper: pd.DataFrame | None = None) -> Path:
    """Mean episode reward per training iteration, one line per model (paper Fig. 5).

    `curves` has columns model, iteration, reward and optionally seed; with several seeds
    the line is their mean and the band their range. `paper` (same columns) adds the paper's
    curve of each model as a dashed line in the model's colour.
    """
    missing = {"model", "iteration", "reward"} - set(curves.columns)
    if missing:
        raise ValueError(f"training curves lack the column(s) {', '.join(sorted(missing))}")
    curves = curves.assign(model=curves["model"].astype(str))
    if models is None:
        models = list(dict.fromkeys(curves["model"]))
    fig = Figure(figsize=(6.4, 4.0), layout="constrained")
    ax = fig.subplots()
    banded = False
    for model in models:
        c = curves[curves["model"] == model]
        if c.empty:
            continue
        if "seed" in c.columns:  # average the seeds' rewards per iteration first
            per_seed = c.groupby(["iteration", "seed"])["reward"].mean().unstack("seed")
        else:
            per_seed = c.groupby("iteration")["reward"].mean().to_frame()
        n = per_seed.shape[1]
        line = ax.plot(per_seed.index, per_seed.mean(axis=1), label=f"{model} ({_seeds(n)})", lw=1.2)[0]
        if paper is not None and (p := paper[paper["model"] == model]).size:
            ax.plot(p["iteration"], p["reward"], ls="--", lw=0.9, color=line.get_color(),
                    label=f"{model} (paper)")
        if n > 1:
            banded = True
            ax.fill_between(per_seed.index, per_seed.min(axis=1), per_seed.max(axis=1),
                            color=line.get_color(), alpha=0.2, lw=0)
    _iteration_axis(ax)
    ax.set_title("training reward per iteration" + (": mean over seeds, band: their range" if banded else ""),
                 fontsize=9)
    ax.legend(ncols=2, fontsize=8)
    return _save(fig, path, 120)


def _save(fig: Figure, path: Path, dpi: int) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi)
    return path


def _seeds(n: int) -> str:
    return f"{n} seed{'s' if n != 1 else ''}"


def _iteration_axis(ax) -> None:
    """Whole iterations on the x axis (a 5-iteration run would otherwise get ticks at 1.5)."""
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel("iteration")
    ax.set_ylabel("mean episode reward")
    ax.grid(alpha=0.3)


PROFILE_BOOT = 1000
# panels per row of the performance profiles and of the heatmap: readable at 1280 px
PANELS_PER_ROW = 3
HEATMAP_COLUMNS = 7


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
    with 95% two-level (seeds, then simulations) bootstrap bands; a grid of panels. Lower is
    better."""
    values = seed_values(rows, HEADLINE)  # in %
    panels = [*scenarios, "all scenarios"] if len(scenarios) > 1 else list(scenarios)
    ncols = min(PANELS_PER_ROW, len(panels))
    nrows = -(-len(panels) // ncols)
    fig = Figure(figsize=(4.2 * ncols, 3.2 * nrows + 0.5), layout="constrained")
    axes = fig.subplots(nrows, ncols, squeeze=False).ravel()
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
    for ax in axes[len(panels):]:
        ax.set_visible(False)
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncols=min(len(labels), 8), fontsize=10,
               frameon=False, title="model", title_fontsize=10)
    fig.suptitle(f"performance profiles of {HEADLINE} (lower is better; band: 95% bootstrap over seeds "
                 "and simulations)", fontsize=10)
    return _save(fig, path, 110)


def plot_training_band(curves: pd.DataFrame, path: Path, models: list[str] | None = None,
                       n_boot: int = 2000) -> Path:
    """Mean episode reward per iteration over seeds, with the 95% bootstrap band of that mean
    over resampled seeds (`profiles.seed_band`); one line per model."""
    curves = curves.assign(model=curves["model"].astype(str))
    models = models or list(dict.fromkeys(curves["model"]))
    fig = Figure(figsize=(6.4, 4.0), layout="constrained")
    ax = fig.subplots()
    for model in models:
        c = curves[curves["model"] == model]
        if c.empty or "seed" not in c.columns:
            continue
        per_seed = c.groupby(["iteration", "seed"])["reward"].mean().unstack("seed")
        mean, lo, hi = seed_band(per_seed.to_numpy(), n_boot, bs.rng_for("training-band", model))
        n = per_seed.shape[1]
        line = ax.plot(per_seed.index, mean, label=f"{model} ({_seeds(n)}{', no band' if n == 1 else ''})",
                       lw=1.1)[0]
        if n > 1:  # a bootstrap over one seed would draw a band of width zero as if it were certain
            ax.fill_between(per_seed.index, lo, hi, color=line.get_color(), alpha=0.2, lw=0)
    _iteration_axis(ax)
    ax.set_title("mean training reward over seeds, 95% bootstrap band over seeds", fontsize=9)
    ax.legend(ncols=2, fontsize=8)
    return _save(fig, path, 120)


def plot_heatmap(summary: pd.DataFrame, models: list[str], scenarios: list[str], path: Path,
                 metric: str = HEADLINE) -> Path:
    """A models x scenarios matrix of one metric's estimates (the table's cells), each cell
    annotated with its estimate and 95 % interval; colour on a log scale, so that 0.05 % and
    5 % both show. More than HEATMAP_COLUMNS scenarios are split into stacked panels, so that
    the numbers stay readable at 1280 px."""
    cells = summary[summary["metric"] == metric].set_index(["model", "scenario"])

    def grid(column: str) -> np.ndarray:
        return np.array([[cells[column].get((m, s), np.nan) for s in scenarios] for m in models], dtype=float)

    mean, lo, hi = grid("mean"), grid("ci_low"), grid("ci_high")
    positive = mean[np.isfinite(mean) & (mean > 0)]
    floor = max(float(positive.min()) if positive.size else 0.01, 0.01)
    top = max(float(np.nanmax(mean)) if np.isfinite(mean).any() else 1.0, floor * 10)
    norm = LogNorm(floor, top)
    chunks = [list(range(i, min(i + HEATMAP_COLUMNS, len(scenarios))))
              for i in range(0, len(scenarios), HEATMAP_COLUMNS)]
    width = 1.55 * len(chunks[0]) + 2.6
    fig = Figure(figsize=(width, (0.62 * len(models) + 1.3) * len(chunks) + 0.6), layout="constrained")
    axes = fig.subplots(len(chunks), 1, squeeze=False)[:, 0]
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
    fig.colorbar(image, ax=list(axes), label=f"{label(metric)}, log scale", shrink=0.8)
    fig.suptitle(f"{metric}: mean over seeds [95% interval over seeds and simulations]", fontsize=10)
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
    rows = -(-len(models) // PANELS_PER_ROW)
    cols = min(len(models), PANELS_PER_ROW)
    fig = Figure(figsize=(3.6 * cols, 2.9 * rows + 0.4), layout="constrained")
    axes = np.atleast_1d(fig.subplots(rows, cols, squeeze=False)).ravel()
    for ax, model in zip(axes, models, strict=False):
        _panel(ax, curves[curves["model"] == model], paper[paper["model"] == model].set_index("iteration")["reward"],
               model)
    for ax in axes[len(models):]:
        ax.set_visible(False)
    handles = {label: h for ax in axes for h, label in zip(*ax.get_legend_handles_labels(), strict=True)}
    fig.legend(handles.values(), handles.keys(), fontsize=7, loc="outside lower center", ncols=len(handles))
    fig.suptitle("The paper's one run (whole episodes) against our seeds, mean episode reward per iteration",
                 fontsize=9)
    return _save(fig, path, 120)


def _panel(ax, ours: pd.DataFrame, paper: pd.Series, model: str) -> None:
    column, name = definition(ours)
    per_seed = ours.pivot_table(index="iteration", columns="seed", values=column)
    n = per_seed.shape[1]
    ax.fill_between(per_seed.index, per_seed.min(axis=1), per_seed.max(axis=1), color="tab:blue", alpha=0.25, lw=0,
                    label=f"ours, range of {n} seeds")
    ax.plot(per_seed.index, per_seed.median(axis=1), color="tab:blue", lw=1.0, label="ours, median")
    ax.plot(paper.index, paper.to_numpy(), color="black", lw=1.0, label="paper (whole episodes)")
    best = int(paper.idxmax())
    ax.plot([best], [paper.loc[best]], marker="v", color="tab:red", ms=6, ls="none",
            label="paper's evaluated policy")
    if column == "reward" and model in OFFSET_MODELS:  # our last iterations on the paper's definition, by the measured offset
        last = per_seed.index[-1]
        mean = float(per_seed.tail(LAST).mean(axis=1).mean())
        ax.errorbar([last + 4], [mean + sum(OFFSET) / 2], yerr=[[(OFFSET[1] - OFFSET[0]) / 2]], fmt="o", ms=3,
                    color="tab:green", capsize=2, label=f"ours, last {LAST} its., + offset {OFFSET[0]:.2f}–{OFFSET[1]:.2f}")
    ax.set_title(f"{model} (ours: {name})", fontsize=8)
    ax.set_xlabel("iteration", fontsize=8)
    ax.set_ylabel("mean episode reward", fontsize=8)
    ax.tick_params(labelsize=7)
    ax.grid(alpha=0.3)
