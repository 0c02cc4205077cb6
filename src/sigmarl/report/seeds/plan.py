"""`sigmarl report --from FOLDER --plan`: per comparison the current verdict, the observed
difference with the interval its test gives, and the seeds per model the verdict's test needs
for the effect that matters, the study's margin δ (`sigmarl.stats.planning`): to detect a true
difference of δ, and to show equivalence within ±δ were the true difference 0, or the observed
one. From the folder's evaluation rows only (no MLflow, no figures)."""

from __future__ import annotations

import math
import textwrap
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

from sigmarl.errors import SigmarlError
from sigmarl.report.cells import model_order, validate_rows
from sigmarl.report.compare.verdicts import (
    Design,
    design_of,
    margin_unit,
    seed_values,
    verdict_label,
    verdict_table,
)
from sigmarl.report.inputs import read_many, read_results
from sigmarl.report.tables import signed
from sigmarl.stats import permutation, planning
from sigmarl.stats.power import seeds_for_difference, seeds_for_equivalence

PLAN_COLUMNS = [
    "scenario", "metric", "variant", "baseline", "n_variant", "n_baseline", "difference", "interval_low",
    "interval_high", "margin", "verdict", "seeds_difference_margin", "seeds_equivalence_zero",
    "seeds_equivalence_observed", "seed_share_variant", "seed_share_baseline",
]  # fmt: skip
_SEEDS = ["seeds_difference_margin", "seeds_equivalence_zero", "seeds_equivalence_observed"]


def comparison_seeds(a, b, margin: float, alpha: float, power: float) -> dict[str, int | None]:
    """The three seed counts of one comparison from its seed means (variant a, baseline b), each
    searched from Welch's analytic answer."""
    va, vb = float(np.var(a, ddof=1)), float(np.var(b, ddof=1))
    d = float(np.mean(a) - np.mean(b))
    out = {}
    for col, truth, kind in [("seeds_difference_margin", margin, "difference"),
                             ("seeds_equivalence_zero", 0.0, "equivalence"),
                             ("seeds_equivalence_observed", d, "equivalence")]:
        start = (seeds_for_difference(truth, va, vb, alpha, power) if kind == "difference"
                 else seeds_for_equivalence(truth, va, vb, margin, alpha, power))
        out[col] = planning.seeds_for(a, b, truth, margin, alpha, power, kind, start=start or planning.MAX_SEEDS)
    return out


def plan_table(rows: pd.DataFrame, design: Design) -> pd.DataFrame:
    """One row per comparison of `verdict_table` (PLAN_COLUMNS); seed counts NA where none is
    within planning.MAX_SEEDS, where equivalence cannot be shown (|difference| >= margin), or
    where a side has fewer than two seeds."""
    table = verdict_table(rows, design)
    means = {metric: {key: np.array([g.mean() for g in groups]) for key, groups in seed_values(rows, metric).items()}
             for metric in design.metrics}
    records = []
    for _, r in table.iterrows():
        a = means[r["metric"]][(r["variant"], r["scenario"])]
        b = means[r["metric"]][(r["baseline"], r["scenario"])]
        low = high = math.nan
        seeds = dict.fromkeys(_SEEDS)
        if len(a) >= 2 and len(b) >= 2:
            low, high = planning.shift_interval(a, b, 1 - design.alpha)
            seeds = comparison_seeds(a, b, r["margin"], design.alpha, design.power)
        records.append({**{c: r[c] for c in PLAN_COLUMNS if c in table.columns},
                        "interval_low": low, "interval_high": high, **seeds})
    frame = pd.DataFrame(records, columns=PLAN_COLUMNS)
    for col in _SEEDS:
        frame[col] = frame[col].astype("Int64")
    return frame


def _seeds(n, possible: bool = True, tested: bool = True) -> str:
    if not tested:
        return "–"
    if not possible:
        return "never"
    return f">{planning.MAX_SEEDS}" if pd.isna(n) else str(int(n))


def _end(x: float) -> str:
    return ("+∞" if x > 0 else "-∞") if math.isinf(x) else signed(x)


def _interval(r: pd.Series) -> str:
    if pd.isna(r["interval_low"]):
        return f"{signed(r['difference'])} [–]"
    return f"{signed(r['difference'])} [{_end(r['interval_low'])}, {_end(r['interval_high'])}]"


def plan_text(table: pd.DataFrame, design: Design) -> str:
    """`sigmarl report --plan`: per comparison its verdict, difference [interval], the seeds
    per model for the study's margin and the share of a seed mean's variance that is seed-to-seed."""
    margins = ", ".join(f"{k} ±{design.margins[k]:g} {margin_unit(k)}" for k in design.metrics)
    level = f"{100 * (1 - design.alpha):g}%"
    lines = [
        f"Seed plan against {design.baseline} (margin δ: {margins}; power {design.power:g} at α {design.alpha:g}; "
        f"verdicts Holm over {len(table)} comparisons):",
        "",
        f"{'':<88}{'seeds per model needed':^37}".rstrip(),
        f"{'scenario':<14}{'metric':<10}{'model':<7}{'seeds':<7}{f'difference [{level} interval]':<30}"
        f"{'verdict':<22}{'detect δ':>10}{'equiv. d=0':>12}{'equiv. d=obs.':>15}{'seed share':>12}",
    ]
    for _, r in table.iterrows():
        tested = not pd.isna(r["interval_low"])
        share = f"{_share(r['seed_share_variant'])}/{_share(r['seed_share_baseline'])}"
        lines.append(
            f"{r['scenario']:<14}{r['metric']:<10}{r['variant']:<7}{f'{r.n_variant}/{r.n_baseline}':<7}"
            f"{_interval(r):<30}{verdict_label(r):<22}"
            f"{_seeds(r['seeds_difference_margin'], tested=tested):>10}"
            f"{_seeds(r['seeds_equivalence_zero'], tested=tested):>12}"
            f"{_seeds(r['seeds_equivalence_observed'], abs(r['difference']) < r['margin'], tested):>15}{share:>12}"
        )
    notes = [
        f"difference: model minus {design.baseline}; [{level} interval]: the shifts of the model's seed means that "
        "the verdict's permutation test does not reject at α (unadjusted; ∞ where so few seeds cannot reject).",
        "seeds per model needed (both sides that many) for power "
        f"{design.power:g} at α {design.alpha:g} per comparison (Holm over the whole study asks more). "
        "detect δ: the permutation test shows a difference when the true difference is δ; "
        "equiv. d=0 / d=obs.: TOST shows equivalence within ±δ when the true difference is 0 / the observed one "
        "(never: |observed| ≥ δ).",
        f"Simulated, not Welch's formula: {planning.SIMULATIONS} datasets per n drawn from each model's "
        "centred seed means (bootstrap), shifted to the true difference, each tested by the verdict's "
        f"permutation tests with {planning.DRAWS} random splits (exact up to {planning.DRAWS} splits; the verdict "
        f"itself is exact up to {permutation.EXACT_LIMIT:,} splits, else draws {permutation.DRAWS:,}); n by "
        f"doubling then bisection to {100 * planning.RELATIVE:g} %, up to {planning.MAX_SEEDS}; fixed seeds.",
        f"seed share: the part of a seed mean's variance that is seed-to-seed (the model's / {design.baseline}'s).",
    ]
    lines += ["", *(textwrap.fill(n, 110, subsequent_indent="  ") for n in notes)]
    return "\n".join(lines) + "\n"


def _share(x: float) -> str:
    return "–" if not math.isfinite(x) else f"{100 * x:.0f}%"


def plan_from_folder(root: Path | list[Path], models: list[str] | None = None, baseline: str | None = None,
                     study=None) -> str:
    """The seed plan of the results folder(s) `root` (models: default all, in the study's order;
    baseline: default the study's, else M0, or the first model; study: its metrics and margins)."""
    roots = [Path(r) for r in (root if isinstance(root, list) else [root])]
    rows = validate_rows((read_results(roots[0]) if len(roots) == 1 else read_many(roots)).rows)
    models = model_order(rows, models, list(study.variants) if study is not None and study.variants else None)
    if study is not None and baseline is None and study.baseline in models:
        baseline = study.baseline
    baseline = baseline or ("M0" if "M0" in models else models[0])
    if baseline not in models or len(models) < 2:
        raise SigmarlError(f"a plan compares other models with the baseline {baseline}; the models chosen "
                           f"from {', '.join(map(str, roots))} are {', '.join(models)}")
    design = replace(design_of(study, models), baseline=baseline) if study is not None \
        else Design(variants=models, baseline=baseline)
    return plan_text(plan_table(rows, design), design)
