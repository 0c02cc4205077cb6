"""Beyond Table I: composite-score intervals, aggregate scores across scenarios, and the
probability that the reference model (M0) has fewer collisions than each other model.

Normalised score of one seed of a model in a scenario: the paper's composite score (eq. 2)
of that seed's means, with the scenario's normalisers fixed to the mean over the compared
models of the table's estimates. The score is linear in the seed's means, so the mean over
seeds is exactly the table's CS; its interval comes from the cells' bootstrap replicates.
Aggregates over scenarios (per model): the mean of the per-scenario scores, and the
interquartile mean (IQM) of all (scenario, seed) scores, as rliable reports; their intervals
come from the same replicates, drawn independently per scenario (stratified bootstrap).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from sigmarl.metrics import COMPOSITE, METRIC_COLUMNS
from sigmarl.report.aggregate import Cell, scenario_order, trim_collisions, validate_rows
from sigmarl.stats import bootstrap as bs

_SCORE_SIGNS = COMPOSITE
_COLS = [METRIC_COLUMNS.index(m) for m in _SCORE_SIGNS]
CS_COLUMNS = ["scenario", "model", "CS", "ci_low", "ci_high"]
AGGREGATE_COLUMNS = ["model", "statistic", "value", "ci_low", "ci_high", "n_scenarios", "n_runs"]
IMPROVEMENT_COLUMNS = [
    "scenario", "reference", "model", "metric", "probability", "ci_low", "ci_high", "n_seeds_reference",
    "n_seeds_model",
]  # fmt: skip


def score_weights(cell_list: list[Cell], composite: pd.DataFrame) -> dict[str, np.ndarray]:
    """Per scenario with a defined composite score: signed weights on (CR_total, CD, AS).

    The normalisers are the means over the models that have a score, as in `composite_scores`.
    """
    out = {}
    scored = composite.dropna(subset=["CS"])
    for scenario, g in scored.groupby("scenario", sort=False):
        points = np.array([c.point[_COLS] for c in cell_list if c.scenario == scenario and c.model in set(g["model"])])
        out[scenario] = np.array(list(_SCORE_SIGNS.values())) / points.mean(0)
    return out


def _seed_scores(values: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Per-seed scores from [..., S, K] seed means."""
    return values[..., _COLS] @ w


def composite_intervals(
    cell_list: list[Cell], composite: pd.DataFrame, level: float = bs.LEVEL
) -> pd.DataFrame:
    """The table's CS per (scenario, model) with its bootstrap interval (NaN where undefined)."""
    weights = score_weights(cell_list, composite)
    cs = composite.set_index(["scenario", "model"])["CS"]
    records = []
    for c in cell_list:
        value = cs.get((c.scenario, c.model), np.nan)
        lo = hi = np.nan
        if c.scenario in weights and np.isfinite(value):
            reps = _seed_scores(c.replicates, weights[c.scenario])  # [B, S]
            lo, hi = bs.percentile_interval(bs.mean_over_seeds(reps[..., None])[..., 0], level)
        records.append({"scenario": c.scenario, "model": c.model, "CS": value, "ci_low": float(lo),
                        "ci_high": float(hi)})
    return pd.DataFrame(records, columns=CS_COLUMNS)


def aggregate_scores(
    cell_list: list[Cell], composite: pd.DataFrame, models: list[str], level: float = bs.LEVEL
) -> pd.DataFrame:
    """Per model, over the scenarios where its score is defined: mean and IQM with intervals."""
    weights = score_weights(cell_list, composite)
    records = []
    for model in models:
        mine = [c for c in cell_list if c.model == model and c.scenario in weights]
        if not mine:
            continue
        points = [_seed_scores(c.seed_means(), weights[c.scenario]) for c in mine]  # [S] each
        reps = [_seed_scores(c.replicates, weights[c.scenario]) for c in mine]  # [B, S] each
        runs = np.concatenate(points)
        stats = {
            "mean": (np.mean([p.mean() for p in points]), np.mean([r.mean(-1) for r in reps], axis=0)),
            "IQM": (bs.iqm(runs), bs.iqm(np.concatenate(reps, axis=-1))),
        }
        for name, (value, samples) in stats.items():
            lo, hi = bs.percentile_interval(samples, level)
            records.append({"model": model, "statistic": name, "value": float(value), "ci_low": float(lo),
                            "ci_high": float(hi), "n_scenarios": len(mine), "n_runs": len(runs)})
    return pd.DataFrame(records, columns=AGGREGATE_COLUMNS)


def improvement(
    rows: pd.DataFrame,
    models: list[str],
    *,
    reference: str | None = None,
    metric: str = "CR_total",
    trim: bool = False,
    level: float = bs.LEVEL,
    n_boot: int = bs.N_BOOT,
) -> pd.DataFrame:
    """Per scenario, P(reference has a lower `metric` than each other model) with an interval.

    The probability compares a simulation of a random seed of each model, ties counting half
    (`bootstrap.probability_of_improvement`); the interval resamples both models' seeds and
    simulations independently. Reference: M0, or the first model when M0 is absent.
    """
    rows = validate_rows(rows)
    rows = rows[rows["model"].isin(models)]
    if trim:
        rows = trim_collisions(rows)
    reference = reference or ("M0" if "M0" in models else models[0])
    records = []
    for scenario in scenario_order(rows):
        sc = rows[rows["scenario"] == scenario]
        ref = _groups(sc[sc["model"] == reference], metric)
        if not ref:
            continue
        for model in models:
            other = _groups(sc[sc["model"] == model], metric)
            if model == reference or not other:
                continue
            p = bs.probability_of_improvement(ref, other)
            samples = bs.bootstrap_improvement(ref, other, n_boot, bs.rng_for("poi", scenario, reference, model,
                                                                              metric, trim))
            lo, hi = bs.percentile_interval(samples, level)
            records.append({"scenario": scenario, "reference": reference, "model": model, "metric": metric,
                            "probability": p, "ci_low": float(lo), "ci_high": float(hi),
                            "n_seeds_reference": len(ref), "n_seeds_model": len(other)})
    return pd.DataFrame(records, columns=IMPROVEMENT_COLUMNS)


def _groups(rows: pd.DataFrame, metric: str) -> list[np.ndarray]:
    """Per seed (ascending), its finite values of `metric` as an [n, 1] array."""
    ordered = rows.sort_values(["seed", "simulation"], kind="stable")
    out = []
    for _, g in ordered.groupby("seed", sort=True):
        v = g[metric].to_numpy(float)
        v = v[np.isfinite(v)]
        if len(v):
            out.append(v[:, None])
    return out
