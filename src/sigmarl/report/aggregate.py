"""Per-simulation evaluation rows -> per (scenario, model, metric) means with 95% CIs.

Simulations of all seeds are pooled for the mean and its confidence interval; the
spread of the per-seed means is reported beside it, because pooled simulations of one
seed share that seed's policy and so understate the seed-to-seed variation.
"""

from __future__ import annotations

import math

import pandas as pd

from sigmarl.errors import SigmarlError
from sigmarl.report.stats import mean_ci
from sigmarl.study import METRIC_COLUMNS, MODELS, SCENARIOS

COLLISION_COLUMNS = ("CR_AA", "CR_AL", "CR_total")
# Units as the paper's reference CSV writes them.
UNITS = {
    "CR_AA": "percent",
    "CR_AL": "percent",
    "CR_total": "percent",
    "CD": "cm",
    "AS": "m/s",
    "CS": "1",
}
SUMMARY_COLUMNS = [
    "scenario", "model", "metric", "unit", "mean", "ci", "std", "n", "n_seeds", "seed_std", "trimmed",
]  # fmt: skip


def validate_rows(rows: pd.DataFrame | None) -> pd.DataFrame:
    """The rows with the columns the report needs; a clear error for empty or malformed input."""
    if rows is None or len(rows) == 0:
        raise SigmarlError(
            "no finished evaluation runs to report on (evaluate some models first, "
            "e.g. with `sigmarl sweep` or `sigmarl evaluate`)"
        )
    missing = [c for c in ("model", "scenario", *METRIC_COLUMNS) if c not in rows.columns]
    if missing:
        raise SigmarlError(f"evaluation rows lack the column(s) {', '.join(missing)}")
    rows = rows.reset_index(drop=True)  # trimming addresses rows by label
    if "seed" not in rows.columns:
        rows["seed"] = 0
    if "simulation" not in rows.columns:
        rows["simulation"] = rows.groupby(["scenario", "model", "seed"]).cumcount()
    rows["model"] = rows["model"].astype(str)
    rows["scenario"] = rows["scenario"].astype(str)
    for c in METRIC_COLUMNS:
        rows[c] = pd.to_numeric(rows[c], errors="coerce")
    return rows


def _known_first(present: list[str], known: list[str]) -> list[str]:
    """The study's own names in the study's order, then any others in order of appearance."""
    return [k for k in known if k in present] + [p for p in present if p not in known]


def model_order(rows: pd.DataFrame, models: list[str] | None = None) -> list[str]:
    """`models` as given (checked against the rows), or every model in the rows, M0..M5 first."""
    present = list(dict.fromkeys(rows["model"]))
    if models is None:
        return _known_first(present, list(MODELS))
    models = [str(m) for m in models]
    absent = [m for m in models if m not in present]
    if absent:
        raise SigmarlError(
            f"no evaluation rows for model(s) {', '.join(absent)}; "
            f"models with rows: {', '.join(_known_first(present, list(MODELS)))}"
        )
    if len(set(models)) != len(models):
        raise SigmarlError(f"model list names a model twice: {', '.join(models)}")
    return models


def scenario_order(rows: pd.DataFrame) -> list[str]:
    return _known_first(list(dict.fromkeys(rows["scenario"])), list(SCENARIOS))


def trim_collisions(rows: pd.DataFrame) -> pd.DataFrame:
    """Blank the collision rates of each evaluation's best and worst simulation.

    As in the paper, per (scenario, model, seed) the simulation with the lowest and the one
    with the highest CR_total are dropped from all three collision-rate columns (the same
    two simulations, so that CR_total stays CR_AA + CR_AL); ties go to the lower
    simulation index. CD and AS keep every simulation. Evaluations of fewer than three
    simulations are left whole, since trimming would leave nothing to average.
    """
    rows = rows.copy()
    drop: list = []
    for _, g in rows.groupby(["scenario", "model", "seed"], sort=False):
        g = g.dropna(subset=["CR_total"])
        if len(g) < 3:
            continue
        ranked = g.sort_values(["CR_total", "simulation"], kind="stable").index
        drop += [ranked[0], ranked[-1]]
    rows.loc[drop, list(COLLISION_COLUMNS)] = math.nan
    return rows


def aggregate(
    rows: pd.DataFrame,
    models: list[str] | None = None,
    *,
    trim: bool = False,
    level: float = 0.95,
) -> pd.DataFrame:
    """One row per (scenario, model, metric): mean, CI half-width, std, n, per-seed spread.

    Collision rates come in as fractions of steps and go out in percent. Column `ci` is
    the half-width of the `level` t-interval over the pooled simulations; `seed_std` is
    the sample standard deviation of the per-seed means (NaN with one seed).
    """
    rows = validate_rows(rows)
    models = model_order(rows, models)
    rows = rows[rows["model"].isin(models)]
    if trim:
        rows = trim_collisions(rows)
    records = []
    for scenario in scenario_order(rows):
        for model in models:
            g = rows[(rows["scenario"] == scenario) & (rows["model"] == model)]
            if g.empty:
                continue
            for metric in METRIC_COLUMNS:
                values = g[metric] * (100.0 if metric in COLLISION_COLUMNS else 1.0)
                mean, half, std, n = mean_ci(values, level)
                seed_means = values.groupby(g["seed"]).mean().dropna()
                records.append(
                    {
                        "scenario": scenario,
                        "model": model,
                        "metric": metric,
                        "unit": UNITS[metric],
                        "mean": mean,
                        "ci": half,
                        "std": std,
                        "n": n,
                        "n_seeds": len(seed_means),
                        "seed_std": seed_means.std(ddof=1) if len(seed_means) > 1 else math.nan,
                        "trimmed": bool(trim and metric in COLLISION_COLUMNS),
                    }
                )
    return pd.DataFrame(records, columns=SUMMARY_COLUMNS)
