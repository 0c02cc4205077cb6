"""The planner's seeds for the study's margin, simulated with the verdict's own permutation test,
against independent numbers: scipy's noncentral t on normal seeds, a direct simulation on
skewed ones, and the permutation p at the interval's ends."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from sigmarl.cli import main
from sigmarl.stats import planning
from sigmarl.stats.permutation import permutation_p
from sigmarl.stats.power import seeds_for_difference


def _t_test_n(effect: float, alpha: float = 0.05, target: float = 0.8) -> int:
    """Seeds per side for a two-sided two-sample t-test (equal variances), from scipy's nct."""
    for n in range(2, 2000):
        df, nc = 2 * n - 2, effect * math.sqrt(n / 2)
        crit = stats.t.ppf(1 - alpha / 2, df)
        if stats.nct.sf(crit, df, nc) + stats.nct.cdf(-crit, df, nc) >= target:
            return n
    raise AssertionError("no n")


@pytest.mark.parametrize("effect", [0.6, 1.0, 1.5])
def test_on_normal_seeds_the_simulated_n_is_the_t_tests(effect) -> None:
    rng = np.random.default_rng(1)
    a, b = rng.standard_normal(400), rng.standard_normal(400)
    a, b = (a - a.mean()) / a.std(ddof=1), (b - b.mean()) / b.std(ddof=1)  # unit-variance sources
    simulated = planning.seeds_for(a, b, effect, margin=0.1, alpha=0.05, target=0.8, kind="difference")
    reference = _t_test_n(effect)
    assert abs(simulated - reference) <= max(2, 0.15 * reference), (simulated, reference)


def test_on_seeds_like_ours_welch_promises_too_few() -> None:
    """One seed in ten five times worse (as our collision rates): Welch's formula asks for fewer
    seeds than the permutation test needs; a direct simulation on fresh draws confirms it."""
    seeds = np.array([1.0] * 9 + [5.0])
    sd = seeds.std(ddof=1)
    delta = 2.5 * sd
    welch = seeds_for_difference(delta, sd ** 2, sd ** 2, 0.05, 0.8)
    simulated = planning.seeds_for(seeds, seeds, delta, margin=0.1, alpha=0.05, target=0.8, kind="difference")
    assert simulated > welch
    rng = np.random.default_rng(7)
    fresh = rng.choice(seeds, size=(400, 2, welch))
    p, _ = permutation_p(fresh[:, 0] + delta, fresh[:, 1], 0.1, draws=199, seed=3)
    assert np.mean(p <= 0.05) < 0.8  # at Welch's n the test falls short of its power


def test_equivalence_needs_a_true_difference_inside_the_margin_and_seeds_are_deterministic() -> None:
    rng = np.random.default_rng(2)
    a, b = rng.standard_normal(30) * 0.05, rng.standard_normal(30) * 0.05
    assert planning.seeds_for(a, b, 0.2, 0.1, 0.05, 0.8, "equivalence") is None
    first = planning.seeds_for(a, b, 0.0, 0.1, 0.05, 0.8, "equivalence")
    assert first == planning.seeds_for(a, b, 0.0, 0.1, 0.05, 0.8, "equivalence") and first >= 2


def test_the_interval_is_where_the_permutation_test_keeps_the_shift() -> None:
    rng = np.random.default_rng(3)
    a, b = rng.standard_normal(8) + 1.0, rng.standard_normal(8)
    low, high = planning.shift_interval(a, b)
    d = a.mean() - b.mean()
    assert low < d < high
    p0, _ = permutation_p(a, b, 0.0)
    assert (low > 0 or high < 0) == (float(p0) <= 0.05)
    for end, outward in ((low, -1), (high, 1)):
        inside, _ = permutation_p(a - (end - outward * 1e-3 * (high - low)), b, 0.0)
        outside, _ = permutation_p(a - (end + outward * 0.05 * (high - low)), b, 0.0)
        assert float(inside) > 0.05 >= float(outside)
    assert planning.shift_interval([1.0, 2.0], [0.0, 0.5]) == (-math.inf, math.inf)  # 6 splits: p >= 1/3


def test_plan_prints_the_margins_seeds(capsys) -> None:
    assert main(["report", "--from", "tests/data/results", "--plan", "tracking.enabled=false"]) == 0
    out = capsys.readouterr().out
    assert "detect δ" in out and "equiv. d=0" in out and "equiv. d=obs." in out
    assert "margin δ: CR_total ±0.1 pp" in out
