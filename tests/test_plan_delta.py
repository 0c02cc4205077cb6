"""The planner's seeds for the study's margin, by the engine's seeds-needed rule, against independent
numbers: scipy's noncentral t on normal seeds, a direct simulation on skewed ones (where the rule,
Welch's, promises too few seeds, as docs/concepts.md says), and the plan's interval, the verdict's own."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from permutation_reference import permutation_p
from scipy import stats

from sigmarl.cli import main
from sigmarl.report.compare.verdicts import Design
from sigmarl.report.plan import plan_table
from sigmarl.stats.engine import Null, difference, seeds_needed

W = (1.0, -1.0)


def _t_test_n(effect: float, alpha: float = 0.05, target: float = 0.8) -> int:
    """Seeds per side for a two-sided two-sample t-test (equal variances), from scipy's nct."""
    for n in range(2, 2000):
        df, nc = 2 * n - 2, effect * math.sqrt(n / 2)
        crit = stats.t.ppf(1 - alpha / 2, df)
        if stats.nct.sf(crit, df, nc) + stats.nct.cdf(-crit, df, nc) >= target:
            return n
    raise AssertionError("no n")


@pytest.mark.parametrize("effect", [0.6, 1.0, 1.5])
def test_on_normal_seeds_the_rules_n_is_the_t_tests(effect) -> None:
    assert seeds_needed(effect, [1.0, 1.0], W, 0.05, 0.8) == _t_test_n(effect)


def test_on_seeds_like_ours_welch_promises_too_few() -> None:
    """One seed in ten five times worse (as our collision rates): at the rule's n (Welch's) a direct
    simulation on fresh draws shows a test of the difference falling short of its power."""
    seeds = np.array([1.0] * 9 + [5.0])
    sd = seeds.std(ddof=1)
    delta = 2.5 * sd
    n = seeds_needed(delta, [sd ** 2, sd ** 2], W, 0.05, 0.8)
    rng = np.random.default_rng(7)
    fresh = rng.choice(seeds, size=(400, 2, n))
    p, _ = permutation_p(fresh[:, 0] + delta, fresh[:, 1], 0.1, draws=199, seed=3)
    assert np.mean(p <= 0.05) < 0.8  # at Welch's n the test falls short of its power


def test_equivalence_needs_a_true_difference_inside_the_margin_and_seeds_are_deterministic() -> None:
    rng = np.random.default_rng(2)
    a, b = rng.standard_normal(30) * 0.05, rng.standard_normal(30) * 0.05
    v = [np.var(a, ddof=1), np.var(b, ddof=1)]
    assert seeds_needed(0.2, v, W, 0.05, 0.8, margin=0.1) is None
    first = seeds_needed(0.0, v, W, 0.05, 0.8, margin=0.1)
    assert first == seeds_needed(0.0, v, W, 0.05, 0.8, margin=0.1) and first >= 2


def test_the_plans_interval_and_seeds_are_the_verdicts_engines() -> None:
    rng = np.random.default_rng(3)
    a, b = rng.standard_normal(8) + 1.0, rng.standard_normal(8)
    rows = pd.DataFrame([{"model": m, "scenario": "S", "seed": s, "simulation": 0, "CR_total": v / 100, "CD": 1.0,
                          "AS": 0.7} for m, xs in (("M1", a), ("M0", b)) for s, v in enumerate(xs)])
    design = Design(variants=["M0", "M1"], margins={"CR_total": 0.5})
    r = plan_table(rows, design).iloc[0]
    engine = difference(a, b, {"zero": Null(0.0)}, 0.95)
    assert (r["ci_low"], r["ci_high"]) == pytest.approx((engine.ci_low, engine.ci_high))
    assert r["ci_low"] < a.mean() - b.mean() < r["ci_high"]
    v = [np.var(a, ddof=1), np.var(b, ddof=1)]
    assert r["seeds_detect_margin"] == seeds_needed(0.5, v, W, 0.05, 0.8)
    assert r["seeds_equivalent_at_zero"] == seeds_needed(0.0, v, W, 0.05, 0.8, margin=0.5)
    one = plan_table(rows[(rows["model"] == "M0") | (rows["seed"] == 0)], design).iloc[0]  # one seed of M1
    assert one["verdict"] == "undecided" and math.isnan(one["ci_low"]) and pd.isna(one["seeds_detect_margin"])


def test_plan_prints_the_margins_seeds(capsys) -> None:
    assert main(["report", "--from", "tests/data/results", "--plan", "tracking.enabled=false"]) == 0
    out = capsys.readouterr().out
    assert "detect δ" in out and "equiv. d=0" in out and "equiv. d=obs." in out
    assert "margin δ: CR_total ±0.1 pp" in out
