"""Beyond Table I: composite-score intervals, aggregate scores across scenarios, and the
probability that the reference model (M0) has fewer collisions than each other model.

A seed's normalised score in a scenario is the paper's composite score (eq. 2) of that seed's
means, with the scenario's normalisers fixed to the mean over the compared models of the table's
estimates: linear in the seed's means, so its mean over seeds is the table's CS, and its interval
comes from the cells' bootstrap replicates. Aggregates over scenarios (per model): the mean of the
per-scenario scores and rliable's interquartile mean (IQM) of all (scenario, seed) scores. They and
the probability of improvement averaged over scenarios resample whole seeds, since one policy's
scores correlate across scenarios (r 0.69 for M0's seeds, 0.87 for M4's): docs/concepts.md,
"Intervals pooled over scenarios".
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from sigmarl.metrics import COMPOSITE, CS, HEADLINE, METRIC_COLUMNS
from sigmarl.report.cells import Cell, scenario_order, trim_collisions, validate_rows
from sigmarl.report.tables import MISSING, TABLE_DIGITS, interval_text
from sigmarl.stats import bootstrap as bs

_COLS = [METRIC_COLUMNS.index(m) for m in COMPOSITE]
AGGREGATE_COLUMNS = ["model", "statistic", "value", "ci_low", "ci_high", "n_scenarios", "n_runs"]
IMPROVEMENT_COLUMNS = ["scenario", "reference", "model", "metric", "probability", "ci_low", "ci_high",
                       "n_seeds_reference", "n_seeds_model"]
OVERALL = "mean over scenarios"


def score_weights(cell_list: list[Cell], composite: pd.DataFrame) -> dict[str, np.ndarray]:
    """Per scenario with a defined composite score: signed weights on the composite metrics.

    The normalisers are the means over the models that have a score, as in `composite_scores`.
    """
    out = {}
    scored = composite.dropna(subset=[CS])
    for scenario, g in scored.groupby("scenario", sort=False):
        points = np.array([c.point[_COLS] for c in cell_list if c.scenario == scenario and c.model in set(g["model"])])
        out[scenario] = np.array(list(COMPOSITE.values())) / points.mean(0)
    return out


def _seed_scores(values: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Per-seed scores from [..., S, K] seed means."""
    return values[..., _COLS] @ w


def composite_intervals(cell_list: list[Cell], composite: pd.DataFrame, level: float = bs.LEVEL) -> pd.DataFrame:
    """The table's CS per (scenario, model) with its bootstrap interval (NaN where undefined)."""
    weights = score_weights(cell_list, composite)
    cs = composite.set_index(["scenario", "model"])[CS]
    records = []
    for c in cell_list:
        value = cs.get((c.scenario, c.model), np.nan)
        lo = hi = np.nan
        if c.scenario in weights and np.isfinite(value):
            reps = _seed_scores(c.replicates, weights[c.scenario])  # [B, S]
            lo, hi = bs.percentile_interval(bs.mean_over_seeds(reps, -1), level)
        records.append((c.scenario, c.model, value, float(lo), float(hi)))
    return pd.DataFrame(records, columns=["scenario", "model", CS, "ci_low", "ci_high"])


def aggregate_scores(cell_list: list[Cell], composite: pd.DataFrame, models: list[str], level: float = bs.LEVEL,
                     n_boot: int = bs.N_BOOT) -> pd.DataFrame:
    """Per model, over the scenarios where its score is defined: mean and IQM with intervals.

    The intervals resample the model's seeds whole (`bootstrap.whole_seed_groups`), each drawn
    seed bringing its scores on every scenario, and widen the percentile level for the number
    of seeds (`bootstrap.expanded_level`).
    """
    weights = score_weights(cell_list, composite)
    records = []
    for model in models:
        mine = [c for c in cell_list if c.model == model and c.scenario in weights]
        if not mine:
            continue
        points = [_seed_scores(c.seed_means(), weights[c.scenario]) for c in mine]  # [S] each
        # [B, U] each: the union of its seeds, the same drawn in every scenario, their simulations per cell
        reps = bs.whole_seed_replicates([(c.seeds, c.groups) for c in mine], n_boot, bs.rng_for("whole-seed", model),
                                        [bs.rng_for("whole-seed", c.scenario, model) for c in mine])
        reps = [_seed_scores(r, weights[c.scenario]) for c, r in zip(mine, reps, strict=True)]
        runs = np.concatenate(points)
        stats = {
            "mean": (np.mean([p.mean() for p in points]), np.mean([bs.mean_over_seeds(r, -1) for r in reps], axis=0)),
            "IQM": (bs.iqm(runs), bs.iqm(np.concatenate(reps, axis=-1))),
        }
        n = reps[0].shape[-1]
        for name, (value, samples) in stats.items():
            records.append((model, name, float(value), *_interval(samples, bs.expanded_level(level, n), n), len(mine),
                            len(runs)))
    return pd.DataFrame(records, columns=AGGREGATE_COLUMNS)


def _compared(rows: pd.DataFrame, models: list[str], reference: str | None, trim: bool) -> tuple[pd.DataFrame, str]:
    """The checked rows of `models` (trimmed as asked) and the reference: M0, or the first model
    when M0 is absent."""
    rows = validate_rows(rows)
    rows = rows[rows["model"].isin(models)]
    if trim:
        rows = trim_collisions(rows)
    return rows, reference or ("M0" if "M0" in models else models[0])


def improvement(rows: pd.DataFrame, models: list[str], *, reference: str | None = None, metric: str = HEADLINE,
                trim: bool = False, level: float = bs.LEVEL, n_boot: int = bs.N_BOOT) -> pd.DataFrame:
    """Per scenario, P(reference has a lower `metric` than each other model) with an interval.

    The probability compares a simulation of a random seed of each model, ties counting half
    (`bootstrap.probability_of_improvement`); the interval resamples both models' seeds and
    simulations independently. Reference: M0, or the first model when M0 is absent.
    """
    rows, reference = _compared(rows, models, reference, trim)
    groups = _seed_groups(rows, metric)
    records = []
    for scenario in scenario_order(rows):
        for model in models:
            if model == reference or (scenario, reference) not in groups or (scenario, model) not in groups:
                continue
            ref, other = groups[(scenario, reference)][1], groups[(scenario, model)][1]
            samples = bs.bootstrap_improvement(ref, other, n_boot, bs.rng_for("poi", scenario, reference, model,
                                                                              metric, trim))
            records.append((scenario, reference, model, metric, bs.probability_of_improvement(ref, other),
                            *_interval(samples, level, min(len(ref), len(other))), len(ref), len(other)))
    return pd.DataFrame(records, columns=IMPROVEMENT_COLUMNS)


def improvement_overall(rows: pd.DataFrame, models: list[str], *, reference: str | None = None, metric: str = HEADLINE,
                        trim: bool = False, level: float = bs.LEVEL, n_boot: int = bs.N_BOOT) -> pd.DataFrame:
    """Per model, the probability of improvement averaged over the scenarios both models have
    (rliable's over tasks), with an interval that resamples each model's seeds whole.

    Columns as `improvement`'s, scenario "mean over scenarios"; n_seeds_* count the union of
    each model's seeds. The level is widened for the smaller of the two seed counts.
    """
    rows, reference = _compared(rows, models, reference, trim)
    groups = _seed_groups(rows, metric)
    records = []
    for model in models:
        pairs = [(groups[(s, reference)], groups[(s, model)]) for s in scenario_order(rows)
                 if (s, reference) in groups and (s, model) in groups]
        if model == reference or not pairs:
            continue
        seeds_ref, ref = bs.whole_seed_groups([r for r, _ in pairs])
        seeds_other, other = bs.whole_seed_groups([o for _, o in pairs])
        rng = bs.rng_for("poi-overall", reference, model, metric, trim)
        picks = (rng.integers(0, len(seeds_ref), (n_boot, len(seeds_ref))),
                 rng.integers(0, len(seeds_other), (n_boot, len(seeds_other))))
        p = np.mean([bs.probability_of_improvement(x, y) for x, y in zip(ref, other, strict=True)])
        samples = np.mean([bs.bootstrap_improvement(x, y, n_boot, rng, picks)
                           for x, y in zip(ref, other, strict=True)], axis=0)
        n = min(len(seeds_ref), len(seeds_other))
        records.append((OVERALL, reference, model, metric, float(p), *_interval(samples, bs.expanded_level(level, n), n),
                        len(seeds_ref), len(seeds_other)))
    return pd.DataFrame(records, columns=IMPROVEMENT_COLUMNS)


def _interval(samples: np.ndarray, level: float, n_seeds: int) -> tuple[float, float]:
    """The percentile interval; none (NaN) from one seed, which has no seed to resample (a
    simulations-only width is not one)."""
    if n_seeds < 2:
        return math.nan, math.nan
    lo, hi = bs.percentile_interval(samples, level)
    return float(lo), float(hi)


def _seed_groups(rows: pd.DataFrame, metric: str) -> dict[tuple[str, str], tuple[list, list[np.ndarray]]]:
    """(scenario, model) -> its seeds (ascending) with a finite value of `metric`, and per seed
    those values as an [n, 1] array (in simulation order)."""
    out: dict[tuple[str, str], tuple[list, list[np.ndarray]]] = {}
    ordered = rows.sort_values(["seed", "simulation"], kind="stable")
    for (scenario, model, seed), g in ordered.groupby(["scenario", "model", "seed"], sort=True):
        v = g[metric].to_numpy(float)
        v = v[np.isfinite(v)]
        if len(v):
            seeds, values = out.setdefault((scenario, model), ([], []))
            seeds.append(seed)
            values.append(v[:, None])
    return out


def _interval_or_dash(value: float, lo: float, hi: float, digits: int) -> str:
    """`interval_text`, with `[–]` where one seed gave no interval."""
    return interval_text(value, lo, hi, digits) + ("" if math.isfinite(lo) and math.isfinite(hi) else " [–]")


def statistics_markdown(improvement: pd.DataFrame, aggregates: pd.DataFrame, *, trim: bool = False,
                        digits: int = TABLE_DIGITS) -> str:
    """Markdown of `improvement` (scenarios x models) and `aggregate_scores`; `[–]` where one seed
    gave no interval."""
    lines: list[str] = []

    if len(improvement):
        reference, metric = improvement["reference"].iloc[0], improvement["metric"].iloc[0]
        others = list(dict.fromkeys(improvement["model"]))
        cells = improvement.set_index(["scenario", "model"])
        lines += [f"Probability that {reference} has a lower {metric} than each model [95% bootstrap interval]"
                  + (" (collision rates trimmed)" if trim else "") + ":", "",
                  "| Scenario | " + " | ".join(f"{reference} vs {m}" for m in others) + " |",
                  "|---|" + "---:|" * len(others)]
        for scenario in dict.fromkeys(improvement["scenario"]):
            row = [_interval_or_dash(*cells.loc[(scenario, m), ["probability", "ci_low", "ci_high"]], digits)
                   if (scenario, m) in cells.index else MISSING for m in others]
            lines.append(f"| {scenario} | " + " | ".join(row) + " |")
        lines += ["", "A simulation of a random seed of each model is compared; ties count half; "
                  "0.5 means no difference, 1 that the reference always had fewer collisions. "
                  "Per scenario, the interval resamples each model's seeds and simulations; the mean "
                  "over scenarios resamples whole seeds (all scenarios of a seed together) with the "
                  "percentile level widened for the number of seeds.", ""]
    if len(aggregates):
        stats = list(dict.fromkeys(aggregates["statistic"]))
        cells = aggregates.set_index(["model", "statistic"])
        lines += ["Composite score aggregated over scenarios [95% interval, whole seeds resampled]:", "",
                  "| Model | " + " | ".join(stats) + " | scenarios | runs |", "|---|" + "---:|" * (len(stats) + 2)]
        for model in dict.fromkeys(aggregates["model"]):
            row = [_interval_or_dash(*cells.loc[(model, s), ["value", "ci_low", "ci_high"]], digits) for s in stats]
            first = cells.loc[(model, stats[0])]
            lines.append(f"| {model} | " + " | ".join(row) + f" | {int(first['n_scenarios'])} | {int(first['n_runs'])} |")
        lines += ["", "Per-seed composite scores with each scenario's normalisers fixed (their mean over "
                  "seeds is the table's CS); mean: over scenarios; IQM: interquartile mean of all "
                  "(scenario, seed) scores."]
    return "\n".join(lines) + "\n" if lines else ""
