"""Welch's tests of a difference of means, TOST, their contrast, and Holm's adjustment.

Study-free: two samples in (e.g. the seed means of two models), a `Test` out. The verdict
rule that reads a test (a difference first, then equivalence) is here too, so that the
fixed and the sequential designs apply the same one.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats


@dataclass(frozen=True)
class Test:
    """The tests of one comparison, from the two sides' samples."""

    n_variant: int
    n_baseline: int
    variant_mean: float
    baseline_mean: float
    difference: float
    se: float
    df: float
    p_difference: float
    p_equivalence: float
    p_difference_welch: float = math.nan  # Welch's p of the difference, whichever test decides
    ci: tuple[float, float] | None = None  # the deciding test's own interval, where it has one

    def interval(self, level: float) -> tuple[float, float]:
        """The deciding test's interval where it gave one, else Welch's t-interval of the difference."""
        if self.ci is not None:
            return self.ci
        if not math.isfinite(self.se):
            return math.nan, math.nan
        if self.se == 0:
            return self.difference, self.difference
        half = float(stats.t.ppf(0.5 + level / 2, self.df)) * self.se
        return self.difference - half, self.difference + half


def welch(variant: np.ndarray, baseline: np.ndarray, margin: float) -> Test:
    """Welch's two-sided test of no difference and TOST within +-margin."""
    a, b = np.asarray(variant, float), np.asarray(baseline, float)
    na, nb = len(a), len(b)
    d = float(a.mean() - b.mean()) if na and nb else math.nan
    means = (float(a.mean()) if na else math.nan, float(b.mean()) if nb else math.nan)
    if na < 2 or nb < 2:
        return Test(na, nb, *means, d, math.nan, math.nan, math.nan, math.nan)
    va, vb = a.var(ddof=1) / na, b.var(ddof=1) / nb
    se = math.sqrt(va + vb)
    if se == 0:  # every value of both sides is the same: no noise to test against
        return Test(na, nb, *means, d, 0.0, math.inf, float(d == 0), float(abs(d) >= margin))
    df = (va + vb) ** 2 / (va**2 / (na - 1) + vb**2 / (nb - 1))
    p_diff, p_eq = p_values(d, se, df, margin)
    return Test(na, nb, *means, d, se, df, p_diff, p_eq, p_diff)


def p_values(d: float, se: float, df: float, margin: float) -> tuple[float, float]:
    """Two-sided p of d = 0, and TOST's p of |d| >= margin, for a t statistic on df."""
    p_diff = min(1.0, 2 * float(stats.t.sf(abs(d) / se, df)))
    p_eq = max(float(stats.t.sf((d + margin) / se, df)), float(stats.t.cdf((d - margin) / se, df)))
    return p_diff, p_eq


def contrast(x: Test, y: Test, margin: float) -> Test:
    """The test of (x's difference) - (y's difference), the four groups independent: the
    standard errors add in squares, and the degrees of freedom are Satterthwaite's over the
    four groups, se^4 / (se_x^4 / df_x + se_y^4 / df_y). Its means are the two differences."""
    d = x.difference - y.difference
    se = math.hypot(x.se, y.se)
    if not math.isfinite(se) or se == 0:  # a side with one value, or no noise at all
        return Test(x.n_variant, y.n_variant, x.difference, y.difference, d, se, math.nan, math.nan, math.nan)
    df = se**4 / (x.se**4 / x.df + y.se**4 / y.df)
    return Test(x.n_variant, y.n_variant, x.difference, y.difference, d, se, df, *p_values(d, se, df, margin))


def holm(p_values: Sequence[float]) -> np.ndarray:
    """Holm's step-down adjusted p-values: the i-th smallest of m is multiplied by m - i + 1,
    made non-decreasing along the order and capped at 1. NaN p-values count as 1 in the
    family (a comparison that could not be tested still is one) and stay NaN."""
    p = np.asarray(p_values, float)
    filled = np.where(np.isnan(p), 1.0, p)
    m = len(p)
    order = np.argsort(filled, kind="stable")
    scaled = filled[order] * (m - np.arange(m))
    adjusted = np.empty(m)
    adjusted[order] = np.minimum(1.0, np.maximum.accumulate(scaled))
    return np.where(np.isnan(p), math.nan, adjusted)


def verdict(test: Test, sign: int, p_difference: float, p_equivalence: float, level_difference: float,
            level_equivalence: float) -> str:
    """The verdict of one comparison from its adjusted p-values: a difference first (better or
    worse by the metric's direction `sign`, +1 when higher is better), then equivalence, else
    undecided."""
    if p_difference <= level_difference:
        return "better" if test.difference * sign > 0 else "worse"
    if p_equivalence <= level_equivalence:
        return "equivalent"
    return "undecided"
