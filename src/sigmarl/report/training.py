"""Training curves -> per-seed summary: iterations, compute time, final and best reward.

The paper's Fig. 5 is one seed per model; its value here is the mean reward over the same
last iterations of its curve, so the two columns compare like with like.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from sigmarl.errors import SigmarlError
from sigmarl.readers import MAX_ITERATION

LAST = 25  # iterations averaged for the "final" reward (the curves are noisy per iteration)
COLUMNS = ["model", "seed", "iterations", "compute_min", "reward_last", "reward_best", "reward_complete_last"]


def seed_curves(curves: pd.DataFrame | None) -> dict[tuple[str, int], pd.DataFrame]:
    """Each (model, seed)'s curve, seeds ascending within a model (a curve without seeds is seed 0's)."""
    if curves is None or not len(curves):
        return {}
    c = curves.assign(model=curves["model"].astype(str))
    if "seed" not in c.columns:
        c = c.assign(seed=0)
    return {(model, int(seed)): g for (model, seed), g in c.groupby(["model", "seed"], sort=True)}


def training_summary(curves: pd.DataFrame, models: list[str]) -> pd.DataFrame:
    """One row per (model, seed) of `curves` (model, seed, iteration, reward[, seconds]).

    compute_min: the summed per-iteration compute time (collection, advantages, optimisation;
    NaN where the curves do not carry it); reward_last: mean reward of the last LAST iterations;
    reward_best: the best iteration's reward; reward_complete_last: the same as reward_last of the
    paper's definition, estimated (`episode_reward_mean_complete`; NaN for a run without it).
    """
    rows = []
    by_seed = seed_curves(curves)
    for model in models:
        for seed in [s for m, s in by_seed if m == model]:
            _check_curve(by_seed[(model, seed)], model, seed)
            g = by_seed[(model, seed)].sort_values("iteration", kind="stable")
            seconds = g["seconds"].sum(min_count=1) if "seconds" in g.columns else float("nan")
            rows.append({"model": model, "seed": seed, "iterations": int(g["iteration"].max()),
                         "compute_min": seconds / 60, "reward_last": g["reward"].tail(LAST).mean(),
                         "reward_best": g["reward"].max(),
                         "reward_complete_last": g["reward_complete"].tail(LAST).mean()
                         if "reward_complete" in g.columns else float("nan")})
    return pd.DataFrame(rows, columns=COLUMNS)


def _check_curve(g: pd.DataFrame, model: str, seed) -> None:
    """A curve the summary can trust, whether a folder's reader checked it or a tracking store
    gave it: whole iterations in 1..MAX_ITERATION and finite rewards, else one line."""
    it = pd.to_numeric(g["iteration"], errors="coerce").astype(float)
    reward = pd.to_numeric(g["reward"], errors="coerce").astype(float)
    bad = ~((it % 1 == 0) & (it > 0) & (it <= MAX_ITERATION)) | ~np.isfinite(reward)
    if bad.any():
        row = g[bad.to_numpy()].iloc[0]
        raise SigmarlError(f"the training curve of {model} seed {seed} is damaged: iteration {row['iteration']!r}, "
                           f"reward {row['reward']!r} (iterations are whole numbers in 1..{MAX_ITERATION}, "
                           "rewards finite); restore its training record (metrics.csv, or the tracking store's run)")


def paper_last_rewards(paper: pd.DataFrame) -> dict[str, float]:
    """The paper's Fig. 5 curves (model, iteration, reward) -> mean of their last LAST iterations."""
    return {str(m): g.sort_values("iteration")["reward"].tail(LAST).mean() for m, g in paper.groupby("model")}


def training_markdown(summary: pd.DataFrame, paper_last: dict[str, float] | None = None) -> str:
    """Per model: each seed's final reward, iterations and compute time, and the totals."""
    paper_col = paper_last is not None
    lines = [
        f"Training per model (seeds in order; reward: mean episode reward of the last {LAST} iterations"
        + (", the paper's Fig. 5 in parentheses" if paper_col else "") + "):",
        "",
        "| Model | seeds | reward per seed | mean reward | iterations | compute (min) per seed |",
        "|---|---:|---|---:|---|---|",
    ]
    for model, g in summary.groupby("model", sort=False):
        mean = f"{g['reward_last'].mean():.2f}"
        if paper_col and model in paper_last:
            mean += f" ({paper_last[model]:.2f})"
        lines.append(
            f"| {model} | {len(g)} | {' / '.join(f'{r:.2f}' for r in g['reward_last'])} | {mean} | "
            f"{' / '.join(str(i) for i in g['iterations'])} | "
            f"{' / '.join('–' if pd.isna(t) else f'{t:.0f}' for t in g['compute_min'])} |"
        )
    total = summary["compute_min"].sum(min_count=1)
    if pd.notna(total):
        lines += [
            "",
            f"Training compute of the {len(summary)} model-seeds: {total / 60:.1f} h, summed over their "
            "iterations (collection, advantages and optimisation, as each run timed itself).",
        ]
    return "\n".join(lines) + "\n"
