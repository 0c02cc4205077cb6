"""Training curves compared (`report.compare.curves`): window means, the comparison engine per window against the
baseline with Holm's correction, where the curves part, and the paper's one seed against our
prediction interval; checked on hand-worked numbers, scipy and a results folder."""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from sigmarl.ablation import flags_of, paper_model
from sigmarl.cli import main
from sigmarl.report.compare.curves import (
    curve_verdicts_markdown,
    paper_seed_table,
    parting,
    separation_table,
    window_means,
)
from sigmarl.report.compare.verdicts import Design
from sigmarl.stats.engine import Null, difference

FIXTURE = Path(__file__).parent / "data" / "results"


def _curves(model: str, seed: int, rewards) -> pd.DataFrame:
    return pd.DataFrame({"model": model, "seed": seed, "iteration": range(1, len(rewards) + 1),
                         "reward": [float(r) for r in rewards]})


def test_window_means_leave_out_an_unfinished_window():
    curves = _curves("M0", 0, list(range(1, 8)))  # 7 iterations, windows of 3: 1-3, 4-6, (7)
    means = window_means(curves, window=3)
    assert means["first"].tolist() == [1, 4] and means["last"].tolist() == [3, 6]
    assert means["reward"].tolist() == [2.0, 5.0]


def test_separation_is_the_engine_per_window_against_the_baseline_with_holm():
    # window 1: no difference; window 2: every variant seed above every baseline seed
    v1, b1 = [0.0, 1.0, 0.0, 1.0, 0.5], [0.5, 0.0, 1.0, 0.2, 0.4]
    v2, b2 = [10.0, 11.0, 12.0, 10.5, 11.5], [0.0, 0.0, 1.0, 0.5, 0.2]
    curves = pd.concat([_curves("M4", s, [v1[s], v2[s]]) for s in range(5)]
                       + [_curves("M0", s, [b1[s], b2[s]]) for s in range(5)])
    table = separation_table(curves, Design(variants=["M0", "M4"], baseline="M0"), window=1).set_index("first")
    for first, (a, b) in {1: (v1, b1), 2: (v2, b2)}.items():
        direct = difference(a, b, {"zero": Null(0.0)})
        assert table.loc[first, "difference"] == pytest.approx(np.mean(a) - np.mean(b))
        assert table.loc[first, "p_difference"] == direct.p["zero"]
        assert (table.loc[first, "ci_low"], table.loc[first, "ci_high"]) == (direct.ci_low, direct.ci_high)
        # at least scipy's exact permutation test of Welch's t, one of the engine's null worlds
        ref = stats.permutation_test((a, b), lambda x, y: stats.ttest_ind(x, y, equal_var=False).statistic,
                                     permutation_type="independent", n_resamples=np.inf).pvalue
        assert table.loc[first, "p_difference"] >= ref - 0.002
    p1, p2 = table["p_difference"]
    assert p1 > 0.05 and p2 < 0.025  # Holm over the two: the smaller p doubled
    assert table.loc[2, "p_difference_holm"] == pytest.approx(2 * p2)
    assert table["verdict"].tolist() == ["undecided", "higher"]


def test_parting_is_the_first_window_of_the_last_unbroken_decided_run():
    def table(verdicts):
        return pd.DataFrame({"model": "M4", "baseline": "M0", "first": [1 + 25 * i for i in range(len(verdicts))],
                             "verdict": verdicts})

    assert parting(table(["undecided", "lower", "undecided", "lower", "lower"])) == {("M4", "M0"): (76, "lower")}
    assert parting(table(["higher", "higher"])) == {("M4", "M0"): (1, "higher")}
    assert parting(table(["higher", "undecided"])) == {("M4", "M0"): None}
    assert parting(table(["lower", "higher"])) == {("M4", "M0"): (26, "higher")}


def test_a_rows_paper_model_is_read_from_its_flags():
    """The report reads a column's paper model from the flags its rows record (`obs`)."""
    assert paper_model(flags_of("E,V,DA,DB,DC")) == "M0"
    assert paper_model(flags_of("V,DA,DB,DC")) == "M1"
    assert paper_model(flags_of("E,V,DA,DC")) == "M4"
    assert paper_model(flags_of("E,V,DA,DB")) == "M5"
    assert paper_model(flags_of("E,V")) is None and paper_model(flags_of("")) is None


def test_the_paper_seed_against_the_prediction_interval_for_one_more_seed():
    summary = pd.DataFrame({"model": ["M0", "M0", "M0", "M4"], "seed": [0, 1, 2, 0],
                            "reward_last": [5.0, 6.0, 7.0, 4.0]})
    table = paper_seed_table(summary, {"M0": 12.0, "M4": 4.3}, {"M0": "M0", "M4": "M4"}).set_index("variant")
    # mean 6, s 1, n 3: 6 +- t(0.975, 2) * sqrt(1 + 1/3)
    half = stats.t.ppf(0.975, 2) * math.sqrt(4 / 3)
    assert (table.loc["M0", "pi_low"], table.loc["M0", "pi_high"]) == pytest.approx((6 - half, 6 + half), rel=1e-5)
    assert table.loc["M0", "verdict"] == "above"  # 12 > 10.97
    assert table.loc["M4", "verdict"] == "one seed" and np.isnan(table.loc["M4", "pi_low"])
    inside = paper_seed_table(summary, {"M0": 6.5}, {"M0": "M0", "M4": None})
    assert inside["verdict"].tolist() == ["within"]


def test_against_the_paper_a_variant_is_read_on_the_papers_definition_where_every_seed_has_it():
    summary = pd.DataFrame({"model": ["M0", "M0", "M4", "M4"], "seed": [0, 1, 0, 1],
                            "reward_last": [5.0, 6.0, 4.0, 5.0],
                            "reward_complete_last": [5.5, 6.5, 4.6, math.nan]})
    table = paper_seed_table(summary, {"M0": 6.0, "M4": 4.5}, {"M0": "M0", "M4": "M4"}).set_index("variant")
    assert table.loc["M0", "reward"] == "complete" and table.loc["M0", "mean"] == pytest.approx(6.0)
    # one seed of M4 trained before the estimate: the variant stays on our definition
    assert table.loc["M4", "reward"] == "batch-cut" and table.loc["M4", "mean"] == pytest.approx(4.5)
    text = curve_verdicts_markdown(pd.DataFrame(), table.reset_index(), Design(variants=["M0", "M4"], baseline="M0"))
    assert "| M0 | M0 | complete | 2 | 6.00 |" in text and "| M4 | M4 | batch-cut | 2 | 4.50 |" in text
    assert "counts every episode whole" in text


def test_a_folder_report_writes_when_the_curves_part(tmp_path):
    source = tmp_path / "results"
    shutil.copytree(FIXTURE, source)
    rng = np.random.default_rng(0)
    for model, level in [("M0", 5.0), ("M4", 4.0)]:
        for seed in (0, 1):
            path = source / model / f"seed{seed}" / "metrics.csv"
            head = pd.read_csv(path).iloc[[0]]
            metrics = pd.concat([head] * 50, ignore_index=True)
            metrics["iteration"] = range(1, 51)
            # the same rise for both, M4 one lower throughout, a little noise per seed
            metrics["episode_reward_mean"] = np.linspace(0, 2, 50) + level + rng.normal(0, 0.01, 50)
            if model == "M4":  # trained since the estimate: a column of the paper's definition
                metrics["episode_reward_mean_complete"] = metrics["episode_reward_mean"] + 0.5
            metrics.to_csv(path, index=False)
    out = tmp_path / "out"
    assert main(["report", "--from", str(source), "--out", str(out), "--no-figures", "--compare-paper",
                 "tracking.enabled=false"]) == 0
    separation = pd.read_csv(out / "curve_verdicts.csv")
    assert separation["first"].tolist() == [1, 26]
    assert separation["difference"].to_numpy() == pytest.approx([-1.0, -1.0], abs=0.02)
    text = (out / "curve_verdicts.md").read_text()
    # two seeds a side: the engine's pooled world has 6 splits, so no p goes under 2/6 and the
    # curves, one apart throughout, cannot be said to part (Welch's t on two seeds did say so); a p
    # that far above 0.05 is drawn to a Monte Carlo error of at most 0.0023
    assert "| M4 | M0 | undecided |" in text and (separation["p_difference"] >= 1 / 3 - 4 * 0.0023).all()
    seeds = pd.read_csv(out / "paper_seeds.csv").set_index("variant")
    assert seeds.loc["M4", "paper"] == pytest.approx(4.33, abs=0.01) and seeds.loc["M4", "seeds"] == 2
    assert seeds.loc["M4", "reward"] == "complete" and seeds.loc["M0", "reward"] == "batch-cut"
    assert seeds.loc["M4", "mean"] == pytest.approx(4.0 + 2 * 37 / 49 + 0.5, abs=0.02)  # iterations 26..50
