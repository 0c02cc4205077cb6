"""Mean confidence intervals and Student-t critical values (scipy's t distribution)."""

from __future__ import annotations

import math
from collections.abc import Iterable

from scipy import stats


def t_critical(df: float, level: float = 0.95) -> float:
    """The t with P(|T| < t) = level: the two-sided critical value for a `level` interval."""
    if not df > 0:
        raise ValueError(f"degrees of freedom must be positive, got {df}")
    if not 0 < level < 1:
        raise ValueError(f"confidence level must lie in (0, 1), got {level}")
    return float(stats.t.ppf(0.5 + level / 2, df))


def mean_ci(values: Iterable[float], level: float = 0.95) -> tuple[float, float, float, int]:
    """(mean, CI half-width, sample standard deviation, n) of the finite values.

    The half-width is t_(n-1) · s / √n; NaN when fewer than two values make a spread.
    """
    xs = [float(v) for v in values if math.isfinite(float(v))]
    n = len(xs)
    if n == 0:
        return math.nan, math.nan, math.nan, 0
    mean = math.fsum(xs) / n
    if n == 1:
        return mean, math.nan, math.nan, 1
    std = math.sqrt(math.fsum((x - mean) ** 2 for x in xs) / (n - 1))
    return mean, t_critical(n - 1, level) * std / math.sqrt(n), std, n
