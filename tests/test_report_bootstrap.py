"""Seed-aware statistics against hand-worked numbers, scipy, and a coverage simulation."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from sigmarl.report.cells import cells, composite_scores, summarise
from sigmarl.report.scores import aggregate_scores, composite_intervals, improvement
from sigmarl.stats import bootstrap as bs


def g(*seeds: list[float]) -> list[np.ndarray]:
    """Per-seed groups of one metric as [n, 1] arrays."""
    return [np.asarray(s, float)[:, None] for s in seeds]


def test_seed_level_mean_weighs_seeds_equally():
    # seed 0: 1, 2, 3 (mean 2); seed 1: 10 (mean 10): (2 + 10) / 2 = 6 (pooled: 16 / 4 = 4)
    assert bs.point_estimate(g([1, 2, 3], [10]))[0] == pytest.approx(6.0)
    # NaN (a trimmed simulation) is left out of its seed's mean: seed 0 -> (1 + 3) / 2
    assert bs.point_estimate(g([1, np.nan, 3], [4]))[0] == pytest.approx(3.0)


def test_intervals_collapse_to_the_point_without_spread():
    rng = np.random.default_rng(0)
    for groups in (g([0.7]), g([0.25, 0.25], [0.25]), g([3.0, 3.0, 3.0], [3.0, 3.0, 3.0], [3.0, 3.0, 3.0])):
        reps = bs.mean_over_seeds(bs.replicate_means(groups, 500, rng))
        lo, hi = bs.percentile_interval(reps)
        point = bs.point_estimate(groups)
        assert lo == pytest.approx(point, rel=1e-12) and hi == pytest.approx(point, rel=1e-12)


def test_two_seeds_of_one_value_each_span_the_seeds():
    # seeds 1 and 3, one simulation each: a replicate draws two seeds with replacement, means
    # 1 (p 1/4), 2 (1/2), 3 (1/4): the 95% interval is [1, 3], the estimate 2.
    groups = g([1.0], [3.0])
    reps = bs.mean_over_seeds(bs.replicate_means(groups, 4000, bs.rng_for("t")))[:, 0]
    assert set(np.unique(reps)) == {1.0, 2.0, 3.0}
    assert np.mean(reps == 2.0) == pytest.approx(0.5, abs=0.03)
    assert bs.percentile_interval(reps) == pytest.approx((1.0, 3.0))


def test_one_seed_matches_scipy_percentile_bootstrap():
    stats = pytest.importorskip("scipy.stats")
    x = np.random.default_rng(3).exponential(1.0, 32)
    reps = bs.mean_over_seeds(bs.replicate_means(g(list(x)), 20000, bs.rng_for("scipy")))[:, 0]
    lo, hi = bs.percentile_interval(reps)
    ref = stats.bootstrap((x,), np.mean, n_resamples=20000, method="percentile",
                          random_state=np.random.default_rng(1)).confidence_interval
    width = ref.high - ref.low
    assert lo == pytest.approx(ref.low, abs=0.03 * width) and hi == pytest.approx(ref.high, abs=0.03 * width)


def _coverage(n_seeds: int, n_sims: int, seed_level: bool, trials: int = 150) -> float:
    """Fraction of 95% intervals that hold the true mean 0 when seeds differ (sd 1) more than
    simulations within a seed (sd 0.3)."""
    rng = np.random.default_rng(7)
    hits = 0
    for _ in range(trials):
        effects = rng.normal(0, 1, n_seeds)
        groups = [rng.normal(e, 0.3, (n_sims, 1)) for e in effects]
        if not seed_level:  # the naive scheme: all simulations pooled as one "seed"
            groups = [np.concatenate(groups)]
        lo, hi = bs.percentile_interval(bs.mean_over_seeds(bs.replicate_means(groups, 400, rng)))
        hits += bool(lo[0] <= 0 <= hi[0])
    return hits / trials


def test_coverage_comes_from_the_seeds():
    # With 12 seeds the two-level interval covers close to 95%; pooling the simulations as if
    # independent ignores the seed-to-seed spread and covers far less.
    assert 0.85 <= _coverage(12, 8, seed_level=True) <= 1.0
    assert _coverage(12, 8, seed_level=False) < 0.6


def test_probability_of_improvement_by_hand():
    # x 0, 1 against y 1, 2: pairs (0,1) (0,2) (1,2) win, (1,1) ties: 3.5 / 4
    assert bs.probability_of_improvement(g([0, 1]), g([1, 2])) == pytest.approx(0.875)
    # y's seeds weigh equally: against seed [1] x=0 wins (1), against seed [0, 0, 0] it ties
    # (0.5): (1 + 0.5) / 2 = 0.75 (pooling the four simulations would give 0.625)
    assert bs.probability_of_improvement(g([0]), g([1], [0, 0, 0])) == pytest.approx(0.75)
    # the reverse comparison is the complement
    assert bs.probability_of_improvement(g([1], [0, 0, 0]), g([0])) == pytest.approx(0.25)


def test_probability_of_improvement_equals_the_double_sum():
    # an independent, literal implementation: every pair of simulations, seed weights
    rng = np.random.default_rng(5)
    x = [rng.integers(0, 4, n).astype(float) for n in (5, 3, 7)]  # small integers: many ties
    y = [rng.integers(0, 4, n).astype(float) for n in (4, 6)]
    total = 0.0
    for xs in x:
        for ys in y:
            pairs = [(a < b) + 0.5 * (a == b) for a in xs for b in ys]
            total += sum(pairs) / len(pairs)
    expected = total / (len(x) * len(y))
    got = bs.probability_of_improvement([v[:, None] for v in x], [v[:, None] for v in y])
    assert got == pytest.approx(expected, abs=1e-12)


def test_probability_of_improvement_interval_collapses():
    rng = bs.rng_for("poi")
    ties = bs.bootstrap_improvement(g([0, 0], [0]), g([0, 0, 0]), 300, rng)
    assert ties == pytest.approx(np.full(300, 0.5), abs=1e-12)
    wins = bs.bootstrap_improvement(g([0, 0.1], [0.2]), g([1, 2], [3]), 300, rng)
    assert wins == pytest.approx(np.ones(300), abs=1e-12)


def test_iqm_by_hand():
    assert bs.iqm(np.array([100.0, 1.0, 3.0, 2.0, 4.0])) == pytest.approx(3.0)  # cut 1 each end
    assert bs.iqm(np.array([1.0, 2.0, 3.0, 4.0])) == pytest.approx(2.5)
    # 13 values a row: floor(13 / 4) = 3 cut from each end, the middle 7 averaged (sorted by hand)
    x = np.random.default_rng(0).normal(size=(5, 13))
    assert bs.iqm(x, axis=-1) == pytest.approx(np.sort(x, axis=-1)[:, 3:10].mean(axis=-1))
    x[2, 4] = np.nan  # a replicate that drew no finite value: NaN, which the interval then skips
    assert np.isnan(bs.iqm(x, axis=-1)[2]) and np.isfinite(bs.iqm(x, axis=-1)[[0, 1, 3, 4]]).all()


def _rows(spec: dict[tuple[str, str, int], list[tuple[float, float, float]]]) -> pd.DataFrame:
    """(model, scenario, seed) -> per simulation (CR_total, CD, AS); CR_AA = CR_total."""
    recs = []
    for (model, scenario, seed), sims in spec.items():
        for k, (cr, cd, speed) in enumerate(sims):
            recs.append({"model": model, "obs": "x", "seed": seed, "scenario": scenario, "simulation": k,
                         "CR_AA": cr, "CR_AL": 0.0, "CR_total": cr, "CD": cd, "AS": speed})
    return pd.DataFrame(recs)


def test_improvement_per_scenario_by_hand():
    # CPM: M0 collides 0 and 0.01 in seed 0, 0 in seed 1; M1 0.01 and 0.02 in its one seed.
    # M0 seed 0 vs M1: (0<.01, 0<.02, .01=.01 half, .01<.02) = 3.5/4; seed 1: 2/2 -> 0.9375
    rows = _rows({
        ("M0", "CPM", 0): [(0.0, 1, 0.5), (0.01, 1, 0.5)],
        ("M0", "CPM", 1): [(0.0, 1, 0.5)],
        ("M1", "CPM", 0): [(0.01, 1, 0.5), (0.02, 1, 0.5)],
    })
    out = improvement(rows, ["M0", "M1"], n_boot=200)
    assert out[["scenario", "reference", "model"]].values.tolist() == [["CPM", "M0", "M1"]]
    assert out["probability"].iloc[0] == pytest.approx(0.9375)
    # one seed of M1: no interval from resampling whole seeds (shown as –)
    assert np.isnan(out["ci_low"].iloc[0]) and np.isnan(out["ci_high"].iloc[0])
    assert (out["n_seeds_reference"].iloc[0], out["n_seeds_model"].iloc[0]) == (2, 1)
    # a second seed of M1 (0.02 against every M0 simulation: 1 each): an interval around the estimate
    rows = pd.concat([rows, _rows({("M1", "CPM", 1): [(0.02, 1, 0.5)]})], ignore_index=True)
    out = improvement(rows, ["M0", "M1"], n_boot=200)
    assert 0.0 <= out["ci_low"].iloc[0] <= out["probability"].iloc[0] <= out["ci_high"].iloc[0] <= 1.0


def test_aggregate_scores_and_cs_intervals():
    # Two scenarios, two models, two seeds each; the per-scenario CS are worked out by the
    # composite module from the estimates, the aggregate mean must be their mean over
    # scenarios, and the IQM of four (scenario, seed) scores is the mean of the middle two.
    spec = {}
    for scenario, shift in [("CPM", 0.0), ("Intersection", 0.005)]:
        spec[("M0", scenario, 0)] = [(0.01 + shift, 2.0, 0.6)]
        spec[("M0", scenario, 1)] = [(0.02 + shift, 2.2, 0.6)]
        spec[("M1", scenario, 0)] = [(0.03 + shift, 2.0, 0.5)]
        spec[("M1", scenario, 1)] = [(0.05 + shift, 2.6, 0.5)]
    rows = _rows(spec)
    cell_list = cells(rows, ["M0", "M1"], n_boot=500)
    composite = composite_scores(summarise(cell_list))
    agg = aggregate_scores(cell_list, composite, ["M0", "M1"]).set_index(["model", "statistic"])
    cs = composite.set_index(["scenario", "model"])["CS"]
    for model in ("M0", "M1"):
        assert agg.at[(model, "mean"), "value"] == pytest.approx(cs.xs(model, level="model").mean())
        assert agg.at[(model, "mean"), "n_runs"] == 4 and agg.at[(model, "mean"), "n_scenarios"] == 2
    # M0 in CPM: normalisers CR 2.75 (%), CD 2.2, AS 0.55; seed scores
    # -1/2.75 - 2/2.2 + .6/.55 = -0.18182 and -2/2.75 - 2.2/2.2 + .6/.55 = -0.63636
    # Intersection: CR normaliser 3.25: -1.5/3.25 - 2/2.2 + .6/.55 = -0.27972, -2.5/3.25 - 1 + .6/.55
    # = -0.67832. Middle two of the four: (-0.27972 - 0.63636) / 2 = -0.45804
    assert agg.at[("M0", "IQM"), "value"] == pytest.approx(-0.45804, abs=1e-5)
    intervals = composite_intervals(cell_list, composite).set_index(["scenario", "model"])
    lo, hi = intervals.loc[("CPM", "M0"), ["ci_low", "ci_high"]]
    # two seeds of one simulation: the interval spans the two seed scores
    assert (lo, hi) == pytest.approx((-0.63636, -0.18182), abs=1e-5)
