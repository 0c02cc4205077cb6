"""The comparison engine (`sigmarl.stats.engine`) against independent numbers: a case worked by
hand, an exact enumeration of every resample at 3 against 3 seeds (with scipy's exact
permutation test for the pooled world), scipy's Welch test where the
bootstrap-t and the t distribution agree (many normal seeds), and its seeds-needed rule against
the engine's own simulated power."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy import stats

from sigmarl.stats.engine import FAR, MC_ERROR, Null, compare, difference, interaction, seeds_needed

TWO = {"zero": Null(0.0)}


def test_hand_worked_two_seeds_against_a_constant_baseline():
    # a = [1, 3], b = [0, 0]: estimate 2, se = sqrt(var(a) / 2) = 1, t_obs = 2. Centred, a's
    # resamples are (-1, -1), (1, 1) (t* = -inf, +inf) and two mixed ones (t* = 0); b adds
    # nothing. P(t* >= 2) = 1/4, so two-sided p = 1/2. The scaled world needs a factor
    # (0 + 0) / 2 = 0, not positive: skipped. The pooled world's 6 splits of (1, 3, 0, 0) give
    # t = 2, +-0.632 (twice each), -2: P(t* >= 2) = 1/6, below the shifted world's, so it stays.
    nulls = {**TWO, "up": Null(0.0, "greater")}
    r = difference([1.0, 3.0], [0.0, 0.0], nulls)
    assert r.estimate == 2.0 and r.se == 1.0
    # both lie far above 0.05: drawn only until then, within their own (shown) Monte Carlo error
    assert r.p["zero"] == pytest.approx(0.5, abs=4 * r.mc_error) and r.mc_error < 0.0025
    assert r.p["up"] == pytest.approx(0.25, abs=4 * r.mc_error)
    full = compare([[1.0, 3.0], [0.0, 0.0]], [1.0, -1.0], nulls, decides=None)  # every p to MC_ERROR
    assert full.mc_error < MC_ERROR and full.draws > r.draws
    assert full.p["zero"] == pytest.approx(0.5, abs=4 * MC_ERROR)
    assert full.p["up"] == pytest.approx(0.25, abs=4 * MC_ERROR)


def _welch(x, y, axis):
    return (x.mean(axis) - y.mean(axis)) / np.sqrt(x.var(axis, ddof=1) / x.shape[axis] + y.var(axis, ddof=1) / y.shape[axis])


def _exact_p(a, b, value, alternative):
    """Every ordered resample of a and of b enumerated (27 x 27) in the shifted and scaled worlds,
    and the pooled world as scipy's exact permutation test of Welch's t (all 20 splits)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    est = a.mean() - b.mean()
    se = math.sqrt(a.var(ddof=1) / 3 + b.var(ddof=1) / 3)
    t_obs = (est - value) / se
    worlds = [(a - a.mean(), b - b.mean(), 0.0)]
    factor = (b.mean() + value) / a.mean()
    if factor > 0:
        worlds.append((a * factor, b, value))
    ps = []
    for wa, wb, c in worlds:
        ra = np.array(list(itertools.product(wa, repeat=3)))
        rb = np.array(list(itertools.product(wb, repeat=3)))
        num = ra.mean(1)[:, None] - rb.mean(1)[None, :] - c
        den = np.sqrt(ra.var(1, ddof=1)[:, None] / 3 + rb.var(1, ddof=1)[None, :] / 3)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.nan_to_num(num / den, nan=0.0)
        greater, less = np.mean(t >= t_obs), np.mean(t <= t_obs)
        ps.append(greater if alternative == "greater" else less if alternative == "less"
                  else min(1.0, 2 * min(greater, less)))
    pooled = stats.permutation_test((a - value, b), _welch, permutation_type="independent", vectorized=True,
                                    n_resamples=np.inf, alternative=alternative).pvalue
    return max(*ps, pooled)


@pytest.mark.parametrize("value, alternative", [(0.0, "two-sided"), (0.5, "less"), (-0.3, "greater")])
def test_matches_an_exact_enumeration_at_three_seeds(value, alternative):
    a, b = [1.2, 2.9, 1.7], [0.8, 1.1, 2.0]
    r = difference(a, b, {"h": Null(value, alternative)})
    assert r.p["h"] == pytest.approx(_exact_p(a, b, value, alternative), abs=4 * max(MC_ERROR, r.mc_error) + 2e-6)


def test_agrees_with_welch_where_the_t_distribution_holds():
    rng = np.random.default_rng(3)
    a, b = rng.normal(0.6, 1.0, 60), rng.normal(0.0, 1.5, 60)
    r = difference(a, b, TWO)
    welch = stats.ttest_ind(a, b, equal_var=False)
    assert r.p["zero"] == pytest.approx(welch.pvalue, abs=0.01)
    low, high = welch.confidence_interval(0.95)
    assert (r.ci_low, r.ci_high) == pytest.approx((low, high), abs=0.05)
    assert r.se == pytest.approx(math.sqrt(a.var(ddof=1) / 60 + b.var(ddof=1) / 60))


def test_reproducible_and_within_the_monte_carlo_error():
    a, b = [0.4, 0.9, 0.5, 1.6, 0.7], [0.3, 0.5, 0.6, 0.2, 0.9]
    nulls = {**TWO, "m": Null(0.1, "less")}
    first, second = difference(a, b, nulls), difference(a, b, nulls)
    assert first == second
    # each p to MC_ERROR, or FAR Monte Carlo errors above the level 0.05 (it decides nothing there)
    assert all((e := math.sqrt(p * (1 - p) / first.draws)) < MC_ERROR or p - FAR * e > 0.05 for p in first.p.values())


def test_fewer_than_two_seeds_a_side_is_undecidable():
    r = difference([1.0], [0.0, 0.5, 0.2], TWO)
    assert not r.decidable and math.isnan(r.p["zero"]) and math.isnan(r.ci_low) and r.estimate == pytest.approx(1.0 - 0.7 / 3)


def test_an_interaction_is_the_difference_of_differences():
    x, bx, y, by = [3.0, 3.2, 2.9], [1.0, 1.1, 0.9], [1.5, 1.4, 1.6], [1.0, 1.2, 0.8]
    r = interaction(x, bx, y, by, TWO)
    assert r.estimate == pytest.approx((np.mean(x) - np.mean(bx)) - (np.mean(y) - np.mean(by)))
    se = math.sqrt(sum(np.var(g, ddof=1) / 3 for g in (x, bx, y, by)))
    assert r.se == pytest.approx(se)
    assert r.ns == (3, 3, 3, 3)


def test_unknown_alternative_is_refused():
    with pytest.raises(ValueError, match="unknown alternative"):
        compare([[1, 2], [1, 2]], [1, -1], {"h": Null(0.0, "sideways")})


def test_seeds_needed_gives_the_engines_power():
    # normal seeds, sd 1 and 1.5, a true difference of 1.2: at the rule's n the engine's own
    # test rejects at about the promised power 0.8 (300 datasets: binomial sd 0.023)
    n = seeds_needed(1.2, [1.0, 2.25], [1.0, -1.0], 0.05, 0.8)
    assert 12 <= n <= 24
    rng = np.random.default_rng(9)
    hits = [compare([rng.normal(1.2, 1.0, n), rng.normal(0.0, 1.5, n)], [1.0, -1.0], TWO, draws=1000).p["zero"] <= 0.05
            for _ in range(300)]
    assert np.mean(hits) == pytest.approx(0.8, abs=0.1)
    assert seeds_needed(0.0, [1.0, 1.0], [1.0, -1.0], 0.05) is None
