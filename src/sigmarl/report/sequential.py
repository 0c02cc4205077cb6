"""Seeds added where they decide something, with the error of repeated looks controlled.

`seeds=auto` runs in rounds: after each round every comparison is decided again, and each
variant with an undecided comparison gets one more seed (the baseline too, when it has no
more seeds than such a variant would). Looking again after every round and stopping at
the first significant result would inflate the error rates (with 8 looks at 5 % each, a
no-difference comparison is called better or worse far more often than 5 % of the time).

The design, declared before the first look:
- looks at n = n_start, n_start + 1, ..., max_seeds seeds per side; a comparison's look is
  the smaller of its two sides' seed counts, and its information fraction n / max_seeds;
- an alpha-spending function of Lan and DeMets with the O'Brien-Fleming shape,
  alpha(t) = 2 - 2 Phi(z_(1 - a/2) / sqrt(t)) per side at one-sided level a, spends little at the early looks and
  nearly all of alpha at the last;
- the boundaries c_1..c_K of the z statistic are such that under no effect the chance to
  first cross at look k is alpha(t_k) - alpha(t_(k-1)) (the z statistics at successive looks
  are those of a Brownian motion at times t_k; the crossing probabilities are computed by
  numerical integration on a grid, as Armitage, McPherson and Rowe did);
- at look k, a test rejects when its p-value is at most the nominal level of c_k (two-sided
  2 (1 - Phi(c_k)) for the difference, one-sided 1 - Phi(c_k) for each test of TOST, whose
  own spending is one-sided); the t tests' p-values are compared with these levels;
- Holm's procedure runs at each look with the look's nominal level in place of alpha, over
  all comparisons of the study: comparisons decided at an earlier look keep their verdict
  and count as rejected in their own family and as not rejected in the other;
- at the last look (n = max_seeds) what is still undecided stays undecided.

`tests/test_sequential.py` simulates the procedure on data whose truth is set and checks
that it calls equal variants different, and variants further apart than the margin
equivalent, at most 5 % of the time, while the same rounds without the correction do not.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import pandas as pd

from sigmarl.errors import SigmarlError
from sigmarl.metrics import BY_NAME
from sigmarl.report.tdist import normal_cdf, normal_ppf
from sigmarl.report.verdicts import Design, Test, comparisons, holm, verdict

_GRID = 2001  # points of the z grid
_SPAN = 10.0  # the grid covers +-_SPAN standard deviations of B(1)


def obrien_fleming_spending(t: float, alpha: float, sides: int = 2) -> float:
    """Cumulative alpha spent by information fraction t (Lan-DeMets, O'Brien-Fleming shape):
    per side, at one-sided level a = alpha / sides, 2 - 2 Phi(z_(1 - a/2) / sqrt(t))."""
    if t <= 0:
        return 0.0
    z = normal_ppf(1 - alpha / sides / 2)
    return float(sides * 2 * normal_cdf(-z / math.sqrt(min(t, 1.0))))


@lru_cache(maxsize=64)
def boundaries(fractions: tuple[float, ...], alpha: float, sides: int = 2) -> tuple[float, ...]:
    """z boundaries c_k at increasing information fractions `fractions` (the last normally 1)
    for a two-sided (sides=2: |Z_k| >= c_k) or one-sided (sides=1: Z_k >= c_k) test."""
    x = np.linspace(-_SPAN, _SPAN, _GRID)  # values of B(t) = sqrt(t) Z
    h = x[1] - x[0]
    density = None
    spent = 0.0
    out = []
    previous_t = 0.0
    for t in fractions:
        dt = t - previous_t
        if density is None:
            density = np.exp(-(x**2) / (2 * t)) / math.sqrt(2 * math.pi * t)
        else:
            offsets = h * np.arange(-(_GRID - 1), _GRID)  # every x_i - x_j
            kernel = np.exp(-(offsets**2) / (2 * dt)) / math.sqrt(2 * math.pi * dt)
            density = np.convolve(density, kernel, mode="full")[_GRID - 1 : 2 * _GRID - 1] * h
        target = obrien_fleming_spending(t, alpha, sides) - spent
        c = _crossing_boundary(x, density, target, sides) / math.sqrt(t)
        out.append(c)
        crossed = x >= c * math.sqrt(t) if sides == 1 else np.abs(x) >= c * math.sqrt(t)
        spent += float(_tail_mass(x, density, c * math.sqrt(t), sides))
        density = np.where(crossed, 0.0, density)
        previous_t = t
    return tuple(out)


def _tail_mass(x: np.ndarray, density: np.ndarray, b: float, sides: int) -> float:
    """Mass of the (sub-)density beyond b (both tails when sides=2), trapezoid with the
    partial cell at b interpolated."""
    cum = np.concatenate([[0.0], np.cumsum((density[1:] + density[:-1]) / 2 * (x[1] - x[0]))])
    total = cum[-1]
    upper = total - np.interp(b, x, cum)
    lower = np.interp(-b, x, cum) if sides == 2 else 0.0
    return float(upper + lower)


def _crossing_boundary(x: np.ndarray, density: np.ndarray, target: float, sides: int) -> float:
    """The b with tail mass `target` beyond it (bisection; the mass falls as b rises)."""
    lo, hi = 0.0, float(x[-1])
    if target <= 0:
        return hi
    for _ in range(100):
        mid = (lo + hi) / 2
        if _tail_mass(x, density, mid, sides) > target:
            lo = mid
        else:
            hi = mid
    return (lo + hi) / 2


def look_fractions(n_start: int, max_seeds: int) -> tuple[float, ...]:
    return tuple(n / max_seeds for n in range(n_start, max_seeds + 1))


@lru_cache(maxsize=64)
def nominal_levels(n_start: int, max_seeds: int, alpha: float) -> dict[int, tuple[float, float]]:
    """Seeds per side at a look -> (two-sided level of the difference test, one-sided level
    of each test of TOST)."""
    fractions = look_fractions(n_start, max_seeds)
    two = boundaries(fractions, alpha, 2)
    one = boundaries(fractions, alpha, 1)
    return {n: (float(2 * normal_cdf(-a)), float(normal_cdf(-b)))
            for n, a, b in zip(range(n_start, max_seeds + 1), two, one, strict=True)}


def sequential_decide(
    tests: Sequence[Test],
    directions: Sequence[int],
    previous: Sequence[str | None],
    n_start: int,
    max_seeds: int,
    alpha: float,
) -> tuple[list[str], np.ndarray, np.ndarray, np.ndarray]:
    """Verdicts at this look: the rules of `verdicts.decide` with each comparison's nominal
    levels at its look (n = the smaller of its sides' seeds), earlier verdicts kept.

    Returns verdicts, the Holm-adjusted difference and equivalence p-values (NaN for the
    comparisons decided earlier) and each comparison's nominal two-sided level."""
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
    decided_before = np.array([p is not None for p in prev])
    return (verdicts, np.where(decided_before, math.nan, adj_diff), np.where(decided_before, math.nan, adj_eq),
            np.array([a[0] for a in at]))


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
    previous = dict(previous or {})
    comps = comparisons(rows, design)
    tests = [c.test for c in comps]
    directions = [BY_NAME[c.metric].direction for c in comps]
    keys = [key(c.scenario, c.metric, c.variant) for c in comps]
    verdicts, p_diff, p_eq, levels = sequential_decide(
        tests, directions, [previous.get(k) for k in keys], n_start, design.max_seeds, design.alpha
    )
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
    for k, c, v, t, p in zip(keys, comps, verdicts, tests, previous_list(previous, keys), strict=True):
        where = f"{c.variant} vs {design.baseline_of(c.variant)}, {c.scenario}, {c.metric}"
        if p:
            continue
        if v != "undecided":
            reasons.append(f"{where}: {v} at {t.n_variant}/{t.n_baseline} seeds "
                           f"(difference {t.difference:+.4g}, Holm p {p_diff[keys.index(k)]:.3g}, "
                           f"equivalence p {p_eq[keys.index(k)]:.3g}, nominal level {levels[keys.index(k)]:.3g})")
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


def previous_list(previous: Mapping[str, str], keys: Sequence[str]) -> list[str | None]:
    return [previous.get(k) if previous.get(k) not in (None, "undecided") else None for k in keys]
