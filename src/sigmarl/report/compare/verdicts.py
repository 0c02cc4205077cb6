"""Comparisons decided by the comparison engine (`sigmarl.stats.engine`; docs/concepts.md, Verdicts),
read as tables: each variant against its baseline (`verdict_table`), a factorial study's
interactions (`interaction_table`), and the findings in sentences (`findings_markdown`).

Per comparison, d is the variant's mean of seed means minus its baseline's: **better** / **worse**
where the engine's two-sided p of d = 0, Holm-adjusted over the study (variants x scenarios x
metrics), is <= alpha, the direction from d's sign and the metric's; else **equivalent within
+-margin** where its two one-sided tests' p, Holm-adjusted, is; else **undecided** (always with
fewer than 2 seeds a side: no test, p = 1 in Holm's family). `seeds_needed`: the engine's rule
(Welch's t) for the easier decision at Holm's level of the comparisons still open. The interval of
d: the engine's (1 - alpha) bootstrap-t interval, unadjusted.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from sigmarl.errors import SigmarlError
from sigmarl.metrics import AS, BY_NAME, CR_TOTAL, HEADLINE, METRICS, label, shown_unit
from sigmarl.report.tables import interval_signed, markdown_table, p_text, seeds_text, signed
from sigmarl.stats.engine import (
    Null,
    Test,
    comparison_test,
    holm,
    interaction,
    seeds_needed,
    verdict,
)

DEFAULT_MARGINS = {m.name: m.margin for m in METRICS}

COLUMNS = ["scenario", "metric", "model", "baseline", "seeds", "difference", "ci_low", "ci_high", "p_difference",
           "p_difference_holm", "p_equivalent_holm", "verdict", "seeds_needed"]


@dataclass(frozen=True)
class Design:
    """The study's shape, as plain parameters."""

    variants: Sequence[str]  # ordered; the baseline may be among them
    baseline: str = "M0"
    # variant -> the variant it is compared with instead of `baseline` (a factorial study
    # compares within each level of the other factor, e.g. M4-paper with M0-paper, M4 with M0)
    baselines: dict[str, str] = field(default_factory=dict)
    # name -> (x, y): x's comparison with its baseline set against y's (`interaction_table`)
    interactions: dict[str, tuple[str, str]] = field(default_factory=dict)
    scenarios: Sequence[str] | None = None  # None: every scenario in the rows, in order
    metrics: Sequence[str] = (HEADLINE,)
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

    def scenarios_of(self, rows: pd.DataFrame) -> list[str]:
        return list(self.scenarios) if self.scenarios is not None else list(dict.fromkeys(rows["scenario"]))


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


def seed_means(rows: pd.DataFrame, metric: str) -> dict[tuple[str, str], np.ndarray]:
    """(model, scenario) -> its seeds' means of `metric` (`seed_values`)."""
    return {k: np.array([g.mean() for g in v]) for k, v in seed_values(rows, metric).items()}


@dataclass(frozen=True)
class Comparison:
    scenario: str
    metric: str
    variant: str
    test: Test
    variances: tuple[float, float]  # of the variant's and the baseline's seed means (NaN: one seed)


def comparisons(rows: pd.DataFrame, design: Design) -> list[Comparison]:
    """Every (scenario, metric, variant) comparison of the design that the rows can make."""
    out = []
    for metric in design.metrics:
        values = seed_means(rows, metric)
        for scenario in design.scenarios_of(rows):
            for variant in design.compared:
                a, b = values.get((variant, scenario)), values.get((design.baseline_of(variant), scenario))
                if a is None or b is None:
                    continue
                test = comparison_test(a, b, design.margins[metric], 1 - design.alpha)
                variances = tuple(float(np.var(x, ddof=1)) if len(x) > 1 else math.nan for x in (a, b))
                out.append(Comparison(scenario, metric, variant, test, variances))
    return out


def decide(tests: Sequence[Test], directions: Sequence[int],
           alpha: float | Sequence[float]) -> tuple[list[str], np.ndarray, np.ndarray]:
    """The verdict rules over a family: verdicts ('better', 'worse', 'equivalent',
    'undecided') and the Holm-adjusted difference and equivalence p-values. `alpha` may be
    one level per comparison (a sequential design's nominal levels)."""
    p_diff = holm([t.p_difference for t in tests])
    p_eq = holm([t.p_equivalence for t in tests])
    levels = np.broadcast_to(np.asarray(alpha, float), (len(tests),))
    verdicts = [verdict(t, sign, pd_, pe, a, a)
                for t, sign, pd_, pe, a in zip(tests, directions, p_diff, p_eq, levels, strict=True)]
    return verdicts, p_diff, p_eq


def plan_seeds(c: Comparison, margin: float, alpha_diff: float, alpha_eq: float, power: float) -> int | None:
    """Seeds per side the easier decision needs by the engine's rule (None: none within reach)."""
    if min(c.test.n_variant, c.test.n_baseline) < 2:
        return None
    d, w = c.test.difference, (1.0, -1.0)
    options = [n for n in (seeds_needed(d, c.variances, w, alpha_diff, power),
                           seeds_needed(d, c.variances, w, alpha_eq, power, margin=margin)) if n is not None]
    return min(options) if options else None


def verdict_table(rows: pd.DataFrame, design: Design) -> pd.DataFrame:
    """One row per comparison (COLUMNS), scenarios then metrics then variants in order."""
    comps = comparisons(rows, design)
    verdicts, p_diff, p_eq = decide([c.test for c in comps], [BY_NAME[c.metric].direction for c in comps],
                                    design.alpha)
    open_diff = max(len(comps) - sum(v in ("better", "worse") for v in verdicts), 1)
    open_eq = max(len(comps) - sum(v == "equivalent" for v in verdicts), 1)
    records = []
    for c, decided, pd_, pe in zip(comps, verdicts, p_diff, p_eq, strict=True):
        lo, hi = c.test.interval(1 - design.alpha)
        needed = plan_seeds(c, design.margins[c.metric], design.alpha / open_diff, design.alpha / open_eq,
                            design.power) if decided == "undecided" else None
        records.append({
            "scenario": c.scenario, "metric": c.metric, "model": c.variant, "baseline": design.baseline_of(c.variant),
            "seeds": f"{c.test.n_variant}/{c.test.n_baseline}", "difference": c.test.difference, "ci_low": lo,
            "ci_high": hi, "p_difference": c.test.p_difference, "p_difference_holm": pd_, "p_equivalent_holm": pe,
            "verdict": decided, "seeds_needed": needed})
    frame = pd.DataFrame(records, columns=COLUMNS)
    frame["seeds_needed"] = frame["seeds_needed"].astype("Int64")
    return frame


def margin_unit(metric: str) -> str:
    """The margin's unit: a difference of collision rates is in percentage points."""
    unit = shown_unit(metric)
    return "pp" if unit == "%" else unit


def within(metric: str, design: Design) -> str:
    return f"within ±{design.margins[metric]:g} {margin_unit(metric)}"


def verdict_label(verdict_: str, metric: str, design: Design) -> str:
    return f"equivalent {within(metric, design)}" if verdict_ == "equivalent" else str(verdict_)


def _metric(r: dict) -> str:
    return f"{r['metric']} ({shown_unit(r['metric'])})"


def _difference(r: dict) -> str:
    return interval_signed(r["difference"], r["ci_low"], r["ci_high"])


def verdicts_markdown(table: pd.DataFrame, design: Design) -> str:
    """The verdict table as Markdown, with the rules it applied in its notes."""
    against = design.baseline if design.one_baseline else "each model's baseline"
    margins = ", ".join(f"{k} ±{design.margins[k]:g} {margin_unit(k)}" for k in design.metrics)
    lines = [f"Verdicts against {against} (seed means compared; {len(table)} comparisons, Holm-corrected; "
             f"α = {design.alpha:g}):", "", *markdown_table(table, {
                 "Scenario": "scenario", "Metric": _metric,
                 "Model": lambda r: r["model"] if design.one_baseline else f"{r['model']} vs {r['baseline']}",
                 "seeds": "seeds", f"difference [{100 * (1 - design.alpha):g}% CI]": _difference,
                 "p (Holm)": lambda r: f"{p_text(r['p_difference'])} ({p_text(r['p_difference_holm'])})",
                 "p equiv. (Holm)": lambda r: p_text(r["p_equivalent_holm"]),
                 "verdict": lambda r: verdict_label(r["verdict"], r["metric"], design),
                 "seeds needed": lambda r: seeds_text(r["seeds_needed"]) if r["verdict"] == "undecided" else "–"},
                 "lllrlrrlr"), "",
             f"seeds: the model's / {against}'s. difference: model minus {against}, in the table's units (pp: "
             "percentage points), with the comparison engine's bootstrap-t interval over seed means (– with one seed "
             "a side). better / worse: the engine's two-sided test of the difference of seed means (each model "
             f"resampled from its own seeds under the null; docs/concepts.md), Holm-adjusted p ≤ α; equivalent: its "
             f"two one-sided tests within the margin ({margins}), Holm-adjusted p ≤ α; otherwise undecided (always "
             "with fewer than 2 seeds a side). p-values: Monte Carlo error under 0.0005, except where a p lies 4 such "
             "errors above α (there at most 0.0023; it decides nothing). seeds needed: seeds per model (and per "
             f"baseline) at which the engine's rule (Welch's t) reaches power {design.power:g} for the easier decision at "
             "Holm's level, at the observed difference: a post-hoc figure that moves with every seed added; to plan "
             "for the margin, `sigmarl report --plan`."]
    return "\n".join(lines) + "\n"


# Interactions of a factorial study (`study.interactions`: name -> [x, y]): x against its baseline
# set against y against its own, (x - bx) - (y - by) over the seed means of four independent groups
# (`engine.interaction`), in a Holm family of their own (every interaction, scenario and metric).
INTERACTION_COLUMNS = ["scenario", "metric", "interaction", "seeds", "x_difference", "y_difference", "difference",
                       "ci_low", "ci_high", "p_difference", "p_difference_holm", "p_same_holm", "verdict"]


def interaction_table(rows: pd.DataFrame, design: Design) -> pd.DataFrame:
    """One row per (scenario, metric, interaction) the rows can make, in that order: **differs**
    where a zero interaction is rejected, **same** within the metric's margin, else **undecided**;
    `seeds`: the groups' x / its baseline / y / its baseline."""
    records = []
    for metric in design.metrics:
        values = seed_means(rows, metric)
        margin = design.margins[metric]
        for scenario in design.scenarios_of(rows):
            for name, (x, y) in design.interactions.items():
                groups = [values.get((m, scenario)) for m in (x, design.baseline_of(x), y, design.baseline_of(y))]
                if any(g is None for g in groups):
                    continue
                r = interaction(*groups, {"zero": Null(0.0), "above": Null(-margin, "greater"),
                                          "below": Null(margin, "less")}, 1 - design.alpha)
                records.append({
                    "scenario": scenario, "metric": metric, "interaction": name,
                    "seeds": "/".join(str(len(g)) for g in groups), "x_difference": groups[0].mean() - groups[1].mean(),
                    "y_difference": groups[2].mean() - groups[3].mean(), "difference": r.estimate, "ci_low": r.ci_low,
                    "ci_high": r.ci_high, "p_difference": r.p["zero"], "p_same": max(r.p["above"], r.p["below"])})
    frame = pd.DataFrame(records, columns=[*INTERACTION_COLUMNS, "p_same"])
    if len(frame):
        frame["p_difference_holm"] = holm(frame["p_difference"].to_numpy())
        frame["p_same_holm"] = holm(frame["p_same"].to_numpy())
        frame["verdict"] = [
            "differs" if pd_ <= design.alpha else "same" if pe <= design.alpha else "undecided"
            for pd_, pe in zip(np.nan_to_num(frame["p_difference_holm"], nan=1.0),
                               np.nan_to_num(frame["p_same_holm"], nan=1.0), strict=True)]
    return frame[INTERACTION_COLUMNS]


def interactions_markdown(table: pd.DataFrame, design: Design) -> str:
    def side(r: dict, k: int) -> str:
        v = design.interactions[r["interaction"]][k]
        return f"{v} − {design.baseline_of(v)}: {signed(r[('x_difference', 'y_difference')[k]])}"

    lines = [f"Interactions: does a comparison change between the two levels? (difference of differences; "
             f"{len(table)} tests, Holm-corrected; α = {design.alpha:g}):", "", *markdown_table(table, {
                 "Scenario": "scenario", "Metric": _metric, "Interaction": "interaction",
                 "first difference": lambda r: side(r, 0), "second difference": lambda r: side(r, 1),
                 "difference of differences [95% CI]": _difference,
                 "p (Holm)": lambda r: f"{p_text(r['p_difference'])} ({p_text(r['p_difference_holm'])})",
                 "p same (Holm)": lambda r: p_text(r["p_same_holm"]),
                 "verdict": lambda r: f"same {within(r['metric'], design)}" if r["verdict"] == "same" else r["verdict"]},
                 "llllllrrl"), "",
             "difference of differences: the first minus the second, over the seed means of the four groups, with "
             "the comparison engine's bootstrap-t interval (each group resampled from its own seeds; "
             "docs/concepts.md). differs: a zero interaction rejected at Holm's level; same: two one-sided tests "
             "within the metric's margin; otherwise undecided (always with fewer than 2 seeds in a group)."]
    return "\n".join(lines) + "\n"


# findings.md: what a study found, in sentences built from its own numbers (a results page quotes
# it verbatim between markers, scripts/results_blocks.py).
def _join(names: list[str]) -> str:
    """"A", "A and B", "A, B and C"."""
    return names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]


def _baseline_sentence(summary: pd.DataFrame, baseline: str, n_scenarios: int) -> str:
    """The baseline's worst and best CR_total over the scenarios, and its speed range."""
    mine = summary[summary["model"] == baseline].set_index(["metric", "scenario"])["mean"]
    if CR_TOTAL not in mine.index.get_level_values(0):
        return ""
    total = mine[CR_TOTAL]
    text = (f" {baseline}'s total collision rate is at most {total.max():.2f} % on each of the "
            f"{n_scenarios} scenarios (worst: {total.idxmax()}, best: {total.idxmin()} at {total.min():.2f} %)")
    if AS in mine.index.get_level_values(0):
        text += f", at an average speed of {mine[AS].min():.2f}–{mine[AS].max():.2f} m/s"
    return text + "."


def _verdict_sentences(verdicts: pd.DataFrame, n_scenarios: int) -> list[str]:
    """Per variant and metric: the scenarios of each verdict, "on every scenario" when all agree."""
    out = []
    for (metric, variant), g in verdicts.groupby(["metric", "model"], sort=False):
        parts = [f"{decided} " + ("on every scenario" if len(where) == n_scenarios else "on " + _join(list(where)))
                 for decided, where in g.groupby("verdict", sort=False)["scenario"]]
        mine, base = str(g["seeds"].iloc[0]).split("/")
        out.append(f"- {variant} against {g['baseline'].iloc[0]} ({label(metric)}, {mine} "
                   f"against {base} seeds): {'; '.join(parts)}.")
    return out


def findings_markdown(summary: pd.DataFrame, verdicts: pd.DataFrame | None, models: list[str],
                      baseline: str | None, alpha: float = 0.05) -> str:
    """The findings as Markdown: the seeds behind each model and the baseline's figures in a
    paragraph, then one line per compared variant and metric."""
    n_scenarios = summary["scenario"].nunique()
    seeds = summary.groupby("model")["n_seeds"].max()
    text = f"Seeds per model: {', '.join(f'{m} {int(seeds[m])}' for m in models if m in seeds.index)}."
    text += (_baseline_sentence(summary, baseline, n_scenarios) if baseline is not None else "") + "\n"
    if verdicts is not None and len(verdicts):
        text += ("\nVerdicts (the comparison engine's two-sided tests of the difference of seed means, "
                 f"Holm-adjusted across all {len(verdicts)} comparisons, α = {alpha:g}):\n\n"
                 + "\n".join(_verdict_sentences(verdicts, n_scenarios)) + "\n")
    return text
