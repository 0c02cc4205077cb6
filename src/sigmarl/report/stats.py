"""Student-t critical values and mean confidence intervals, without scipy.

The t distribution with an integer number of degrees of freedom has a closed-form
CDF as a finite series (Abramowitz & Stegun 26.7.3 and 26.7.4), so a bisection on it
gives exact quantiles; for very large df the Cornish-Fisher expansion (A&S 26.7.5) is
used instead, whose error there is far below the digits we print.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from functools import lru_cache
from statistics import NormalDist

_SERIES_MAX_DF = 1000  # above this the series costs more than the expansion's error is worth


def _central_probability(t: float, df: int) -> float:
    """P(|T| < t) for Student's t with `df` degrees of freedom (A&S 26.7.3/26.7.4)."""
    theta = math.atan(t / math.sqrt(df))
    sin, cos = math.sin(theta), math.cos(theta)
    c2 = cos * cos
    term = total = 1.0
    if df % 2 == 0:
        # sin θ · (1 + 1/2 cos²θ + 1·3/(2·4) cos⁴θ + … up to cos^(df-2) θ)
        for k in range(1, df // 2):
            term *= (2 * k - 1) / (2 * k) * c2
            total += term
        return sin * total
    if df == 1:
        return 2 * theta / math.pi
    # 2/π · (θ + sin θ cos θ · (1 + 2/3 cos²θ + 2·4/(3·5) cos⁴θ + … up to cos^(df-3) θ))
    for k in range(1, (df - 1) // 2):
        term *= (2 * k) / (2 * k + 1) * c2
        total += term
    return 2 / math.pi * (theta + sin * cos * total)


def _cornish_fisher(level: float, df: int) -> float:
    z = NormalDist().inv_cdf(0.5 + level / 2)
    g1 = (z**3 + z) / 4
    g2 = (5 * z**5 + 16 * z**3 + 3 * z) / 96
    g3 = (3 * z**7 + 19 * z**5 + 17 * z**3 - 15 * z) / 384
    g4 = (79 * z**9 + 776 * z**7 + 1482 * z**5 - 1920 * z**3 - 945 * z) / 92160
    return z + g1 / df + g2 / df**2 + g3 / df**3 + g4 / df**4


@lru_cache(maxsize=256)
def t_critical(df: int, level: float = 0.95) -> float:
    """The t with P(|T| < t) = level: the two-sided critical value for a `level` interval."""
    if df < 1 or int(df) != df:
        raise ValueError(f"degrees of freedom must be a positive integer, got {df}")
    if not 0 < level < 1:
        raise ValueError(f"confidence level must lie in (0, 1), got {level}")
    df = int(df)
    if df > _SERIES_MAX_DF:
        return _cornish_fisher(level, df)
    lo, hi = 0.0, 1.0
    while _central_probability(hi, df) < level:
        lo, hi = hi, hi * 2
    while hi - lo > 1e-12 * hi:
        mid = (lo + hi) / 2
        if _central_probability(mid, df) < level:
            lo = mid
        else:
            hi = mid
    return (lo + hi) / 2


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
