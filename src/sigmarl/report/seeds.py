"""Per model-seed figures: each trained policy's collision rates, center-line deviation, speed and
training reward; where a next seed will land, and how many seeds are slow.

The table's cells average seeds; this lists them one by one, so that a claim such as "one seed
of seven drives like the paper's M4" can be read off a generated file instead of a hand-run
query. Rates are each seed's mean over its simulations, in % of steps like the table's.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
from scipy import stats

from sigmarl.metrics import AS, CD, CR_AA, CR_AL, CR_TOTAL, label, scaled
from sigmarl.report.cells import model_order, scenario_order
from sigmarl.report.tables import p_text, signed
from sigmarl.report.training import LAST, seed_curves
from sigmarl.stats.bootstrap import t_critical

RATES = [CR_TOTAL, CR_AA, CR_AL]
MIN_SEEDS = 5  # fewer seeds than this give no useful rank correlation
# The reward windows end at these fractions of a seed's training: at the paper's budget of 250
# iterations, iterations 51-75, 126-150 and 226-250 (early, middle and final learning).
WINDOW_ENDS = (0.3, 0.6, 1.0)


def reward_windows(iterations: int) -> list[tuple[int, int]]:
    """The (first, last) iterations of each window, LAST long, for a training of `iterations`."""
    windows = []
    for fraction in WINDOW_ENDS:
        end = max(1, round(fraction * iterations))
        windows.append((max(1, end - LAST + 1), end))
    return windows


def seed_table(rows: pd.DataFrame, curves: pd.DataFrame | None, models: list[str] | None = None) -> pd.DataFrame:
    """One row per evaluated (model, seed): `<rate>_<scenario>` in %, the worst scenario's CR_total,
    `CD_<scenario>` in cm, the speed's range over scenarios, and the mean reward in each of `reward_windows` (NaN where
    the seed has no training curve)."""
    models = model_order(rows, models)
    scenarios = scenario_order(rows)
    chosen = rows[rows["model"].isin(models)]
    # in the table's units (collision rates in %); (model, seed) x (metric, scenario)
    wide = pd.concat([chosen[["model", "seed", "scenario"]], scaled(chosen)], axis=1).groupby(
        ["model", "seed", "scenario"], sort=False)[[*RATES, CD, AS]].mean().unstack("scenario")
    wide = wide.reindex(columns=pd.MultiIndex.from_product([[*RATES, CD, AS], scenarios])).sort_index()
    by_seed = seed_curves(curves)
    records = []
    for model in models:
        for seed in sorted(rows.loc[rows["model"] == model, "seed"].unique()):
            m = wide.loc[(model, seed)]
            record = {"model": model, "seed": int(seed)}
            record |= {f"{metric}_{s}": m[(metric, s)] for metric in [*RATES, CD] for s in scenarios}
            record |= {f"{CR_TOTAL}_worst": m[CR_TOTAL].max(), f"{AS}_min": m[AS].min(), f"{AS}_max": m[AS].max()}
            records.append(record | _rewards(by_seed.get((model, int(seed)))))
    return pd.DataFrame(records)


def _rewards(c: pd.DataFrame | None) -> dict[str, float]:
    """The training length and the mean reward in each of `reward_windows` of one seed's curve."""
    if c is None:
        return {"iterations": float("nan")} | {f"reward_{i}": float("nan") for i in range(len(WINDOW_ENDS))}
    out = {"iterations": int(c["iteration"].max())}
    for i, (first, last) in enumerate(reward_windows(out["iterations"])):
        out[f"reward_{i}"] = c.loc[c["iteration"].between(first, last), "reward"].mean()
    return out


def spearman(x: pd.Series, y: pd.Series) -> tuple[float, float]:
    """Spearman's rank correlation and its two-sided p-value (scipy.stats.spearmanr: Student's t
    with n - 2 degrees of freedom; ties share their mean rank); NaN with fewer than 3 seeds or a
    constant side."""
    if len(x) < 3 or x.nunique() < 2 or y.nunique() < 2:
        return float("nan"), float("nan")
    rho, p = stats.spearmanr(x, y)
    return float(rho), float(p)


def reward_collisions(table: pd.DataFrame, scenarios: list[str], min_seeds: int = MIN_SEEDS) -> pd.DataFrame:
    """Does a seed's training reward predict how much it collides? Spearman's rho between the
    reward in each window and CR_total averaged over `scenarios`, over the seeds of each model
    with at least `min_seeds` of them, and over those models' seeds pooled (a model's level then
    mixes in; rank correlation within one model is the cleaner reading)."""
    table = table.assign(CR_total_mean=table[[f"CR_total_{s}" for s in scenarios]].mean(axis=1))
    counts = table.dropna(subset=["reward_0"]).groupby("model", sort=False).size()
    models = [m for m, n in counts.items() if n >= min_seeds]
    groups = [[m] for m in models] + ([models] if len(models) > 1 else [])
    records = []
    for group in groups:
        g = table[table["model"].isin(group)].dropna(subset=["reward_0"])
        record: dict = {"models": " + ".join(group), "seeds": len(g)}
        for i in range(len(WINDOW_ENDS)):
            record[f"rho_{i}"], record[f"p_{i}"] = spearman(g[f"reward_{i}"], g["CR_total_mean"])
        records.append(record)
    return pd.DataFrame(records)


def seeds_markdown(table: pd.DataFrame, scenarios: list[str]) -> str:
    """The table as Markdown: one line per model-seed, scenarios in `scenarios`' order."""
    iterations = table["iterations"].dropna().unique() if "iterations" in table else []
    if len(iterations) == 1:
        windows = " / ".join(f"{a}–{b}" for a, b in reward_windows(int(iterations[0])))
        reward_head = f"reward, iterations {windows}"
    else:
        reward_head = "reward at " + " / ".join(f"{f:.0%}" for f in WINDOW_ENDS) + " of training"
    lines = [
        f"Each evaluated model-seed (per scenario: {' / '.join(scenarios)}; collision rates in % of "
        f"steps, each the seed's mean over its simulations; reward: mean episode reward over {LAST} "
        "iterations):",
        "",
        f"| Model | seed | {label(RATES[0])} | worst | {label(RATES[1])} | {label(RATES[2])} | {label(CD)} | "
        f"{label(AS)} | {reward_head} |",
        "|---|---:|---|---:|---|---|---|---|---|",
    ]
    for r in table.to_dict("records"):
        rates = [" / ".join(_num(r[f"{rate}_{s}"]) for s in scenarios) for rate in RATES]
        deviation = " / ".join(_num(r[f"CD_{s}"]) for s in scenarios)
        speed = f"{r['AS_min']:.2f}–{r['AS_max']:.2f}"
        rewards = " / ".join(_num(r[f"reward_{i}"]) for i in range(len(WINDOW_ENDS)))
        lines.append(f"| {r['model']} | {r['seed']} | {rates[0]} | {_num(r['CR_total_worst'])} | {rates[1]} | "
                     f"{rates[2]} | {deviation} | {speed} | {rewards} |")
    correlation = reward_collisions(table, scenarios)
    if len(correlation):
        windows = reward_head.removeprefix("reward, iterations ").removeprefix("reward at ")
        lines += [
            "",
            "Does a seed's training reward predict its collisions? Spearman's rank correlation between "
            "the reward in each window and CR_total averaged over the scenarios, over the seeds of each "
            f"model with at least {MIN_SEEDS} (and over those models' seeds pooled); two-sided p from "
            "Student's t, not corrected for the several windows and groups:",
            "",
            f"| Models | seeds | rho (p), {windows} |",
            "|---|---:|---|",
        ]
        for r in correlation.to_dict("records"):
            cells = " / ".join(f"{signed(r[f'rho_{i}'], 2)} ({p_text(r[f'p_{i}'])})" for i in range(len(WINDOW_ENDS)))
            lines.append(f"| {r['models']} | {r['seeds']} | {cells} |")
    return "\n".join(lines) + "\n"


def _num(x: float) -> str:
    return "–" if pd.isna(x) else f"{x:.2f}"


# Where a next seed will land, and how many seeds are slow: the small-n practice of reporting
# seed-to-seed spread as intervals for one more run, not only for the mean.
#
# Prediction interval (per model and scenario, CR_total): normal theory, mean +- t_{n-1} s
# sqrt(1 + 1/n), its low end clipped at 0 (a rate); beside it the seeds' range [min, max], which
# holds a next seed with probability (n-1)/(n+1) whatever the seeds' distribution (so 95 % needs
# 39 seeds; our seed means are skewed, so the normal interval's 95 % is an approximation).
#
# Slow seeds: where the study declares `slow_seed` (a CR_total in %), a seed whose worst scenario
# exceeds it is slow; each variant's proportion is compared with its baseline's by Fisher's exact
# test (two-sided), the test for proportions of a few seeds.
LEVEL = 0.95
PREDICTION_COLUMNS = ["model", "scenario", "n_seeds", "mean", "sd", "pi_low", "pi_high", "min", "max",
                      "range_coverage"]
SLOW_COLUMNS = ["model", "baseline", "threshold", "slow", "seeds", "baseline_slow", "baseline_seeds", "p_fisher"]


def prediction_table(seeds: pd.DataFrame, scenarios: list[str], level: float = LEVEL) -> pd.DataFrame:
    """Per model and scenario with at least 2 seeds: the next seed's CR_total interval."""
    records = []
    for model, g in seeds.groupby("model", sort=False):
        for scenario in scenarios:
            x = g[f"CR_total_{scenario}"].dropna().to_numpy(float)
            n = len(x)
            if n < 2:
                continue
            mean, sd = float(x.mean()), float(x.std(ddof=1))
            half = t_critical(n - 1, level) * sd * math.sqrt(1 + 1 / n)
            records.append({"model": model, "scenario": scenario, "n_seeds": n, "mean": mean, "sd": sd,
                            "pi_low": max(0.0, mean - half), "pi_high": mean + half, "min": float(x.min()),
                            "max": float(x.max()), "range_coverage": (n - 1) / (n + 1)})
    return pd.DataFrame(records, columns=PREDICTION_COLUMNS)


def slow_seed_table(seeds: pd.DataFrame, baseline_of: dict[str, str], threshold: float) -> pd.DataFrame:
    """Per compared variant: its slow seeds (worst CR_total above `threshold`) against its
    baseline's, with Fisher's exact p. Empty where the threshold is 0 (not declared)."""
    if threshold <= 0:
        return pd.DataFrame(columns=SLOW_COLUMNS)
    worst = seeds.groupby("model", sort=False)["CR_total_worst"]
    counts = {m: (int((w > threshold).sum()), int(w.notna().sum())) for m, w in worst}
    records = []
    for model, baseline in baseline_of.items():
        if model not in counts or baseline not in counts:
            continue
        (a, n), (b, m) = counts[model], counts[baseline]
        p = float(stats.fisher_exact([[a, n - a], [b, m - b]]).pvalue)
        records.append({"model": model, "baseline": baseline, "threshold": threshold, "slow": a, "seeds": n,
                        "baseline_slow": b, "baseline_seeds": m, "p_fisher": p})
    return pd.DataFrame(records, columns=SLOW_COLUMNS)


def next_seed_markdown(prediction: pd.DataFrame, slow: pd.DataFrame, scenarios: list[str]) -> str:
    """The two tables as Markdown (empty where neither has rows)."""
    lines: list[str] = []
    if len(prediction):
        cells = prediction.set_index(["model", "scenario"])
        lines += [
            f"Where a next seed's CR_total (%) will land, per scenario ({' / '.join(scenarios)}): the "
            f"{LEVEL:.0%} prediction interval (normal theory, mean ± t s √(1 + 1/n)) and the seeds' "
            "range [min, max], which holds a next seed with probability (n − 1)/(n + 1) whatever the "
            "distribution:",
            "",
            "| Model | seeds | prediction interval | range (its coverage) |",
            "|---|---:|---|---|",
        ]
        for model in dict.fromkeys(prediction["model"]):
            mine = [cells.loc[(model, s)] for s in scenarios if (model, s) in cells.index]
            pi = " / ".join(f"[{r['pi_low']:.2f}, {r['pi_high']:.2f}]" for r in mine)
            ranges = " / ".join(f"[{r['min']:.2f}, {r['max']:.2f}]" for r in mine)
            n = int(np.max([r["n_seeds"] for r in mine]))
            lines.append(f"| {model} | {n} | {pi} | {ranges} ({(n - 1) / (n + 1):.0%}) |")
        lines.append("")
    if len(slow):
        threshold = float(slow["threshold"].iloc[0])
        lines += [
            f"Slow seeds (worst CR_total over the scenarios above {threshold:g} %), each variant against "
            "its baseline by Fisher's exact test (two-sided, unadjusted):",
            "",
            "| Model | slow | baseline | baseline slow | p |",
            "|---|---:|---|---:|---:|",
        ]
        for r in slow.to_dict("records"):
            lines.append(f"| {r['model']} | {r['slow']} of {r['seeds']} | {r['baseline']} | "
                         f"{r['baseline_slow']} of {r['baseline_seeds']} | {p_text(r['p_fisher'])} |")
        lines.append("")
    return "\n".join(lines)
