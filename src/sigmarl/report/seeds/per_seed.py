"""Per model-seed figures: each trained policy's collision rates, center-line deviation, speed and
training reward.

The table's cells average seeds; this lists them one by one, so that a claim such as "one seed
of seven drives like the paper's M4" can be read off a generated file instead of a hand-run
query. Rates are each seed's mean over its simulations, in % of steps like the table's.
"""

from __future__ import annotations

import math

import pandas as pd
from scipy import stats

from sigmarl.metrics import label, scaled
from sigmarl.report.cells import model_order, scenario_order
from sigmarl.report.tables import p_text, signed
from sigmarl.report.training import LAST

RATES = ["CR_total", "CR_AA", "CR_AL"]
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
    keys = chosen[["model", "seed", "scenario"]]
    # in the table's units (collision rates in %)
    per_seed = pd.concat([keys, scaled(chosen)], axis=1).groupby(["model", "seed", "scenario"], sort=False)[
        [*RATES, "CD", "AS"]].mean().sort_index()  # sorted: `.loc[(model, seed)]` without a PerformanceWarning
    by_seed = _curves_by_seed(curves)
    records = []
    for model in models:
        for seed in sorted(rows.loc[rows["model"] == model, "seed"].unique()):
            means = per_seed.loc[(model, seed)]
            record: dict = {"model": model, "seed": int(seed)}
            for rate in RATES:
                for scenario in scenarios:
                    record[f"{rate}_{scenario}"] = means[rate].get(scenario, float("nan"))
            for scenario in scenarios:
                record[f"CD_{scenario}"] = means["CD"].get(scenario, float("nan"))
            present = means.reindex(scenarios)
            record["CR_total_worst"] = present["CR_total"].max()
            record["AS_min"], record["AS_max"] = present["AS"].min(), present["AS"].max()
            record.update(_rewards(by_seed.get((model, int(seed)))))
            records.append(record)
    return pd.DataFrame(records)


def _curves_by_seed(curves: pd.DataFrame | None) -> dict[tuple[str, int], pd.DataFrame]:
    """Each (model, seed)'s curve, split once (a curve without seeds is seed 0's)."""
    if curves is None or not len(curves):
        return {}
    c = curves.assign(model=curves["model"].astype(str))
    if "seed" not in c.columns:
        c = c.assign(seed=0)
    return {(model, int(seed)): g for (model, seed), g in c.groupby(["model", "seed"], sort=False)}


def _rewards(c: pd.DataFrame | None) -> dict[str, float]:
    """The training length and the mean reward in each of `reward_windows` of one seed's curve."""
    if c is None:
        return {f"reward_{i}": float("nan") for i in range(len(WINDOW_ENDS))} | {"iterations": float("nan")}
    out = {"iterations": int(c["iteration"].max())}
    for i, (first, last) in enumerate(reward_windows(out["iterations"])):
        out[f"reward_{i}"] = c.loc[c["iteration"].between(first, last), "reward"].mean()
    return out


def spearman(x: pd.Series, y: pd.Series) -> tuple[float, float]:
    """Spearman's rank correlation and its two-sided p-value from Student's t with n - 2 degrees
    of freedom (the approximation scipy.stats.spearmanr uses); ties share their mean rank."""
    rx, ry = x.rank(), y.rank()
    n = len(rx)
    if n < 3 or rx.nunique() < 2 or ry.nunique() < 2:
        return float("nan"), float("nan")
    rho = float(rx.corr(ry))
    if abs(rho) >= 1 - 1e-12:  # a perfect ranking (up to rounding): no t to compute
        return math.copysign(1.0, rho), 0.0
    t = rho * math.sqrt((n - 2) / (1 - rho * rho))
    return rho, min(1.0, 2 * float(stats.t.sf(abs(t), n - 2)))


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
        f"| Model | seed | {label(RATES[0])} | worst | {label(RATES[1])} | {label(RATES[2])} | {label('CD')} | "
        f"{label('AS')} | {reward_head} |",
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
