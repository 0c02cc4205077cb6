"""Seed plans: `sigmarl report --plan` (per comparison the verdict, the difference with the
engine's interval, and the seeds per model the engine's seeds-needed rule asks for the study's
margin δ: to detect a true difference of δ, and to show equivalence within ±δ were the true
difference 0, or the observed one), and `seeds=auto`'s rounds (every comparison decided at this
look by the group-sequential design below, and which variants get one more seed). From the
folder's evaluation rows only. The rule and its limits: docs/concepts.md, "Seeds needed".
"""

from __future__ import annotations

import math
import textwrap
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from functools import lru_cache, partial
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import stats

from sigmarl.errors import SigmarlError
from sigmarl.metrics import BY_NAME
from sigmarl.report.cells import model_order, validate_rows
from sigmarl.report.compare.verdicts import (
    Design,
    comparisons,
    design_of,
    margin_unit,
    seed_values,
    verdict_label,
    verdict_table,
)
from sigmarl.report.tables import signed
from sigmarl.results.folders import read_many, read_results
from sigmarl.stats.bootstrap import components
from sigmarl.stats.engine import Test, holm, seeds_needed, verdict

MAX_SEEDS = 10_000  # beyond this a plan says "more than"
SEED_COLUMNS = ["seeds_detect_margin", "seeds_equivalent_at_zero", "seeds_equivalent_at_observed"]
PLAN_COLUMNS = ["scenario", "metric", "model", "baseline", "seeds", "difference", "ci_low", "ci_high", "verdict",
                *SEED_COLUMNS, "seed_share_model", "seed_share_baseline"]


def plan_table(rows: pd.DataFrame, design: Design) -> pd.DataFrame:
    """One row per comparison of `verdict_table` (PLAN_COLUMNS); seed counts NA where none is
    within MAX_SEEDS, where equivalence cannot be shown (|difference| >= margin), or where a side
    has fewer than two seeds."""
    table = verdict_table(rows, design)
    comps = {(c.scenario, c.metric, c.variant): c for c in comparisons(rows, design)}
    shares = {metric: {k: components(g).seed_share for k, g in seed_values(rows, metric).items()}
              for metric in design.metrics}
    records = []
    for _, r in table.iterrows():
        c = comps[(r["scenario"], r["metric"], r["model"])]
        margin, counts = design.margins[r["metric"]], [None, None, None]
        if min(c.test.n_variant, c.test.n_baseline) >= 2:
            need = partial(seeds_needed, variances=c.variances, weights=(1.0, -1.0), alpha=design.alpha,
                           power_target=design.power, cap=MAX_SEEDS)
            counts = [need(margin), need(0.0, margin=margin), need(c.test.difference, margin=margin)]
        records.append({**{k: r[k] for k in table.columns if k in PLAN_COLUMNS}, **dict(zip(SEED_COLUMNS, counts, strict=True)),
                        "seed_share_model": shares[r["metric"]].get((r["model"], r["scenario"]), math.nan),
                        "seed_share_baseline": shares[r["metric"]].get((r["baseline"], r["scenario"]), math.nan)})
    frame = pd.DataFrame(records, columns=PLAN_COLUMNS)
    for col in SEED_COLUMNS:
        frame[col] = frame[col].astype("Int64")
    return frame


def _seeds(n, possible: bool = True, tested: bool = True) -> str:
    if not tested:
        return "–"
    if not possible:
        return "never"
    return f">{MAX_SEEDS}" if pd.isna(n) else str(int(n))


def _share(x: float) -> str:
    return "–" if not math.isfinite(x) else f"{100 * x:.0f}%"


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
        tested = math.isfinite(r["ci_low"])
        interval = f"[{signed(r['ci_low'])}, {signed(r['ci_high'])}]" if tested else "[–]"
        share = f"{_share(r['seed_share_model'])}/{_share(r['seed_share_baseline'])}"
        possible = abs(r["difference"]) < design.margins[r["metric"]]
        lines.append(
            f"{r['scenario']:<14}{r['metric']:<10}{r['model']:<7}{r['seeds']:<7}"
            f"{signed(r['difference']) + ' ' + interval:<30}{verdict_label(r['verdict'], r['metric'], design):<22}"
            f"{_seeds(r['seeds_detect_margin'], tested=tested):>10}{_seeds(r['seeds_equivalent_at_zero'], tested=tested):>12}"
            f"{_seeds(r['seeds_equivalent_at_observed'], possible, tested):>15}{share:>12}")
    notes = [
        f"verdict, difference (model minus {design.baseline}) and its [{level} interval]: the comparison engine's, as "
        "in verdicts.md (each model resampled from its own seeds under the null; Holm over the study; – with "
        "fewer than 2 seeds a side).",
        f"seeds per model needed (both sides that many) for power {design.power:g} at α {design.alpha:g} per "
        "comparison (Holm over the whole study asks more), by the engine's seeds-needed rule (Welch's t, its "
        "noncentral distribution, at the seed means' variances; checked against the engine's own test by "
        "simulation): detect δ: a two-sided test shows a difference when the true difference is δ; equiv. d=0 / "
        "d=obs.: TOST shows equivalence within ±δ when the true difference is 0 / the observed one (never: "
        f"|observed| ≥ δ); >{MAX_SEEDS}: not within {MAX_SEEDS}.",
        f"seed share: the part of a seed mean's variance that is seed-to-seed (the model's / {design.baseline}'s).",
    ]
    lines += ["", *(textwrap.fill(n, 110, subsequent_indent="  ") for n in notes)]
    return "\n".join(lines) + "\n"


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


# seeds=auto's group-sequential design: looks at n_start..max_seeds seeds a side, a comparison's
# look the smaller of its two sides' counts and its information fraction n / max_seeds; alpha
# spent by Lan and DeMets' O'Brien-Fleming-shaped function, alpha(t) = 2 - 2 Phi(z_(1-a/2) / sqrt(t))
# per side at one-sided level a; boundaries c_k such that, under no effect, the chance to first
# cross at look k is alpha(t_k) - alpha(t_(k-1)), the looks' z being a Brownian motion at t_k
# (crossing probabilities by numerical integration on a grid, as Armitage, McPherson and Rowe).
# A look rejects where a p-value is at most the nominal level of its c_k (two-sided for the
# difference, one-sided for each test of TOST); Holm runs at each look with that level in place
# of alpha, comparisons decided earlier keep their verdict. tests/test_sequential.py simulates it.
_GRID = 2001  # points of the z grid
_SPAN = 10.0  # the grid covers +-_SPAN standard deviations of B(1)


def obrien_fleming_spending(t: float, alpha: float, sides: int = 2) -> float:
    """Cumulative alpha spent by information fraction t (Lan-DeMets, O'Brien-Fleming shape):
    per side, at one-sided level a = alpha / sides, 2 - 2 Phi(z_(1 - a/2) / sqrt(t))."""
    if t <= 0:
        return 0.0
    z = float(stats.norm.ppf(1 - alpha / sides / 2))
    return float(sides * 2 * stats.norm.cdf(-z / math.sqrt(min(t, 1.0))))


def _tail_mass(x: np.ndarray, density: np.ndarray, b: float, sides: int) -> float:
    """Mass of the (sub-)density beyond b (both tails when sides=2), trapezoid, b interpolated."""
    cum = np.concatenate([[0.0], np.cumsum((density[1:] + density[:-1]) / 2 * (x[1] - x[0]))])
    return float(cum[-1] - np.interp(b, x, cum) + (np.interp(-b, x, cum) if sides == 2 else 0.0))


@lru_cache(maxsize=64)
def boundaries(fractions: tuple[float, ...], alpha: float, sides: int = 2) -> tuple[float, ...]:
    """z boundaries c_k at increasing information fractions `fractions` (the last normally 1)
    for a two-sided (sides=2: |Z_k| >= c_k) or one-sided (sides=1: Z_k >= c_k) test."""
    x = np.linspace(-_SPAN, _SPAN, _GRID)  # values of B(t) = sqrt(t) Z
    h = x[1] - x[0]
    density, spent, previous_t, out = None, 0.0, 0.0, []
    for t in fractions:
        dt = t - previous_t
        if density is None:
            density = np.exp(-(x**2) / (2 * t)) / math.sqrt(2 * math.pi * t)
        else:
            offsets = h * np.arange(-(_GRID - 1), _GRID)  # every x_i - x_j
            kernel = np.exp(-(offsets**2) / (2 * dt)) / math.sqrt(2 * math.pi * dt)
            density = np.convolve(density, kernel, mode="full")[_GRID - 1 : 2 * _GRID - 1] * h
        target = obrien_fleming_spending(t, alpha, sides) - spent
        lo, hi = 0.0, float(x[-1])  # the b with tail mass `target` beyond it (bisection)
        for _ in range(100 if target > 0 else 0):
            mid = (lo + hi) / 2
            lo, hi = (mid, hi) if _tail_mass(x, density, mid, sides) > target else (lo, mid)
        b = (lo + hi) / 2 if target > 0 else hi
        out.append(b / math.sqrt(t))
        spent += _tail_mass(x, density, b, sides)
        density = np.where(x >= b if sides == 1 else np.abs(x) >= b, 0.0, density)
        previous_t = t
    return tuple(out)


@lru_cache(maxsize=64)
def nominal_levels(n_start: int, max_seeds: int, alpha: float) -> dict[int, tuple[float, float]]:
    """Seeds per side at a look -> (two-sided level of the difference test, one-sided level
    of each test of TOST)."""
    fractions = tuple(n / max_seeds for n in range(n_start, max_seeds + 1))
    two, one = boundaries(fractions, alpha, 2), boundaries(fractions, alpha, 1)
    return {n: (float(2 * stats.norm.cdf(-a)), float(stats.norm.cdf(-b)))
            for n, a, b in zip(range(n_start, max_seeds + 1), two, one, strict=True)}


def sequential_decide(tests: Sequence[Test], directions: Sequence[int], previous: Sequence[str | None],
                      n_start: int, max_seeds: int, alpha: float
                      ) -> tuple[list[str], np.ndarray, np.ndarray, np.ndarray]:
    """Verdicts at this look: Holm, then `verdict`, with each comparison's nominal levels at its
    look (n = the smaller of its sides' seeds), earlier verdicts kept. Returns verdicts, the
    Holm-adjusted difference and equivalence p-values (NaN for the comparisons decided earlier)
    and each comparison's nominal two-sided level."""
    levels = nominal_levels(n_start, max_seeds, alpha)
    first, last = min(levels), max(levels)
    at = [levels[min(max(min(t.n_variant, t.n_baseline), first), last)] for t in tests]
    prev = [p if p and p != "undecided" else None for p in previous]
    # a comparison decided before is rejected in its family (p = 0) and not in the other (1)
    p_diff = [0.0 if p in ("better", "worse") else 1.0 if p else t.p_difference for t, p in zip(tests, prev, strict=True)]
    p_eq = [0.0 if p == "equivalent" else 1.0 if p else t.p_equivalence for t, p in zip(tests, prev, strict=True)]
    adj_diff, adj_eq = holm(p_diff), holm(p_eq)
    verdicts = [p or verdict(t, sign, ad, ae, a_diff, a_eq)
                for t, sign, p, ad, ae, (a_diff, a_eq) in zip(tests, directions, prev, adj_diff, adj_eq, at, strict=True)]
    before = np.array([p is not None for p in prev])
    return (verdicts, np.where(before, math.nan, adj_diff), np.where(before, math.nan, adj_eq),
            np.array([a[0] for a in at]))


def smallest_permutation_p(n: int) -> float:
    """The smallest two-sided p of an exact permutation test at n against n seeds (the engine's
    pooled world): the observed split and its mirror among C(2n, n)."""
    return 2 / math.comb(2 * n, n)


def first_decidable_look(n_start: int, max_seeds: int, alpha: float, comparisons: int = 1) -> int:
    """The fewest seeds per side, at least n_start, at which a first look can show a difference:
    the smallest permutation p reaches that look's two-sided nominal level divided by
    `comparisons` (Holm's first step). A look before it would only spend alpha. When none can,
    the single look at max_seeds."""
    for n in range(n_start, max_seeds):
        if smallest_permutation_p(n) <= nominal_levels(n, max_seeds, alpha)[n][0] / comparisons:
            return n
    return max_seeds


@dataclass
class Round:
    """What one look decided and what the next round trains."""

    verdicts: pd.DataFrame  # scenario, metric, variant, n_variant, n_baseline, difference, p's, level, verdict
    add: dict[str, int]  # variant (or baseline) -> seeds to add before the next look
    reasons: list[str]  # one line per decision and per seed added, to record with the run
    done: bool  # nothing left to add: all decided, or the cap reached


def key(scenario: str, metric: str, variant: str) -> str:
    return f"{scenario}/{metric}/{variant}"


def next_round(
    rows: pd.DataFrame,
    design: Design,
    n_start: int,
    previous: Mapping[str, str] | None = None,
) -> Round:
    """Decide every comparison at this look and say which seeds the next round adds.

    rows: the evaluation rows so far (model, seed, scenario, simulation, metric columns);
    n_start: the seeds per side at the first look (declared once, before it, and passed
    unchanged at every look); previous: `key(...)` -> verdict of the earlier looks (decided
    comparisons keep theirs). Pure: the caller records the reasons and trains the seeds.
    """
    if not 2 <= n_start <= design.max_seeds:
        raise SigmarlError(f"the first look needs 2 to max_seeds ({design.max_seeds}) seeds per model, got {n_start}")
    comps = comparisons(rows, design)
    tests = [c.test for c in comps]
    keys = [key(c.scenario, c.metric, c.variant) for c in comps]
    earlier = [(previous or {}).get(k) for k in keys]
    verdicts, p_diff, p_eq, levels = sequential_decide(
        tests, [BY_NAME[c.metric].direction for c in comps], earlier, n_start, design.max_seeds, design.alpha)
    frame = pd.DataFrame({
        "scenario": [c.scenario for c in comps], "metric": [c.metric for c in comps],
        "variant": [c.variant for c in comps], "n_variant": [t.n_variant for t in tests],
        "n_baseline": [t.n_baseline for t in tests], "difference": [t.difference for t in tests],
        "p_difference": [t.p_difference for t in tests], "p_difference_holm": p_diff,
        "p_equivalence": [t.p_equivalence for t in tests], "p_equivalence_holm": p_eq,
        "nominal_level": levels, "verdict": verdicts,
    })
    reasons = []
    seeds = rows.groupby("model")["seed"].nunique().to_dict()
    add: dict[str, int] = {}
    for i, (c, v, t, p) in enumerate(zip(comps, verdicts, tests, earlier, strict=True)):
        where = f"{c.variant} vs {design.baseline_of(c.variant)}, {c.scenario}, {c.metric}"
        if p and p != "undecided":
            continue
        if v != "undecided":
            reasons.append(f"{where}: {v} at {t.n_variant}/{t.n_baseline} seeds (difference {t.difference:+.4g}, "
                           f"Holm p {p_diff[i]:.3g}, equivalence p {p_eq[i]:.3g}, nominal level {levels[i]:.3g})")
        elif seeds.get(c.variant, 0) >= design.max_seeds:
            reasons.append(f"{where}: undecided at the cap of {design.max_seeds} seeds")
        else:
            add[c.variant] = 1
    for variant in list(add):
        reasons.append(f"{variant}: one more seed ({seeds.get(variant, 0) + 1}), for its undecided "
                       f"comparison(s): {', '.join(c.scenario + '/' + c.metric for c, v in zip(comps, verdicts, strict=True) if c.variant == variant and v == 'undecided')}")
    for base in dict.fromkeys(design.baseline_of(v) for v in list(add)):
        # a baseline keeps pace with the variants compared with it
        if base not in add and seeds.get(base, 0) <= max(seeds.get(v, 0) for v in add
                                                          if design.baseline_of(v) == base) < design.max_seeds:
            add[base] = 1
            reasons.append(f"{base}: one more seed ({seeds.get(base, 0) + 1}), as the baseline "
                           "of the undecided comparisons")
    return Round(frame, add, reasons, done=not add)
