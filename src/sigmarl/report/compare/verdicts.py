"""One verdict per comparison (variant against the baseline, per scenario and metric).

The unit of replication is the seed: a seed's value is its mean over its simulations (in the
table's units: collision rates in %, CD in cm, AS in m/s). For each comparison, with d the
variant's mean of seed means minus the baseline's:

- difference: the comparison engine's two-sided test of d = 0 (`sigmarl.stats.engine`: each
  model resampled from its own seeds under the null, the largest p over its null worlds);
  Welch's p is reported beside it;
- equivalence: the engine's two one-sided tests (TOST) of d <= -margin and d >= margin, whose
  p-value is the larger of the two;
- the p-values of each kind are Holm-adjusted over all the study's comparisons (variants x
  scenarios x metrics), so each kind's family-wise error rate is at most alpha.

Rules, in order:
1. **better** / **worse**: the Holm-adjusted difference p-value is <= alpha; the direction
   comes from the sign of d and the metric's better direction (lower collision rates and CD,
   higher AS);
2. **equivalent within +-margin**: else, the Holm-adjusted TOST p-value is <= alpha;
3. **undecided**: else; then `seeds_needed` is the seeds per side that a power analysis
   (power `power`, true difference = d, variances from the two-level components) says the
   easier of the two decisions needs at Holm's level for the first undecided comparison of
   its kind (alpha / comparisons of that kind not yet decided); `seeds_needed_unadjusted`
   the same at alpha itself.
A comparison with fewer than two seeds on a side has no test (p-values NaN, counted as 1 in
Holm's family) and is undecided.

The interval of d is the engine's (1 - alpha) bootstrap-t interval, unadjusted (Welch's where
a side has one seed or no spread).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from sigmarl.errors import SigmarlError
from sigmarl.metrics import BY_NAME, METRICS, shown_unit
from sigmarl.report.tables import p_text, seeds_text, signed
from sigmarl.stats.engine import comparison_test
from sigmarl.stats.power import seeds_for_difference, seeds_for_equivalence
from sigmarl.stats.tests import Test, holm, verdict
from sigmarl.stats.variance import Components, components

DEFAULT_MARGINS = {m.name: m.margin for m in METRICS}

COLUMNS = [
    "scenario", "metric", "variant", "baseline", "n_variant", "n_baseline", "variant_mean",
    "baseline_mean", "difference", "ci_low", "ci_high", "margin", "p_difference",
    "p_difference_holm", "p_welch", "p_equivalence", "p_equivalence_holm", "verdict", "seeds_needed",
    "seeds_needed_unadjusted", "decision_planned", "seed_share_variant", "seed_share_baseline",
]  # fmt: skip


@dataclass(frozen=True)
class Design:
    """The study's shape, as plain parameters."""

    variants: Sequence[str]  # ordered; the baseline may be among them
    baseline: str = "M0"
    # variant -> the variant it is compared with instead of `baseline` (a factorial study
    # compares within each level of the other factor, e.g. M4-paper with M0-paper, M4 with M0)
    baselines: dict[str, str] = field(default_factory=dict)
    # name -> (x, y): x's comparison with its baseline set against y's (`report.compare.interactions`)
    interactions: dict[str, tuple[str, str]] = field(default_factory=dict)
    scenarios: Sequence[str] | None = None  # None: every scenario in the rows, in order
    metrics: Sequence[str] = ("CR_total",)
    margins: dict[str, float] = field(default_factory=lambda: dict(DEFAULT_MARGINS))
    alpha: float = 0.05
    power: float = 0.8
    max_seeds: int = 10
    slow_seed: float = 0.0  # worst CR_total (%) above which a seed is slow; 0: not declared

    def __post_init__(self):
        unknown = [m for m in self.metrics if m not in BY_NAME]
        if unknown:
            raise SigmarlError(f"no verdicts for metric(s) {', '.join(unknown)}; known: {', '.join(BY_NAME)}")
        missing = [m for m in self.metrics if m not in self.margins]
        if missing:
            raise SigmarlError(f"no equivalence margin for {', '.join(missing)}")
        if not 0 < self.alpha < 1 or not 0 < self.power < 1:
            raise SigmarlError(f"alpha and power must lie in (0, 1), got {self.alpha} and {self.power}")

    def baseline_of(self, variant: str) -> str:
        return self.baselines.get(variant, self.baseline)

    @property
    def compared(self) -> list[str]:
        return [v for v in self.variants if v != self.baseline and self.baseline_of(v) != v]

    @property
    def one_baseline(self) -> bool:
        return all(self.baseline_of(v) == self.baseline for v in self.compared)


def design_of(study, variants: Sequence[str]) -> Design:
    """The verdicts' parameters of a study config (`sigmarl.config.StudyConfig`) for the table's
    columns `variants`: its baseline (or M0, or the first column, when the baseline is absent),
    the variants' own baselines, metrics, margins (over the metrics' own defaults) and seed cap."""
    variants = list(variants)
    baseline = study.baseline if study.baseline in variants else ("M0" if "M0" in variants else variants[0])
    own = {v: b for v, b in dict(study.baselines).items() if v in variants}
    present = {name: (x, y) for name, (x, y) in dict(study.interactions).items()
               if {x, y, own.get(x, baseline), own.get(y, baseline)} <= set(variants)}
    return Design(variants=variants, baseline=baseline, baselines=own, interactions=present,
                  metrics=tuple(study.metrics),
                  margins={**DEFAULT_MARGINS, **dict(study.margins)}, max_seeds=int(study.max_seeds),
                  slow_seed=float(study.slow_seed))


def seed_values(rows: pd.DataFrame, metric: str) -> dict[tuple[str, str], list[np.ndarray]]:
    """(model, scenario) -> per seed (ascending) its finite values of `metric`, in the table's units."""
    scale = BY_NAME[metric].scale
    out: dict[tuple[str, str], list[np.ndarray]] = {}
    ordered = rows.sort_values(["seed", "simulation"], kind="stable")
    for (model, scenario, _), g in ordered.groupby(["model", "scenario", "seed"], sort=False):
        v = g[metric].to_numpy(float) * scale
        v = v[np.isfinite(v)]
        if len(v):
            out.setdefault((str(model), str(scenario)), []).append(v)
    return out


@dataclass(frozen=True)
class Comparison:
    scenario: str
    metric: str
    variant: str
    test: Test
    variant_components: Components | None
    baseline_components: Components | None


def comparisons(rows: pd.DataFrame, design: Design) -> list[Comparison]:
    """Every (scenario, metric, variant) comparison of the design that the rows can make."""
    scenarios = list(design.scenarios) if design.scenarios is not None else list(dict.fromkeys(rows["scenario"]))
    out = []
    for metric in design.metrics:
        values = seed_values(rows, metric)
        for scenario in scenarios:
            for variant in design.compared:
                base = values.get((design.baseline_of(variant), scenario))
                mine = values.get((variant, scenario))
                if not base or not mine:
                    continue
                test = comparison_test(np.array([g.mean() for g in mine]), np.array([g.mean() for g in base]),
                                       design.margins[metric], 1 - design.alpha)
                out.append(Comparison(scenario, metric, variant, test, components(mine), components(base)))
    return out


def decide(
    tests: Sequence[Test], directions: Sequence[int], alpha: float | Sequence[float]
) -> tuple[list[str], np.ndarray, np.ndarray]:
    """The verdict rules 1-3 over a family: verdicts ('better', 'worse', 'equivalent',
    'undecided') and the Holm-adjusted difference and equivalence p-values. `alpha` may be
    one level per comparison (a sequential design's nominal levels)."""
    p_diff = holm([t.p_difference for t in tests])
    p_eq = holm([t.p_equivalence for t in tests])
    levels = np.broadcast_to(np.asarray(alpha, float), (len(tests),))
    verdicts = [verdict(t, sign, pd_, pe, a, a)
                for t, sign, pd_, pe, a in zip(tests, directions, p_diff, p_eq, levels, strict=True)]
    return verdicts, p_diff, p_eq


def plan_seeds(c: Comparison, margin: float, alpha_diff: float, alpha_eq: float, power: float
               ) -> tuple[int | None, str]:
    """Seeds per side the easier decision needs (None: none within reach), and which one."""
    if c.variant_components is None or c.baseline_components is None:
        return None, ""
    va, vb = c.variant_components.seed_mean_variance(), c.baseline_components.seed_mean_variance()
    if math.isnan(va) or math.isnan(vb):  # one seed on a side: no seed-to-seed variance yet
        return None, ""
    d = c.test.difference
    options = [(n, kind) for n, kind in [
        (seeds_for_difference(d, va, vb, alpha_diff, power), "difference"),
        (seeds_for_equivalence(d, va, vb, margin, alpha_eq, power), "equivalence"),
    ] if n is not None]
    return min(options) if options else (None, "")


def verdict_table(rows: pd.DataFrame, design: Design) -> pd.DataFrame:
    """One row per comparison (COLUMNS), scenarios then metrics then variants in order."""
    comps = comparisons(rows, design)
    directions = [BY_NAME[c.metric].direction for c in comps]
    verdicts, p_diff, p_eq = decide([c.test for c in comps], directions, design.alpha)
    m = len(comps)
    open_diff = m - sum(v in ("better", "worse") for v in verdicts)
    open_eq = m - sum(v == "equivalent" for v in verdicts)
    records = []
    for c, decided, pd_, pe in zip(comps, verdicts, p_diff, p_eq, strict=True):
        margin = design.margins[c.metric]
        lo, hi = c.test.interval(1 - design.alpha)
        needed, kind = plan_seeds(c, margin, design.alpha / max(open_diff, 1), design.alpha / max(open_eq, 1),
                                  design.power)
        unadjusted, _ = plan_seeds(c, margin, design.alpha, design.alpha, design.power)
        records.append({
            "scenario": c.scenario, "metric": c.metric, "variant": c.variant, "baseline": design.baseline_of(c.variant),
            "n_variant": c.test.n_variant, "n_baseline": c.test.n_baseline,
            "variant_mean": c.test.variant_mean, "baseline_mean": c.test.baseline_mean,
            "difference": c.test.difference, "ci_low": lo, "ci_high": hi, "margin": margin,
            "p_difference": c.test.p_difference, "p_difference_holm": pd_,
            "p_welch": c.test.p_difference_welch, "p_equivalence": c.test.p_equivalence, "p_equivalence_holm": pe, "verdict": decided,
            "seeds_needed": needed, "seeds_needed_unadjusted": unadjusted, "decision_planned": kind,
            "seed_share_variant": c.variant_components.seed_share,
            "seed_share_baseline": c.baseline_components.seed_share,
        })
    frame = pd.DataFrame(records, columns=COLUMNS)
    for col in ("seeds_needed", "seeds_needed_unadjusted"):
        frame[col] = frame[col].astype("Int64")
    return frame


def margin_unit(metric: str) -> str:
    """The margin's unit: a difference of collision rates is in percentage points."""
    unit = shown_unit(metric)
    return "pp" if unit == "%" else unit


def verdict_label(row: pd.Series) -> str:
    if row["verdict"] == "equivalent":
        return f"equivalent within ±{row['margin']:g} {margin_unit(row['metric'])}"
    return str(row["verdict"])


def verdicts_markdown(table: pd.DataFrame, design: Design) -> str:
    """The verdict table as Markdown, with the rules it applied in its notes."""
    m = len(table)
    against = design.baseline if design.one_baseline else "each model's baseline"
    lines = [
        f"Verdicts against {against} (seed means compared; {m} comparisons, Holm-corrected; "
        f"α = {design.alpha:g}):",
        "",
        "| Scenario | Metric | Model | seeds | difference [95% CI] | p (Holm) | Welch p | p equiv. (Holm) "
        "| verdict | seeds needed at the observed difference (unadj.) |",
        "|---|---|---|---:|---|---:|---:|---:|---|---:|",
    ]
    if abs(design.alpha - 0.05) > 1e-12:
        lines[2] = lines[2].replace("95% CI", f"{100 * (1 - design.alpha):g}% CI")
    for _, r in table.iterrows():
        unit = shown_unit(r["metric"])
        undecided = r["verdict"] == "undecided"
        needed = f"{seeds_text(r['seeds_needed'])} ({seeds_text(r['seeds_needed_unadjusted'])})" if undecided else "–"
        model = r["variant"] if design.one_baseline else f"{r['variant']} vs {r['baseline']}"
        lines.append(
            f"| {r['scenario']} | {r['metric']} ({unit}) | {model} | {r['n_variant']}/{r['n_baseline']} | "
            f"{signed(r['difference'])} [{signed(r['ci_low'])}, {signed(r['ci_high'])}] | {p_text(r['p_difference'])} "
            f"({p_text(r['p_difference_holm'])}) | {p_text(r['p_welch'])} | {p_text(r['p_equivalence'])} ({p_text(r['p_equivalence_holm'])}) | "
            f"{verdict_label(r)} | {needed} |"
        )
    margins = ", ".join(f"{k} ±{design.margins[k]:g} {margin_unit(k)}" for k in design.metrics)
    lines += [
        "",
        f"seeds: the model's / {against}'s. difference: model minus {against}, in the table's "
        "units (pp: percentage points), with the comparison engine's bootstrap-t interval over seed means. "
        "better / worse: the comparison engine's two-sided test of the difference of seed means (each model "
        "resampled from its own seeds under the null; docs/concepts.md), Holm-adjusted p ≤ α; Welch p: "
        "Welch's t-test, reported, not decided on (skewed seeds make it reject too often at few seeds); "
        f"equivalent: the engine's two one-sided tests within the margin ({margins}), Holm-adjusted p ≤ α; "
        "otherwise undecided. seeds needed: seeds per model (and per baseline) for power "
        f"{design.power:g} to reach the easier decision, at Holm's level (at α unadjusted in parentheses), "
        "from the two-level variance of a seed mean (seed-to-seed plus simulations) and the observed "
        "difference, whose interval on the same row says how far off that figure can be: a post-hoc "
        "figure that moves with every seed added. To plan for the difference that matters (the margin), "
        "`sigmarl report --plan`.",
    ]
    return "\n".join(lines) + "\n"
