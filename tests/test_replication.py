"""The replication verdicts (`report.compare.replication`): every number of the table worked by hand
or by scipy, the rules on cases whose answer is known, and the published table against the
committed folder."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from sigmarl.report.compare.replication import (
    INTERACTION_COLUMNS,
    RANKING_COLUMNS,
    STRUCK,
    Replication,
    decide,
    difference_claims,
    one_sided,
    pair_position,
    ranking_claims,
    replication_markdown,
    replication_table,
    summary_line,
)
from sigmarl.report.tables import paper_values, struck_out
from sigmarl.stats.engine import Null, difference

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


def only_differences(table: pd.DataFrame) -> Replication:
    return Replication(table, pd.DataFrame(columns=RANKING_COLUMNS), pd.DataFrame(columns=INTERACTION_COLUMNS))


# ---- the two-seed-by-two-seed case, by hand ----

def test_two_by_two_pairs_by_hand():
    # pairs of (1, 3) minus (0, 1): 1, 0, 3, 2; 2.5 lies above three of four, one pair beyond it:
    # p = 2 (1 + 1) / (1 + 4)
    pct, p = pair_position(np.array([1.0, 3.0]), np.array([0.0, 1.0]), 2.5)
    assert pct == 75.0 and p == pytest.approx(0.8)
    assert pair_position(np.array([1.0, 3.0]), np.array([0.0, 1.0]), 1.0)[0] == 37.5  # tie counts half
    # beyond every pair: the smallest p four pairs allow, 2 / 5
    assert pair_position(np.array([1.0, 3.0]), np.array([0.0, 1.0]), 10.0) == (100.0, pytest.approx(0.4))


def test_one_sided_p_is_the_engines():
    rng = np.random.default_rng(7)
    a, b = rng.lognormal(0, 1, 4), rng.lognormal(0, 1, 5)
    record, sign = one_sided(a, b, -0.4)  # the paper's direction negative: tested on the negated seeds
    assert sign == -1.0
    direct = difference(-a, -b, {"smaller": Null(0.4, "less"), "direction": Null(0.0, "greater")})
    assert record.p["smaller"] == direct.p["smaller"] and record.p["direction"] == direct.p["direction"]


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
    # the paper: M4 collides more than M0 on CPM; here M4's 8 seeds all collide less than M0's 8
    claimed = paper_difference("CPM", "M4")
    assert claimed > 0
    rows = rows_of({("M0", "CPM"): [1.0, 1.1, 1.2, 1.3, 1.4, 1.5, 1.2, 1.3],
                    ("M4", "CPM"): [0.0, 0.01, 0.02, 0.03, 0.04, 0.05, 0.02, 0.03]})
    r = difference_claims(rows, ["M0", "M4"], "M0").iloc[0]
    assert r["paper"] == pytest.approx(claimed)
    assert r["ours"] == pytest.approx(0.025 - 1.25)
    assert r["seeds"] == "8/8"
    # beyond every one of 64 pairs: p = 2 / 65, one claim, so Holm leaves it: not seed luck
    assert r["pair_percentile"] == 100.0 and r["p_seed_luck"] == pytest.approx(2 / 65)
    assert r["p_reversed"] < 0.001 and r["verdict"] == "reversed"
    assert r["p_verdict"] == r["p_reversed"]  # the one test a reversal rests on
    assert r["explanation"] == "not seed luck"
    assert r["ci_low"] < r["ours"] < r["ci_high"] < 0


def test_not_reproduced_and_undecided_with_seeds_needed():
    # Intersection: the paper's M5 - M0 is +2.05 pp; ours sits at zero with a spread of 0.1 pp
    near_zero = [0.9, 1.0, 1.1, 0.95, 1.05, 1.0]
    rows = rows_of({("M0", "Intersection"): near_zero, ("M5", "Intersection"): near_zero[::-1],
                    ("M0", "CPM"): [0.2, 0.9, 0.4], ("M5", "CPM"): [0.5, 0.1, 0.9]}, spread=0.05)
    t = difference_claims(rows, ["M0", "M5"], "M0").set_index("scenario")
    assert t.loc["Intersection", "verdict"] == "not reproduced"
    assert t.loc["Intersection", "p_smaller"] < 0.01
    assert t.loc["Intersection", "p_verdict"] == t.loc["Intersection", "p_smaller"]
    assert t.loc["CPM", "verdict"] == "undecided"
    assert t.loc["CPM", "p_verdict"] == t.loc["CPM", "p_direction"]  # the paper's direction, not shown
    # +2.05 beyond all 36 pairs: p 2/37 = 0.054 unadjusted, so seed luck cannot be ruled out at 6 seeds
    assert t.loc["Intersection", "explanation"] == "seed luck"
    assert t.loc["CPM", "explanation"] == "seed luck"
    # 3 against 3 cannot decide; the seeds a decision needs are more, and finite
    assert not pd.isna(t.loc["CPM", "seeds_needed"]) and t.loc["CPM", "seeds_needed"] > 3


def test_one_seed_a_side_is_undecided_with_no_interval():
    rows = rows_of({("M0", "CPM"): [0.4], ("M5", "CPM"): [0.9], ("M0", "Intersection"): [0.5, 0.7],
                    ("M5", "Intersection"): [4.0]})
    t = difference_claims(rows, ["M0", "M5"], "M0")
    assert (t["verdict"] == "undecided").all() and t["ci_low"].isna().all() and t["seeds_needed"].isna().all()
    assert "[–]" in replication_markdown(only_differences(t))
    ranks = ranking_claims(rows_of({("M0", "CPM"): [0.4], ("M4", "CPM"): [9.0]}), ["M0", "M4"], n_boot=200)
    assert ranks["verdict"].tolist() == ["undecided"]


def test_struck_out_values_are_data_and_no_claim():
    # Table I's struck-out values, read from its csv: M1 on the three unseen scenarios, every metric
    assert {(s, m) for s, _, m in struck_out()} == {("Intersection", "M1"), ("On-Ramp", "M1"), ("Roundabout", "M1")}
    rows = rows_of({("M0", "On-Ramp"): [0.1, 0.2, 0.1], ("M1", "On-Ramp"): [40.0, 45.0, 42.0],
                    ("M0", "CPM"): [0.1, 0.2, 0.1], ("M1", "CPM"): [40.0, 45.0, 42.0]})
    t = difference_claims(rows, ["M0", "M1"], "M0").set_index("scenario")
    assert t.loc["On-Ramp", "verdict"] == STRUCK and math.isnan(t.loc["On-Ramp", "p_direction"])
    assert t.loc["On-Ramp", "ours"] == pytest.approx(42.333 - 0.1333, abs=1e-3)  # our number beside it
    assert t.loc["CPM", "verdict"] != STRUCK
    assert math.isnan(t.loc["On-Ramp", "p_verdict"])
    assert "1 more struck out by the paper" in summary_line(t.reset_index(), pd.DataFrame(columns=RANKING_COLUMNS))


def test_ranking_by_whole_seeds():
    # Intersection: M0 best on every metric in every seed; CPM: the paper's best is M4, and M0 wins here
    seeds = {("M0", "Intersection"): [0.1, 0.2, 0.1], ("M4", "Intersection"): [2.0, 2.5, 3.0],
             ("M0", "CPM"): [0.1, 0.2, 0.1], ("M4", "CPM"): [2.0, 2.5, 3.0]}
    t = ranking_claims(rows_of(seeds), ["M0", "M4"], n_boot=500).set_index("scenario")
    assert PAPER.loc[("CPM", "CS"), ["M0", "M4"]].idxmax() == "M4"
    assert t.loc["Intersection", "paper_best"] == "M0" and t.loc["Intersection", "share_first"] == 1.0
    assert t.loc["Intersection", "verdict"] == "reproduced"
    assert t.loc["CPM", "share_first"] == 0.0 and t.loc["CPM", "verdict"] == "not reproduced"
    assert t.loc["CPM", "most_often_first"] == "M0"


def test_ranking_share_of_an_even_race_is_near_half():
    # two seeds each, one better and one worse than the other model: whichever draw has the lower mean wins
    seeds = {("M0", "Intersection"): [0.0, 2.0], ("M4", "Intersection"): [1.0, 1.0]}
    share = ranking_claims(rows_of(seeds), ["M0", "M4"], n_boot=4000).iloc[0]["share_first"]
    # M0 ranks first when its draw holds seed 0 at least once but not only seed 1: draws (0,0), (0,1), (1,0)
    # give means 0, 1, 1 against M4's 1; CR ties leave CD and AS equal, scores equal, argmax picks M0
    assert share == pytest.approx(0.75, abs=0.03)


# ---- the published table ----

def test_published_replication_is_the_committed_folders():
    from sigmarl.results.folders import read_results

    rows = read_results(ROOT / "results" / "paper-budget").rows
    found = replication_table(rows, ["M0", "M1", "M2", "M3", "M4", "M5"])
    table = found.differences
    claims = table[table["verdict"] != STRUCK]
    assert len(claims) == 17 and (table["verdict"] == STRUCK).sum() == 3 and len(found.rankings) == 4
    assert table["verdict"].notna().all() and found.rankings["verdict"].notna().all()
    page = (ROOT / "docs" / "results" / "paper-study.md").read_text(encoding="utf-8")
    assert replication_markdown(found) in page
    # every claim's paper number is Table I's
    for _, r in table.iterrows():
        assert r["paper"] == pytest.approx(paper_difference(r["scenario"], r["model"]))
    assert list(itertools.islice(table["scenario"], 1)) == ["CPM"]


def test_summary_counts_each_verdict():
    differences = pd.DataFrame({"seeds": ["5/14", "6/14", "14/14"], "verdict": ["reversed", "undecided", "undecided"]})
    rankings = pd.DataFrame({"seeds": [14], "verdict": ["reproduced"]})
    assert summary_line(differences, rankings) == ("Summary (5–14 seeds a model). Of the paper's 3 CR_total differences: "
                                   "1 reversed; 2 undecided. Of the paper's 1 best-score rankings: 1 reproduced.")
    one = pd.DataFrame({"seeds": ["1/1"], "verdict": ["undecided"]})
    assert summary_line(one, rankings.iloc[:0]).startswith("Summary (1 seed a model). ")  # the quick study
