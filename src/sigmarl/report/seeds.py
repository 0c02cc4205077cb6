"""Per model-seed figures: each trained policy's collision rates, speed and training reward.

The table's cells average seeds; this lists them one by one, so that a claim such as "one seed
of seven drives like the paper's M4" can be read off a generated file instead of a hand-run
query. Rates are each seed's mean over its simulations, in % of steps like the table's.
"""

from __future__ import annotations

import pandas as pd

from sigmarl.report.aggregate import model_order, scenario_order
from sigmarl.report.training import LAST

RATES = ["CR_total", "CR_AA", "CR_AL"]
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
    the speed's range over scenarios, and the mean reward in each of `reward_windows` (NaN where
    the seed has no training curve)."""
    models = model_order(rows, models)
    scenarios = scenario_order(rows)
    per_seed = rows[rows["model"].isin(models)].groupby(["model", "seed", "scenario"], sort=False)[
        [*RATES, "AS"]].mean()
    records = []
    for model in models:
        for seed in sorted(rows.loc[rows["model"] == model, "seed"].unique()):
            means = per_seed.loc[(model, seed)]
            record: dict = {"model": model, "seed": int(seed)}
            for rate in RATES:
                for scenario in scenarios:
                    record[f"{rate}_{scenario}"] = 100 * means[rate].get(scenario, float("nan"))
            present = means.reindex(scenarios)
            record["CR_total_worst"] = 100 * present["CR_total"].max()
            record["AS_min"], record["AS_max"] = present["AS"].min(), present["AS"].max()
            record.update(_rewards(curves, model, int(seed)))
            records.append(record)
    return pd.DataFrame(records)


def _rewards(curves: pd.DataFrame | None, model: str, seed: int) -> dict[str, float]:
    nan = {f"reward_{i}": float("nan") for i in range(len(WINDOW_ENDS))} | {"iterations": float("nan")}
    if curves is None or not len(curves):
        return nan
    c = curves[(curves["model"].astype(str) == model) & (curves.get("seed", 0) == seed)]
    if not len(c):
        return nan
    out = {"iterations": int(c["iteration"].max())}
    for i, (first, last) in enumerate(reward_windows(out["iterations"])):
        out[f"reward_{i}"] = c.loc[c["iteration"].between(first, last), "reward"].mean()
    return out


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
        f"| Model | seed | CR_total (%) | worst | CR_AA (%) | CR_AL (%) | AS (m/s) | {reward_head} |",
        "|---|---:|---|---:|---|---|---|---|",
    ]
    for r in table.to_dict("records"):
        rates = [" / ".join(_num(r[f"{rate}_{s}"]) for s in scenarios) for rate in RATES]
        speed = f"{r['AS_min']:.2f}–{r['AS_max']:.2f}"
        rewards = " / ".join(_num(r[f"reward_{i}"]) for i in range(len(WINDOW_ENDS)))
        lines.append(f"| {r['model']} | {r['seed']} | {rates[0]} | {_num(r['CR_total_worst'])} | {rates[1]} | "
                     f"{rates[2]} | {speed} | {rewards} |")
    return "\n".join(lines) + "\n"


def _num(x: float) -> str:
    return "–" if pd.isna(x) else f"{x:.2f}"
