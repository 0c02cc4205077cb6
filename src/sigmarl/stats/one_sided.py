"""One-sided permutation tests of a shifted difference of means.

H0: mean(a) - mean(b) <= shift, against "greater". The first sample is moved by the shift
(a - shift), the two are pooled, and the observed split's statistic is ranked among those of
every split of the pooled values into groups of the same sizes (exact up to
`permutation.EXACT_LIMIT` splits, else `permutation.DRAWS` random ones, p = (1 + count) /
(1 + draws)). "Less" is "greater" of the negated samples.

statistic: "difference", the difference of means, as the verdicts' own tests
(`sigmarl.stats.permutation`); or "welch", Welch's t (a studentized permutation test; Janssen
1997, Chung and Romano 2013), asymptotically of its level under unequal spreads. Measured on
the committed seeds (tests/test_one_sided_level.py) neither keeps the level when the two sides'
seeds differ in shape at equal means, at these seed counts, so the replication verdicts keep the
verdicts' statistic.
"""

from __future__ import annotations

import numpy as np

from sigmarl.stats.permutation import DRAWS, EXACT_LIMIT, SEED, is_exact, share, splits

_CHUNK = 4_000_000  # splits x samples computed at once (memory)
_TINY = 1e-12  # a group without spread: Welch's variance floored, so t stays finite


def _statistic(sum1, sq1, sum2, sq2, n1: int, n2: int, statistic: str) -> np.ndarray:
    m1, m2 = sum1 / n1, sum2 / n2
    if statistic == "difference":
        return m1 - m2
    v1 = np.maximum(sq1 - n1 * m1 * m1, 0.0) / (n1 - 1)
    v2 = np.maximum(sq2 - n2 * m2 * m2, 0.0) / (n2 - 1)
    return (m1 - m2) / np.sqrt(np.maximum(v1 / n1 + v2 / n2, _TINY))


def greater_p(a, b, shift: float = 0.0, statistic: str = "difference", draws: int = DRAWS, seed: int = SEED,
              exact_limit: int = EXACT_LIMIT):
    """p of H0: mean(a) - mean(b) <= shift (alternative: greater).

    a [..., n_a] and b [..., n_b], at least two values each: one pair of samples, or many along
    the leading axes (p is then an array of that shape)."""
    if statistic not in ("difference", "welch"):
        raise ValueError(f"unknown statistic {statistic!r}; known: difference, welch")
    a, b = np.asarray(a, float), np.asarray(b, float)
    lead = np.broadcast_shapes(a.shape[:-1], b.shape[:-1])
    na, nb = a.shape[-1], b.shape[-1]
    if na < 2 or nb < 2:
        raise ValueError(f"a permutation test needs two values a side, got {na} and {nb}")
    a = np.broadcast_to(a, (*lead, na)).reshape(-1, na) - shift
    b = np.broadcast_to(b, (*lead, nb)).reshape(-1, nb)
    exact = is_exact(na + nb, na, exact_limit)
    s = splits(na + nb, na, draws, seed, exact_limit)
    p = np.empty(len(a))
    step = max(1, _CHUNK // len(s))
    for lo in range(0, len(a), step):
        pooled = np.concatenate([a[lo:lo + step], b[lo:lo + step]], axis=-1)
        total, total_sq = pooled.sum(-1, keepdims=True), (pooled ** 2).sum(-1, keepdims=True)
        sum1, sq1 = pooled @ s.T, (pooled ** 2) @ s.T
        t = _statistic(sum1, sq1, total - sum1, total_sq - sq1, na, nb, statistic)
        x, y = pooled[:, :na], pooled[:, na:]
        observed = _statistic(x.sum(-1), (x ** 2).sum(-1), y.sum(-1), (y ** 2).sum(-1), na, nb, statistic)[:, None]
        # the same value reached by another order of summation counts as extreme
        tol = 1e-9 * np.maximum(1.0, np.abs(pooled).max(axis=-1, keepdims=True) if statistic == "difference"
                                else np.abs(observed))
        p[lo:lo + step] = share(np.count_nonzero(t >= observed - tol, axis=-1), len(s), exact)
    return float(p[0]) if not lead else p.reshape(lead)


def less_p(a, b, shift: float = 0.0, statistic: str = "difference", draws: int = DRAWS, seed: int = SEED,
           exact_limit: int = EXACT_LIMIT):
    """p of H0: mean(a) - mean(b) >= shift (alternative: less)."""
    return greater_p(-np.asarray(a, float), -np.asarray(b, float), -shift, statistic, draws, seed, exact_limit)
