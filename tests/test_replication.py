"""The replication verdicts (`report.compare.replication`): every number of the table worked by hand
or by scipy, the rules on cases whose answer is known, and the published table against the
committed folder."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from sigmarl.report.compare.replication import (
    decide,
    difference_claims,
    pair_position,
    ranking_claims,
    replication_markdown,
    replication_table,
    summary_line,
)
from sigmarl.report.table.paper import paper_values
from sigmarl.stats.one_sided import greater_p, less_p

ROOT = Path(__file__).resolve().parents[1]
PAPER = paper_values()


def paper_difference(scenario: str, model: str) -> float:
    return float(PAPER.loc[(scenario, "CR_total"), model] - PAPER.loc[(scenario, "CR_total"), "M0"])


def rows_of(seed_means: dict[tuple[str, str], list[float]], cd: float = 1.0, speed: float = 0.7,
            spread: float = 0.0) -> pd.DataFrame:
    """Evaluation rows whose CR_total seed means (in %) are given: one simulation per seed, or
    (spread) two, at the mean -+ spread."""
    records = []
    for (model, scenario), values in seed_means.items():
        for seed, v in enumerate(values):
            for sim, x in enumerate([v - spread, v + spread] if spread else [v]):
                records.append({"model": model, "obs": "", "seed": seed, "scenario": scenario, "simulation": sim,
                                "CR_AA": x / 100, "CR_AL": 0.0, "CR_total": x / 100, "CD": cd, "AS": speed})
    return pd.DataFrame(records)


# ---- the two-seed-by-two-seed case, by hand ----

def test_two_by_two_pairs_by_hand():
    # pairs of (1, 3) minus (0, 1): 1, 0, 3, 2; 2.5 lies above three of four
    pct, low, high = pair_position(np.array([1.0, 3.0]), np.array([0.0, 1.0]), 2.5)
    assert pct == 75.0
    # numpy's linear percentiles of 0, 1, 2, 3: the 2.5th at 0.075, the 97.5th at 2.925
    assert low == pytest.approx(0.075) and high == pytest.approx(2.925)
    assert pair_position(np.array([1.0, 3.0]), np.array([0.0, 1.0]), 1.0)[0] == 37.5  # tie counts half
    assert pair_position(np.array([1.0, 3.0]), np.array([0.0, 1.0]), 10.0)[0] == 100.0  # beyond every pair


def test_two_by_two_permutation_p_by_hand():
    a, b = [1.0, 3.0], [0.0, 1.0]
    # the 6 splits of (1, 3, 0, 1): differences +1.5, -1.5, -0.5, +0.5, +1.5, -1.5; observed +1.5
    assert greater_p(a, b) == pytest.approx(2 / 6)
    # moved by 1: (0, 2, 0, 1) splits to +0.5, -1.5, -0.5, +0.5, +1.5, -0.5; observed +0.5
    assert greater_p(a, b, shift=1.0) == pytest.approx(3 / 6)
    # less: -1.5 and below, observed +1.5 is the largest but one: 6 of 6 at or below it
    assert less_p(a, b) == pytest.approx(1.0)
    # moved by 2: (-1, 1, 0, 1) splits to -0.5, -1.5, -0.5, +0.5, +1.5, +0.5; observed -0.5
    assert less_p(a, b, shift=2.0) == pytest.approx(3 / 6)


@pytest.mark.parametrize("statistic", ["difference", "welch"])
@pytest.mark.parametrize("shift", [0.0, 0.4])
def test_one_sided_p_is_scipys_exact_permutation_test(statistic, shift):
    rng = np.random.default_rng(7)
    a, b = rng.lognormal(0, 1, 4), rng.lognormal(0, 1, 5)

    def stat(x, y, axis):
        if statistic == "difference":
            return x.mean(axis) - y.mean(axis)
        return (x.mean(axis) - y.mean(axis)) / np.sqrt(x.var(axis, ddof=1) / x.shape[axis] + y.var(axis, ddof=1) / y.shape[axis])

    for alternative, ours in (("greater", greater_p), ("less", less_p)):
        ref = stats.permutation_test((a - shift, b), stat, permutation_type="independent", alternative=alternative,
                                     n_resamples=np.inf, vectorized=True).pvalue
        assert ours(a, b, shift, statistic) == pytest.approx(ref, abs=1e-12), alternative


# ---- the rules ----

@pytest.mark.parametrize("p, expected", [
    ({"direction": 0.01, "reversed": 1, "smaller": 1, "larger": 1}, "reproduced"),
    ({"direction": 0.01, "reversed": 1, "smaller": 0.01, "larger": 1}, "reproduced, smaller"),
    ({"direction": 0.01, "reversed": 1, "smaller": 1, "larger": 0.01}, "reproduced, larger"),
    ({"direction": 0.3, "reversed": 0.5, "smaller": 0.01, "larger": 1}, "not reproduced"),
    ({"direction": 1, "reversed": 0.01, "smaller": 0.01, "larger": 1}, "reversed"),
    ({"direction": 0.3, "reversed": 0.5, "smaller": 0.2, "larger": 1}, "undecided"),
])
def test_verdict_rules(p, expected):
    assert decide(p, 0.05) == expected


def test_reversed_claim_and_paper_outside_our_range():
    # the paper: M4 collides more than M0 on CPM; here M4's 6 seeds all collide less than M0's 6
    claimed = paper_difference("CPM", "M4")
    assert claimed > 0
    rows = rows_of({("M0", "CPM"): [1.0, 1.1, 1.2, 1.3, 1.4, 1.5], ("M4", "CPM"): [0.0, 0.01, 0.02, 0.03, 0.04, 0.05]})
    r = difference_claims(rows, ["M0", "M4"], "M0").iloc[0]
    assert r["paper"] == pytest.approx(claimed)
    assert r["ours"] == pytest.approx(0.025 - 1.25)
    assert r["pair_percentile"] == 100.0 and not r["paper_inside_pairs"]  # beyond every pair: not seed luck
    # reversed: the observed split is the most extreme of C(12, 6) = 924; one claim, Holm leaves it
    assert r["p_reversed_holm"] == pytest.approx(1 / 924)
    assert r["verdict"] == "reversed"
    assert r["explanation"] == "not seed luck"


def test_not_reproduced_and_undecided_with_seeds_needed():
    # Intersection: the paper's M5 - M0 is +2.05 pp; ours sits at zero with a spread of 0.1 pp
    near_zero = [0.9, 1.0, 1.1, 0.95, 1.05, 1.0]
    rows = rows_of({("M0", "Intersection"): near_zero, ("M5", "Intersection"): near_zero[::-1],
                    ("M0", "CPM"): [0.2, 0.9, 0.4], ("M5", "CPM"): [0.5, 0.1, 0.9]}, spread=0.05)
    t = difference_claims(rows, ["M0", "M5"], "M0").set_index("scenario")
    assert t.loc["Intersection", "verdict"] == "not reproduced"
    assert t.loc["Intersection", "p_smaller"] == pytest.approx(1 / 924)  # every split below +2.05
    assert t.loc["CPM", "verdict"] == "undecided"  # 3 against 3 seeds cannot decide at all
    # +2.05 beyond every pair of near-zero seeds; CPM's +0.25 inside pairs spread over +-0.8
    assert t.loc["Intersection", "explanation"] == "not seed luck"
    assert t.loc["CPM", "explanation"] == "seed luck"
    # 3 against 3 cannot decide; the seeds a decision needs are more, and finite
    assert not pd.isna(t.loc["CPM", "seeds_needed"]) and t.loc["CPM", "seeds_needed"] > 3


def test_ranking_by_whole_seeds():
    # Intersection: M0 best on every metric in every seed; CPM: the paper's best is M4, and M0 wins here
    seeds = {("M0", "Intersection"): [0.1, 0.2, 0.1], ("M4", "Intersection"): [2.0, 2.5, 3.0],
             ("M0", "CPM"): [0.1, 0.2, 0.1], ("M4", "CPM"): [2.0, 2.5, 3.0]}
    t = ranking_claims(rows_of(seeds), ["M0", "M4"], n_boot=500).set_index("scenario")
    assert PAPER.loc[("CPM", "CS"), ["M0", "M4"]].idxmax() == "M4"
    assert t.loc["Intersection", "model"] == "M0" and t.loc["Intersection", "probability_first"] == 1.0
    assert t.loc["Intersection", "verdict"] == "reproduced"
    assert t.loc["CPM", "probability_first"] == 0.0 and t.loc["CPM", "verdict"] == "not reproduced"
    assert t.loc["CPM", "most_often_first"] == "M0"


def test_ranking_share_of_an_even_race_is_near_half():
    # two seeds each, one better and one worse than the other model: whichever draw has the lower mean wins
    seeds = {("M0", "Intersection"): [0.0, 2.0], ("M4", "Intersection"): [1.0, 1.0]}
    share = ranking_claims(rows_of(seeds), ["M0", "M4"], n_boot=4000).iloc[0]["probability_first"]
    # M0 ranks first when its draw holds seed 0 at least once but not only seed 1: draws (0,0), (0,1), (1,0)
    # give means 0, 1, 1 against M4's 1; CR ties leave CD and AS equal, scores equal, argmax picks M0
    assert share == pytest.approx(0.75, abs=0.03)


# ---- the published table ----

def test_published_replication_is_the_committed_folders():
    from sigmarl.report.inputs.folder import read_results

    rows = read_results(ROOT / "results" / "paper-budget").rows
    table = replication_table(rows, ["M0", "M1", "M2", "M3", "M4", "M5"])
    assert (table["claim"] == "difference").sum() == 20 and (table["claim"] == "ranking").sum() == 4
    assert table["verdict"].notna().all()
    page = (ROOT / "docs" / "results" / "paper-study.md").read_text(encoding="utf-8")
    assert replication_markdown(table) in page
    # every claim's paper number is Table I's
    for _, r in table[table["claim"] == "difference"].iterrows():
        assert r["paper"] == pytest.approx(paper_difference(r["scenario"], r["model"]))
    assert list(itertools.islice(table["scenario"], 1)) == ["CPM"]


def test_summary_counts_each_verdict():
    table = pd.DataFrame({"claim": ["difference"] * 3 + ["ranking"], "n_model": [5, 6, 14, 14],
                          "n_baseline": [14, 14, 14, pd.NA],
                          "verdict": ["reversed", "undecided", "undecided", "reproduced"]})
    assert summary_line(table) == ("Summary (5–14 seeds a model). Of the paper's 3 CR_total differences: "
                                   "1 reversed; 2 undecided. Of the paper's 1 best-score rankings: 1 reproduced.")
