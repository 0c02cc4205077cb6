"""The report's per-seed table (`seeds.md`/`seeds.csv`): each model-seed's rates, speed and
reward windows, checked on hand-worked rows and curves and on a results folder."""

from __future__ import annotations

import warnings
from pathlib import Path

import pandas as pd
import pytest

from sigmarl.cli import main
from sigmarl.report.seeds import (
    reward_collisions,
    reward_windows,
    seed_table,
    seeds_markdown,
    spearman,
)

FIXTURE = Path(__file__).parent / "data" / "results"


def _row(model, seed, scenario, sim, aa, al, speed, cd=1.0):
    return {"model": model, "obs": "E,V,DA,DB,DC", "seed": seed, "scenario": scenario, "simulation": sim,
            "CR_AA": aa, "CR_AL": al, "CR_total": aa + al, "CD": cd, "AS": speed}


def test_seed_table_of_hand_worked_rows_and_curves():
    rows = pd.DataFrame([
        # M0 seed 0: CPM agent collisions 0.002 and 0.004 of steps -> 0.30 %; Roundabout lane 0.01 -> 1.00 %
        _row("M0", 0, "CPM", 0, 0.002, 0.0, 0.6, cd=1.5), _row("M0", 0, "CPM", 1, 0.004, 0.0, 0.7, cd=2.0),
        _row("M0", 0, "Roundabout", 0, 0.0, 0.01, 0.5), _row("M0", 0, "Roundabout", 1, 0.0, 0.01, 0.5),
        # M4 seed 3: no collisions at all
        _row("M4", 3, "CPM", 0, 0.0, 0.0, 0.7), _row("M4", 3, "Roundabout", 0, 0.0, 0.0, 0.72),
    ])
    # M0 seed 0 learns reward = iteration over 250 iterations; M4 seed 3 has no curve
    curves = pd.DataFrame({"model": "M0", "seed": 0, "iteration": range(1, 251),
                           "reward": [float(i) for i in range(1, 251)]})
    table = seed_table(rows, curves, ["M0", "M4"]).set_index(["model", "seed"])
    m0 = table.loc[("M0", 0)]
    assert m0["CR_total_CPM"] == pytest.approx(0.3) and m0["CR_AA_CPM"] == pytest.approx(0.3)
    assert m0["CR_AL_Roundabout"] == pytest.approx(1.0) and m0["CR_total_worst"] == pytest.approx(1.0)
    assert (m0["AS_min"], m0["AS_max"]) == pytest.approx((0.5, 0.65))
    assert (m0["CD_CPM"], m0["CD_Roundabout"]) == pytest.approx((1.75, 1.0))  # cm, as the rows hold it
    # the windows 51-75, 126-150, 226-250 of reward = iteration
    assert reward_windows(250) == [(51, 75), (126, 150), (226, 250)]
    assert [m0[f"reward_{i}"] for i in range(3)] == pytest.approx([63.0, 138.0, 238.0])
    assert pd.isna(table.loc[("M4", 3), "reward_0"]) and table.loc[("M4", 3), "CR_total_worst"] == 0
    text = seeds_markdown(table.reset_index(), ["CPM", "Roundabout"])
    assert "reward, iterations 51–75 / 126–150 / 226–250" in text  # the one training length there is
    assert "| M0 | 0 | 0.30 / 1.00 | 1.00 | 0.30 / 0.00 | 0.00 / 1.00 | 1.75 / 1.00 | 0.50–0.65 | 63.00 / 138.00 / 238.00 |" in text
    assert "| M4 | 3 | 0.00 / 0.00 | 0.00 | 0.00 / 0.00 | 0.00 / 0.00 | 1.00 / 1.00 | 0.70–0.72 | – / – / – |" in text


def test_rows_out_of_order_give_the_same_table_without_a_performance_warning():
    # rows in no order at all (several folders, shuffled): M4 and M0, seeds 0-2, two scenarios
    rows = pd.DataFrame([_row(m, s, sc, k, 0.001 * (s + 1), 0.0, 0.5 + 0.1 * s)
                         for m in ("M4", "M0") for s in (2, 0, 1) for sc in ("Roundabout", "CPM") for k in (1, 0)])
    rows = rows.sample(frac=1, random_state=0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # pandas' PerformanceWarning "indexing past lexsort depth"
        table = seed_table(rows, None, ["M0", "M4"])
    assert list(zip(table["model"], table["seed"], strict=True)) == [(m, s) for m in ("M0", "M4") for s in (0, 1, 2)]
    assert list(table["CR_total_CPM"]) == pytest.approx([0.1 * (s + 1) for _ in "ab" for s in range(3)])
    assert list(table["AS_max"]) == pytest.approx([0.5 + 0.1 * s for _ in "ab" for s in range(3)])


def test_short_trainings_have_windows_inside_them():
    assert reward_windows(10) == [(1, 3), (1, 6), (1, 10)]
    assert reward_windows(1) == [(1, 1), (1, 1), (1, 1)]


def test_folder_report_writes_the_seed_table(tmp_path):
    assert main(["report", "--from", str(FIXTURE), "--out", str(tmp_path), "--no-figures",
                 "tracking.enabled=false"]) == 0
    table = pd.read_csv(tmp_path / "seeds.csv")
    rows = pd.concat(pd.read_csv(p) for p in sorted(FIXTURE.glob("*/seed*/evaluation_rows.csv")))
    expected = rows.groupby(["model", "seed", "scenario"])["CR_total"].mean().mul(100)
    for r in table.to_dict("records"):
        for scenario in rows["scenario"].unique():
            assert r[f"CR_total_{scenario}"] == pytest.approx(expected[(r["model"], r["seed"], scenario)])
    assert len(table) == len(expected.droplevel("scenario").index.unique())
    # seeds of different training lengths: the windows are named as fractions of each one's training
    assert "reward at 30% / 60% / 100% of training" in seeds_markdown(
        pd.DataFrame([{**table.iloc[0], "iterations": 10}, {**table.iloc[1], "iterations": 250}]),
        list(rows["scenario"].unique()))
    assert (tmp_path / "seeds.md").read_text(encoding="utf-8").startswith("Each evaluated model-seed")


def test_spearman_agrees_with_scipy_ties_included():
    from scipy.stats import spearmanr

    x = pd.Series([3.2, 4.1, 4.1, 5.0, 2.2, 6.3, 5.5])
    y = pd.Series([0.9, 0.2, 0.4, 0.1, 0.9, 0.05, 0.3])
    rho, p = spearman(x, y)
    expected = spearmanr(x, y)
    assert rho == pytest.approx(expected.statistic, abs=1e-12)
    assert p == pytest.approx(expected.pvalue, rel=1e-6)
    assert all(pd.isna(v) for v in spearman(pd.Series([1.0, 1.0, 1.0]), pd.Series([1.0, 2.0, 3.0])))


def test_reward_and_collisions_of_hand_worked_seeds():
    # M0: 5 seeds whose collisions fall as their early reward rises (rho -1); M4: 5 seeds with
    # the reverse (rho +1); M2: 2 seeds, too few to be listed alone or pooled
    records = []
    for model, sign, n in [("M0", -1, 5), ("M4", 1, 5), ("M2", 1, 2)]:
        for seed in range(n):
            records.append({"model": model, "seed": seed, "CR_total_CPM": 1.0 + sign * seed,
                            "CR_total_Roundabout": 3.0 + sign * seed, "reward_0": float(seed),
                            "reward_1": 2.0, "reward_2": float(seed % 2)})
    corr = reward_collisions(pd.DataFrame(records), ["CPM", "Roundabout"]).set_index("models")
    assert list(corr.index) == ["M0", "M4", "M0 + M4"] and corr.loc["M0 + M4", "seeds"] == 10
    assert corr.loc["M0", "rho_0"] == pytest.approx(-1.0) and corr.loc["M0", "p_0"] == pytest.approx(0.0, abs=1e-12)
    assert corr.loc["M4", "rho_0"] == pytest.approx(1.0)
    assert pd.isna(corr.loc["M0", "rho_1"])  # a constant reward ranks nothing
    # pooled: CR_total means 2, 1, 0, -1, -2 (M0) and 2, 3, 4, 5, 6 (M4) against rewards 0..4 twice
    from scipy.stats import spearmanr

    expected = spearmanr([0, 1, 2, 3, 4] * 2, [2, 1, 0, -1, -2, 2, 3, 4, 5, 6])
    assert corr.loc["M0 + M4", "rho_0"] == pytest.approx(expected.statistic)
    assert corr.loc["M0 + M4", "p_0"] == pytest.approx(expected.pvalue, rel=1e-6)
