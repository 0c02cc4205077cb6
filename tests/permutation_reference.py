"""The permutation tests the verdicts used before the comparison engine (`sigmarl.stats.engine`),
kept as references: the tests of their level (tests/test_permutation_level.py,
tests/test_one_sided_level.py) and scripts/engine_level.py, which shows the one-sided
"smaller" test failing its level where the engine holds it.

Permutation tests of a difference of two samples' means, and their TOST.

Seed means are skewed (most seeds collide rarely, one in ten learns slowly and collides
several times more), and at 3 to 10 seeds per side Welch's t-test then rejects a true null
more often than its level says. A permutation test needs no shape: under no difference the
two samples are exchangeable, so the observed difference is ranked among the differences of
every split of the pooled values into groups of the same sizes.

- exact: every split is enumerated when there are at most `EXACT_LIMIT` of them (10 against
  10 seeds: 184,756), and p is the share of splits at least as extreme (the observed one
  among them); with equal sizes only the half of the splits that holds the first value in
  its first group is computed, each standing also for its complement (the opposite
  difference);
- Monte Carlo otherwise: `DRAWS` random splits from a fixed seed, p = (1 + extreme) /
  (1 + draws), which keeps the level (Phipson and Smyth); the standard error of such a p is
  at most 0.5 / sqrt(draws), 0.0035 at 20,000 draws.

Equivalence within +-margin (TOST) shifts the first sample by the margin, so that each of
its two one-sided nulls, d = +margin and d = -margin, becomes "no difference", and tests
each one-sided; its p is the larger of the two. The shift moves a split's difference by
margin x (the first sample's share of the split's first group minus its share of the
second), so one product of the pooled values with the splits serves all three tests.

With few seeds the smallest p there is, 2 / C(n_a + n_b, n_a) two-sided, may lie above the
level: 3 against 3 seeds (20 splits) can never show a difference at 0.05.
"""

from __future__ import annotations

import math
from dataclasses import replace
from functools import lru_cache
from itertools import combinations

import numpy as np

from sigmarl.stats.engine import Test, welch

EXACT_LIMIT = 200_000
DRAWS = 20_000
SEED = 20240924  # fixed, so that the same samples give the same p-values
_CHUNK = 4_000_000  # splits x samples computed at once (memory)


def is_exact(n: int, k: int, exact_limit: int = EXACT_LIMIT) -> bool:
    return math.comb(n, k) <= exact_limit


@lru_cache(maxsize=8)
def splits(n: int, k: int, draws: int = DRAWS, seed: int = SEED, exact_limit: int = EXACT_LIMIT) -> np.ndarray:
    """[S, n] float indicators of the first group (k of n) for every split, or for `draws`
    random ones when there are more than `exact_limit` splits (the observed split not among them)."""
    if is_exact(n, k, exact_limit):
        idx = np.fromiter((i for c in combinations(range(n), k) for i in c), dtype=np.intp).reshape(-1, k)
    else:
        idx = np.argsort(np.random.default_rng(seed).random((draws, n)), axis=1)[:, :k]
    out = np.zeros((len(idx), n))
    np.put_along_axis(out, idx, 1.0, axis=1)
    out.setflags(write=False)
    return out


def share(count: np.ndarray, total: int, exact: bool) -> np.ndarray:
    """p from the number of splits at least as extreme: their share of every split (exact), or
    (1 + count) / (1 + draws)."""
    return count / total if exact else (1 + count) / (1 + total)


def permutation_p(a, b, margin: float, draws: int = DRAWS, seed: int = SEED, exact_limit: int = EXACT_LIMIT):
    """Two-sided permutation p of mean(a) = mean(b), and TOST's p of |difference| >= margin.

    a [..., n_a] and b [..., n_b]: one pair of samples, or many along the leading axes (then
    the two p's are arrays of that shape). `exact_limit`: enumerate every split up to this many
    (a power simulation sets it low for speed)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    lead = np.broadcast_shapes(a.shape[:-1], b.shape[:-1])
    a = np.broadcast_to(a, (*lead, a.shape[-1])).reshape(-1, a.shape[-1])
    b = np.broadcast_to(b, (*lead, b.shape[-1])).reshape(-1, b.shape[-1])
    na, nb = a.shape[-1], b.shape[-1]
    exact = is_exact(na + nb, na, exact_limit)
    s = splits(na + nb, na, draws, seed, exact_limit)
    total = len(s)
    # equal sizes, every split: a split and its complement have opposite differences (and
    # shifts), so the half holding value 0 in its first group (combinations' first half)
    # stands for both: half the work
    mirrored = exact and na == nb
    if mirrored:
        s = s[: total // 2]
    first_a = s[:, :na].sum(axis=1)  # how many of a's values each split puts in its first group
    shift = first_a / na - (na - first_a) / nb  # a split's difference moves by margin x this
    p_diff, p_eq = np.empty(len(a)), np.empty(len(a))
    step = max(1, _CHUNK // len(s))
    for lo in range(0, len(a), step):
        pooled = np.concatenate([a[lo:lo + step], b[lo:lo + step]], axis=-1)
        first = pooled @ s.T
        diffs = first / na - (pooled.sum(axis=-1, keepdims=True) - first) / nb
        d = (pooled[:, :na].mean(-1) - pooled[:, na:].mean(-1))[:, None]
        # ties of the statistic (the same difference summed in another order) count as extreme
        tol = 1e-9 * np.maximum(1.0, np.maximum(np.abs(pooled).max(axis=-1, keepdims=True), abs(margin)))
        down, up = diffs - margin * shift, diffs + margin * shift
        n_diff = np.count_nonzero(np.abs(diffs) >= np.abs(d) - tol, axis=-1)
        n_upper = np.count_nonzero(down <= d - margin + tol, axis=-1)  # null d = +margin
        n_lower = np.count_nonzero(up >= d + margin - tol, axis=-1)  # null d = -margin
        if mirrored:  # the complements: difference -diffs, shift -shift
            n_diff = 2 * n_diff
            n_upper = n_upper + np.count_nonzero(down >= margin - d - tol, axis=-1)
            n_lower = n_lower + np.count_nonzero(up <= -d - margin + tol, axis=-1)
        p_diff[lo:lo + step] = share(n_diff, total, exact)
        p_eq[lo:lo + step] = np.maximum(share(n_upper, total, exact), share(n_lower, total, exact))
    if not lead:
        return float(p_diff[0]), float(p_eq[0])
    return p_diff.reshape(lead), p_eq.reshape(lead)


def permutation_test(variant, baseline, margin: float, draws: int = DRAWS, seed: int = SEED) -> Test:
    """The permutation tests of one comparison; Welch's p stays as `p_difference_welch`, and the
    standard error, degrees of freedom and interval stay Welch's (reported, not decided on)."""
    test = welch(variant, baseline, margin)
    if not math.isfinite(test.se) or test.se == 0:  # one seed on a side, or no noise at all
        return test
    p_diff, p_eq = permutation_p(variant, baseline, margin, draws, seed)
    return replace(test, p_difference=p_diff, p_equivalence=p_eq)


# One-sided permutation tests of a shifted difference of means (the replication table's
# "smaller" test before the engine):
# One-sided permutation tests of a shifted difference of means.
#
# H0: mean(a) - mean(b) <= shift, against "greater". The first sample is moved by the shift
# (a - shift), the two are pooled, and the observed split's statistic is ranked among those of
# every split of the pooled values into groups of the same sizes (exact up to
# `permutation.EXACT_LIMIT` splits, else `permutation.DRAWS` random ones, p = (1 + count) /
# (1 + draws)). "Less" is "greater" of the negated samples.
#
# statistic: "difference", the difference of means, as the verdicts' own tests
# (above); or "welch", Welch's t (a studentized permutation test; Janssen
# 1997, Chung and Romano 2013), asymptotically of its level under unequal spreads. Measured on
# the committed seeds (tests/test_one_sided_level.py) neither keeps the level when the two sides'
# seeds differ in shape at equal means, at these seed counts, so the replication verdicts keep the
# verdicts' statistic.
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
