"""Seeds added where they decide something, with the error of repeated looks controlled.

A study that adds seeds runs in rounds: after each round every comparison is decided again, and each
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

tests/test_sequential.py simulates the procedure on data whose truth is set and checks
that it calls equal variants different, and variants further apart than the margin
equivalent, at most 5 % of the time, while the same rounds without the correction do not.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from functools import lru_cache

import numpy as np
from scipy import stats

from sigmarl.stats.tests import Test, holm, verdict

_GRID = 2001  # points of the z grid
_SPAN = 10.0  # the grid covers +-_SPAN standard deviations of B(1)


def obrien_fleming_spending(t: float, alpha: float, sides: int = 2) -> float:
    """Cumulative alpha spent by information fraction t (Lan-DeMets, O'Brien-Fleming shape):
    per side, at one-sided level a = alpha / sides, 2 - 2 Phi(z_(1 - a/2) / sqrt(t))."""
    if t <= 0:
        return 0.0
    z = float(stats.norm.ppf(1 - alpha / sides / 2))
    return float(sides * 2 * stats.norm.cdf(-z / math.sqrt(min(t, 1.0))))


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
    return {n: (float(2 * stats.norm.cdf(-a)), float(stats.norm.cdf(-b)))
            for n, a, b in zip(range(n_start, max_seeds + 1), two, one, strict=True)}


def sequential_decide(
    tests: Sequence[Test],
    directions: Sequence[int],
    previous: Sequence[str | None],
    n_start: int,
    max_seeds: int,
    alpha: float,
) -> tuple[list[str], np.ndarray, np.ndarray, np.ndarray]:
    """Verdicts at this look: the fixed design's rules (Holm, then `tests.verdict`) with each comparison's nominal
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


def smallest_permutation_p(n: int) -> float:
    """The smallest two-sided p of the exact permutation test at n against n seeds: the observed
    split and its mirror among C(2n, n) (`sigmarl.stats.permutation`)."""
    return 2 / math.comb(2 * n, n)


def first_decidable_look(n_start: int, max_seeds: int, alpha: float, comparisons: int = 1) -> int:
    """The fewest seeds per side, at least n_start, at which a first look can show a difference:
    with looks from there to max_seeds, the permutation test's smallest p reaches that look's
    two-sided nominal level divided by `comparisons` (Holm's first step over the study's
    family). A look before it could decide no better/worse and would only spend alpha. When
    none can, the single look at max_seeds."""
    for n in range(n_start, max_seeds):
        if smallest_permutation_p(n) <= nominal_levels(n, max_seeds, alpha)[n][0] / comparisons:
            return n
    return max_seeds
