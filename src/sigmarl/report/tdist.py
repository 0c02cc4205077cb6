"""Student's t and the noncentral t for any real degrees of freedom, with numpy only.

T = (Z + nc) / sqrt(V / df), with Z standard normal and V chi-squared with df degrees of
freedom, so P(T <= t) = E[Phi(t * sqrt(V / df) - nc)]. The expectation is a one-dimensional
integral over x = log V, whose integrand is smooth and decays fast at both ends, so the
trapezoidal rule on a fixed grid is accurate to ~1e-10 (the tests check it against scipy).
Welch's test needs non-integer df and the power analysis needs the noncentral t; scipy
is not a runtime dependency, hence this module.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

_N_GRID = 601
_ERFC = np.frompyfunc(math.erfc, 1, 1)


def normal_cdf(x: np.ndarray | float) -> np.ndarray:
    """Phi(x), accurate in both tails (erfc, not 1 - erf)."""
    return np.asarray(_ERFC(-np.asarray(x, dtype=float) / math.sqrt(2)), dtype=float) / 2


def normal_ppf(p: float) -> float:
    from statistics import NormalDist

    return NormalDist().inv_cdf(p)


@lru_cache(maxsize=512)
def _grid(df: float) -> tuple[np.ndarray, np.ndarray]:
    """sqrt(V / df) on the grid and the trapezoid weights times the density of log V."""
    k = df / 2
    # log V from far below the bulk (the density there grows like V^k, and the bulk's width
    # in log V is about sqrt(2 / df)) to far above it
    width = math.sqrt(2 / df)
    lo = math.log(df) - min(700.0, 40 / k + 12 * width)
    hi = max(math.log(df + 40 * math.sqrt(2 * df) + 200), math.log(df) + 12 * width)
    x = np.linspace(lo, hi, _N_GRID)
    v = np.exp(x)
    log_density = k * x - v / 2 - k * math.log(2) - math.lgamma(k)  # density of log V
    w = np.exp(log_density) * (x[1] - x[0])
    w[[0, -1]] /= 2
    return np.sqrt(v / df), w / w.sum()  # normalised: the grid's own mass is 1


def nct_cdf(t: float, df: float, nc: float = 0.0) -> float:
    """P(T <= t) for the noncentral t with `df` (> 0, real) degrees of freedom and
    noncentrality `nc`; nc = 0 is Student's t."""
    if not df > 0:
        raise ValueError(f"degrees of freedom must be positive, got {df}")
    if math.isinf(df):
        return float(normal_cdf(t - nc))
    s, w = _grid(float(df))
    return float(np.dot(w, normal_cdf(t * s - nc)))


def t_pdf(t: float, df: float) -> float:
    """The density of Student's t: E[s phi(t s)], s = sqrt(V / df)."""
    if math.isinf(df):
        return math.exp(-t * t / 2) / math.sqrt(2 * math.pi)
    s, w = _grid(float(df))
    return float(np.dot(w, s * np.exp(-((t * s) ** 2) / 2))) / math.sqrt(2 * math.pi)


def t_cdf(t: float, df: float) -> float:
    return nct_cdf(t, df, 0.0)


def t_sf(t: float, df: float) -> float:
    """P(T > t), computed as P(T < -t) so that small tail probabilities keep their digits."""
    return nct_cdf(-t, df, 0.0)


def t_ppf(p: float, df: float) -> float:
    """The t with P(T <= t) = p: Newton's method from the normal quantile, kept inside a
    bracket that bisection narrows whenever a Newton step would leave it."""
    if not 0 < p < 1:
        raise ValueError(f"probability must lie in (0, 1), got {p}")
    if p < 0.5:
        return -t_ppf(1 - p, df)
    if p == 0.5:
        return 0.0
    q = 1 - p  # work with the upper tail, which keeps its digits for p near 1
    lo, hi = 0.0, 1.0
    while t_sf(hi, df) > q:
        lo, hi = hi, hi * 2
    t = min(max(normal_ppf(p), lo), hi)
    for _ in range(100):
        gap = t_sf(t, df) - q  # > 0: t is too small
        if abs(gap) <= 1e-14 * q:
            return t
        if gap > 0:
            lo = t
        else:
            hi = t
        step = t + gap / t_pdf(t, df)
        if abs(step - t) <= 1e-13 * t:
            return step
        t = step if lo < step < hi else (lo + hi) / 2
    return t
