"""Verdicts, Holm, TOST, power and variance components against independent numbers."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from sigmarl.report.compare.verdicts import Design, verdict_table, verdicts_markdown
from sigmarl.report.plan import plan_table, plan_text
from sigmarl.stats.bootstrap import components
from sigmarl.stats.engine import MC_ERROR, comparison_test, holm, power, seeds_needed, welch

W = (1.0, -1.0)


def seeds_for_difference(delta, va, vb, alpha, target):
    return seeds_needed(delta, [va, vb], W, alpha, target)


def seeds_for_equivalence(delta, va, vb, margin, alpha, target):
    return seeds_needed(delta, [va, vb], W, alpha, target, margin=margin)


def difference_power(n, delta, va, vb, alpha):
    return power(n, delta, [va, vb], W, alpha)


def equivalence_power(n, delta, va, vb, margin, alpha):
    return power(n, delta, [va, vb], W, alpha, margin=margin)


def test_holm_hand_worked():
    # sorted: 0.01 x 3 = 0.03; 0.03 x 2 = 0.06; 0.04 x 1 = 0.04, raised to the 0.06 before it
    assert holm([0.01, 0.04, 0.03]) == pytest.approx([0.03, 0.06, 0.06])
    # at alpha 0.05 only the first is rejected (Bonferroni would reject it too; 0.03 > 0.05/2)
    assert list(holm([0.01, 0.04, 0.03]) <= 0.05) == [True, False, False]
    # an untestable comparison still counts in the family
    adjusted = holm([0.01, math.nan])
    assert adjusted[0] == pytest.approx(0.02) and math.isnan(adjusted[1])
    assert holm([0.5, 0.9]) == pytest.approx([1.0, 1.0])


def test_welch_and_tost_match_scipy_one_sided_tests():
    a = np.array([0.41, 0.55, 0.38, 0.62, 0.47])
    b = np.array([0.52, 0.61, 0.70, 0.58])
    margin = 0.2
    test = welch(a, b, margin)
    assert test.difference == pytest.approx(a.mean() - b.mean())
    assert test.p_difference == pytest.approx(stats.ttest_ind(a, b, equal_var=False).pvalue, rel=1e-6)
    # TOST: H0 d <= -margin (shift a up by the margin, one-sided greater) and d >= margin
    p_low = stats.ttest_ind(a + margin, b, equal_var=False, alternative="greater").pvalue
    p_high = stats.ttest_ind(a - margin, b, equal_var=False, alternative="less").pvalue
    assert test.p_equivalence == pytest.approx(max(p_low, p_high), rel=1e-6)
    ci = stats.ttest_ind(a, b, equal_var=False).confidence_interval(0.95)
    assert test.interval(0.95) == pytest.approx((ci.low, ci.high), rel=1e-8)


def test_tost_hand_worked():
    # two seeds each side, seed means 1, 3 and 0, 2: d = 1, se = sqrt(2/2 + 2/2) = sqrt(2),
    # Welch df = 2^2 / (1/1 + 1/1) = 2; margin 5: t = (1 + 5)/sqrt 2 = 4.243 and
    # (1 - 5)/sqrt 2 = -2.828; p = max(P(T2 > 4.243), P(T2 < -2.828)) = P(T2 > 2.828)
    # = 0.5 - 2.828 / (2 sqrt(2 + 2.828^2)) (the t2 CDF is closed-form) = 0.0528
    test = welch(np.array([1.0, 3.0]), np.array([0.0, 2.0]), 5.0)
    assert test.df == pytest.approx(2.0)
    t = 4 / math.sqrt(2)
    assert test.p_equivalence == pytest.approx(0.5 - t / (2 * math.sqrt(2 + t * t)), rel=1e-9)
    assert test.p_equivalence == pytest.approx(0.0528, abs=1e-4)


def test_sample_sizes_match_the_textbook():
    # Cohen (1988): two-sided alpha 0.05, power 0.8: d = 0.8 -> 26 per group, d = 0.5 -> 64
    assert seeds_for_difference(0.8, 1.0, 1.0, 0.05, 0.8) == 26
    assert seeds_for_difference(0.5, 1.0, 1.0, 0.05, 0.8) == 64
    assert seeds_for_difference(-0.5, 1.0, 1.0, 0.05, 0.8) == 64  # the sign does not matter
    assert seeds_for_difference(0.0, 1.0, 1.0, 0.05, 0.8) is None
    # the power itself: P(|T| > t_crit) under the noncentral t, as scipy computes it
    n, d = 26, 0.8
    crit, nc = stats.t.ppf(0.975, 2 * n - 2), d / math.sqrt(2 / n)
    expected = stats.nct.sf(crit, 2 * n - 2, nc) + stats.nct.cdf(-crit, 2 * n - 2, nc)
    assert difference_power(n, d, 1.0, 1.0, 0.05) == pytest.approx(expected, abs=1e-9)
    assert expected > 0.8 > difference_power(n - 1, d, 1.0, 1.0, 0.05)


def test_equivalence_sample_size():
    # no true difference, margin one standard deviation, alpha 0.05 per one-sided test,
    # power 0.8: the normal approximation 2 (z_0.95 + z_0.9)^2 = 17.1 -> 18 with t quantiles
    assert seeds_for_equivalence(0.0, 1.0, 1.0, 1.0, 0.05, 0.8) == 18
    n = 18
    crit, se = stats.t.ppf(0.95, 2 * n - 2), math.sqrt(2 / n)
    expected = stats.nct.sf(crit, 2 * n - 2, 1 / se) + stats.nct.cdf(-crit, 2 * n - 2, -1 / se) - 1
    assert equivalence_power(n, 0.0, 1.0, 1.0, 1.0, 0.05) == pytest.approx(expected, abs=1e-9)
    assert seeds_for_equivalence(1.0, 1.0, 1.0, 1.0, 0.05, 0.8) is None  # the difference is the margin


def test_variance_components_hand_worked_balanced():
    # seeds (1, 3), (4, 6), (7, 9): means 2, 5, 8, grand mean 5
    # MSW = (1 + 1 + 1 + 1 + 1 + 1) / (6 - 3) = 2; MSB = 2 (9 + 0 + 9) / 2 = 18
    # sigma_sim^2 = 2, sigma_seed^2 = (18 - 2) / 2 = 8; a seed mean: 8 + 2/2 = 9
    c = components([np.array([1.0, 3.0]), np.array([4.0, 6.0]), np.array([7.0, 9.0])])
    assert (c.sigma2_sim, c.sigma2_seed) == pytest.approx((2.0, 8.0))
    assert c.seed_mean_variance() == pytest.approx(9.0)
    assert c.seed_mean_variance() == pytest.approx(np.var([2.0, 5.0, 8.0], ddof=1))  # balanced: equal
    assert c.seed_mean_variance(n_sims=8) == pytest.approx(8.25)
    assert c.seed_share == pytest.approx(8 / 9)
    assert c.spread_ratio == pytest.approx(8.0)


def test_variance_components_unbalanced_and_truncated():
    # unbalanced: n = 2, 4; n0 = (6 - (4 + 16)/6) / 1 = 8/3
    g = [np.array([0.0, 2.0]), np.array([4.0, 6.0, 4.0, 6.0])]
    c = components(g)
    msw = (2 + 4) / 4
    msb = 2 * (1 - 11 / 3) ** 2 + 4 * (5 - 11 / 3) ** 2
    assert c.sigma2_sim == pytest.approx(msw)
    assert c.sigma2_seed == pytest.approx((msb - msw) / (8 / 3))
    # seeds closer together than their simulations allow: the seed component is 0, not negative
    c = components([np.array([0.0, 10.0]), np.array([1.0, 9.0])])
    assert c.sigma2_seed == 0.0 and c.sigma2_sim == pytest.approx(41.0)
    assert math.isnan(components([np.array([1.0, 2.0])]).sigma2_seed)


def _rows(values: dict[tuple[str, str], list[list[float]]]) -> pd.DataFrame:
    return pd.DataFrame([
        {"model": m, "scenario": sc, "seed": s, "simulation": j, "CR_total": v / 100, "CD": 1.0, "AS": 0.7}
        for (m, sc), seeds in values.items() for s, sims in enumerate(seeds) for j, v in enumerate(sims)
    ])


def test_verdict_rules_and_holm_over_the_study():
    # 5 seeds a side: a permutation test of 3 against 3 (20 splits) cannot reach p < 0.1
    rows = _rows({
        ("M0", "A"): [[1.0, 1.2], [1.1, 1.2], [1.0, 1.1], [1.2, 1.0], [1.1, 1.1]],
        ("M1", "A"): [[5.0, 5.2], [5.3, 5.1], [4.9, 5.1], [5.0, 5.0], [5.2, 5.1]],  # far worse in every seed
        ("M2", "A"): [[1.1, 1.1], [1.2, 1.1], [1.1, 1.0], [1.1, 1.2], [1.0, 1.2]],  # the same seed means
        ("M3", "A"): [[1.0, 3.0], [0.2, 0.4], [2.0, 2.6], [0.1, 0.5], [3.0, 1.0]],  # noisy: nothing can be said
        ("M0", "B"): [[1.0, 1.2], [1.1, 1.2], [1.0, 1.1], [1.2, 1.0], [1.1, 1.1]],
        ("M1", "B"): [[0.5, 0.7], [0.6, 0.8], [0.4, 0.6], [0.6, 0.6], [0.5, 0.6]],  # better by half a point
    })
    design = Design(variants=["M0", "M1", "M2", "M3"], metrics=("CR_total",), margins={"CR_total": 0.3})
    table = verdict_table(rows, design)
    got = dict(zip(zip(table["scenario"], table["model"], strict=True), table["verdict"], strict=True))
    assert got == {("A", "M1"): "worse", ("A", "M2"): "equivalent", ("A", "M3"): "undecided",
                   ("B", "M1"): "better"}
    # Holm's family is the 4 comparisons of the study (M2 and M3 are absent from B)
    raw = table["p_difference"].to_numpy()
    assert table["p_difference_holm"].to_numpy() == pytest.approx(holm(raw))
    assert table["p_difference_holm"].max() <= 1 and (table["p_difference_holm"] >= raw).all()
    undecided = table[table["verdict"] == "undecided"].iloc[0]
    # at Holm's level for the first open comparison of each kind (alpha / 2 without a difference, alpha / 3
    # without equivalence): the engine's rule,
    # at least as many seeds as at alpha itself, and the easier of the two decisions
    a, b = [np.array([np.mean(s) for s in rows_of]) for rows_of in ([[1.0, 3.0], [0.2, 0.4], [2.0, 2.6], [0.1, 0.5], [3.0, 1.0]],
                                                                  [[1.0, 1.2], [1.1, 1.2], [1.0, 1.1], [1.2, 1.0], [1.1, 1.1]])]
    variances, d = [np.var(a, ddof=1), np.var(b, ddof=1)], a.mean() - b.mean()
    expected = min(n for n in (seeds_needed(d, variances, W, 0.05 / 2, 0.8),
                               seeds_needed(d, variances, W, 0.05 / 3, 0.8, margin=0.3)) if n is not None)
    assert undecided["seeds_needed"] == expected >= seeds_needed(d, variances, W, 0.05, 0.8) >= 2
    text = verdicts_markdown(table, design)
    assert "| A | CR_total (%) | M2 | 5/5 |" in text and "equivalent within ±0.3 pp" in text
    assert "undecided" in plan_text(plan_table(rows, design), design)


def test_design_rejects_unknown_metrics():
    from sigmarl.errors import SigmarlError

    with pytest.raises(SigmarlError, match="no verdicts for metric"):
        Design(variants=["M0"], metrics=("speed",))
    with pytest.raises(SigmarlError, match="no equivalence margin"):
        Design(variants=["M0"], metrics=("CD",), margins={"CR_total": 0.1})


def test_each_variant_against_its_own_baseline():
    """A 2 x 2 factorial (rules x strategy): M4-paper against M0-paper and M4 against M0, while
    M0 itself is compared with M0-paper; each difference against scipy's Welch test of the
    pair's own seed means and the comparison engine's p, Holm over the three."""
    seeds = {
        "M0-paper": [[2.0, 2.2], [2.4, 2.2], [2.1, 2.1], [2.3, 2.1], [2.2, 2.0]],
        "M4-paper": [[3.0, 3.2], [3.1, 3.3], [2.9, 3.1], [3.2, 3.0], [3.1, 3.1]],
        "M0": [[1.0, 1.2], [1.1, 1.3], [1.0, 1.2], [1.2, 1.2], [1.1, 1.0]],
        "M4": [[0.6, 0.8], [0.7, 0.5], [0.6, 0.6], [0.7, 0.7], [0.5, 0.6]],
    }
    rows = _rows({(m, "A"): v for m, v in seeds.items()})
    design = Design(variants=list(seeds), baseline="M0-paper", baselines={"M4": "M0"},
                    metrics=("CR_total",), margins={"CR_total": 0.1})
    table = verdict_table(rows, design)
    assert list(zip(table["model"], table["baseline"], strict=True)) == [
        ("M4-paper", "M0-paper"), ("M0", "M0-paper"), ("M4", "M0")]
    means = {m: np.array([np.mean(s) for s in v]) for m, v in seeds.items()}
    for _, r in table.iterrows():
        a, b = means[r["model"]], means[r["baseline"]]
        assert r["difference"] == pytest.approx(a.mean() - b.mean())
        assert welch(a, b, 0.1).p_difference == pytest.approx(stats.ttest_ind(a, b, equal_var=False).pvalue, rel=1e-6)
        # decided by the comparison engine, whose p is the largest over its null worlds: at least the
        # pooled world's, scipy's exact permutation test of Welch's t (252 splits)
        assert r["p_difference"] == comparison_test(a, b, 0.1).p_difference
        welch_t = lambda x, y, axis: (x.mean(axis) - y.mean(axis)) / np.sqrt(  # noqa: E731
            x.var(axis, ddof=1) / x.shape[axis] + y.var(axis, ddof=1) / y.shape[axis])
        exact = stats.permutation_test((a, b), welch_t, permutation_type="independent", n_resamples=np.inf,
                                       vectorized=True)
        assert r["p_difference"] >= exact.pvalue - 4 * MC_ERROR
    assert table["p_difference_holm"].to_numpy() == pytest.approx(holm(table["p_difference"].to_numpy()))
    assert list(table["verdict"]) == ["worse", "better", "better"]
    text = verdicts_markdown(table, design)
    assert text.startswith("Verdicts against each model's baseline")
    assert "| A | CR_total (%) | M4 vs M0 | 5/5 |" in text
    # one baseline for all: the table reads as before
    single = verdicts_markdown(verdict_table(rows, Design(variants=list(seeds), baseline="M0-paper")),
                               Design(variants=list(seeds), baseline="M0-paper"))
    assert single.startswith("Verdicts against M0-paper") and "| A | CR_total (%) | M4 | 5/5 |" in single
