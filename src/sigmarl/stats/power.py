"""Power and seeds needed for the two decisions a comparison of seed means can reach.

Both sides get n seeds; v_a and v_b are the variances of one seed's mean (two-level:
sigma_seed^2 + sigma_sim^2 / n_sims). The difference of the means has standard error
sqrt((v_a + v_b) / n) and the t statistic Welch's degrees of freedom
(v_a + v_b)^2 (n - 1) / (v_a^2 + v_b^2), which is 2n - 2 when v_a = v_b (Student's test).

- A difference (two-sided t-test at level `alpha`): power = P(|T| > t_(1-alpha/2)) with T
  noncentral t of noncentrality delta / se.
- Equivalence within +-margin (two one-sided tests at `alpha` each): power is approximated
  by P(T1 > t_(1-alpha)) + P(T2 < -t_(1-alpha)) - 1, with noncentralities
  (delta + margin) / se and (delta - margin) / se (zero when negative).
"""

from __future__ import annotations

import math

from scipy import stats

MAX_N = 100_000  # beyond this the answer is "practically never"


def _cdf(t: float, df: float, nc: float) -> float:
    """P(T <= t) of the noncentral t; scipy answers NaN far in a tail, where it is ~0 or ~1."""
    p = float(stats.norm.cdf(t - nc)) if math.isinf(df) else float(stats.nct.cdf(t, df, nc))
    return p if math.isfinite(p) else float(t > nc)


def _sf(t: float, df: float, nc: float) -> float:
    p = float(stats.norm.sf(t - nc)) if math.isinf(df) else float(stats.nct.sf(t, df, nc))
    return p if math.isfinite(p) else float(t < nc)


def _df(n: int, va: float, vb: float) -> float:
    if va + vb == 0:
        return math.inf
    return (va + vb) ** 2 * (n - 1) / (va**2 + vb**2)


def difference_power(n: int, delta: float, va: float, vb: float, alpha: float) -> float:
    se = math.sqrt((va + vb) / n)
    df = _df(n, va, vb)
    crit = float(stats.t.ppf(1 - alpha / 2, df)) if math.isfinite(df) else 0.0
    nc = abs(delta) / se if se > 0 else math.inf
    if math.isinf(nc):
        return 1.0 if delta else 0.0
    return _sf(crit, df, nc) + _cdf(-crit, df, nc)


def equivalence_power(n: int, delta: float, va: float, vb: float, margin: float, alpha: float) -> float:
    if abs(delta) >= margin:
        return 0.0
    se = math.sqrt((va + vb) / n)
    if se == 0:
        return 1.0
    df = _df(n, va, vb)
    crit = float(stats.t.ppf(1 - alpha, df))
    upper = _sf(crit, df, (delta + margin) / se)  # rejects "delta <= -margin"
    lower = _cdf(-crit, df, (delta - margin) / se)  # rejects "delta >= margin"
    return max(0.0, upper + lower - 1)


def _smallest_n(power_at, target: float) -> int | None:
    """The smallest n >= 2 with power_at(n) >= target (power rises with n), or None."""
    if power_at(2) >= target:
        return 2
    lo, hi = 2, 4
    while power_at(hi) < target:
        lo, hi = hi, hi * 2
        if hi > MAX_N:
            return None
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if power_at(mid) >= target:
            hi = mid
        else:
            lo = mid
    return hi


def seeds_for_difference(delta: float, va: float, vb: float, alpha: float, power: float) -> int | None:
    """Seeds per side for a two-sided test at `alpha` to detect `delta` with `power`
    (None: no difference to detect, or more than MAX_N)."""
    if delta == 0 or not all(map(math.isfinite, (delta, va, vb))):
        return None
    return _smallest_n(lambda n: difference_power(n, delta, va, vb, alpha), power)


def seeds_for_equivalence(delta: float, va: float, vb: float, margin: float, alpha: float,
                          power: float) -> int | None:
    """Seeds per side for TOST at `alpha` to show equivalence within +-margin when the true
    difference is `delta` (None: |delta| >= margin, or more than MAX_N)."""
    if not abs(delta) < margin or not all(map(math.isfinite, (va, vb))):
        return None
    return _smallest_n(lambda n: equivalence_power(n, delta, va, vb, margin, alpha), power)
