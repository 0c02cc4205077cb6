"""Where a next seed lands and how many seeds are slow (report/seeds.py), against hand-worked
numbers and a simulation of normal seeds, where the prediction interval is exact."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from sigmarl.report.seeds import next_seed_markdown, prediction_table, slow_seed_table


def _seeds(model: str, values: list[float], scenario: str = "CPM") -> pd.DataFrame:
    return pd.DataFrame({"model": model, "seed": range(len(values)), f"CR_total_{scenario}": values,
                         "CR_total_worst": values})


def test_prediction_interval_by_hand():
    # x = 1, 2, 3: mean 2, s 1, t_{0.975, 2} = 4.30265, sqrt(1 + 1/3) = 1.15470 -> half 4.96827
    row = prediction_table(_seeds("M0", [1.0, 2.0, 3.0]), ["CPM"]).iloc[0]
    assert row["pi_high"] == pytest.approx(2 + 4.96827, abs=1e-4)
    assert row["pi_low"] == 0.0  # 2 - 4.97 clipped: a rate
    assert (row["min"], row["max"], row["range_coverage"]) == (1.0, 3.0, 0.5)


def test_one_seed_gives_no_interval():
    assert prediction_table(_seeds("M0", [1.0]), ["CPM"]).empty


def test_normal_seeds_next_seed_lands_inside_95_percent():
    rng = np.random.default_rng(3)
    hits, trials = 0, 2000
    for _ in range(trials):
        x = 10 + rng.standard_normal(6)  # far from 0: the clip never acts
        row = prediction_table(_seeds("M0", list(x)), ["CPM"]).iloc[0]
        nxt = 10 + rng.standard_normal()
        hits += row["pi_low"] <= nxt <= row["pi_high"]
    assert abs(hits / trials - 0.95) < 0.015  # Monte Carlo SE 0.005


def test_fisher_exact_by_hand():
    # M1 4 slow of 4 against M0 1 of 14: P(table) = C(5,4) C(13,0) / C(18,4) = 5/3060, the most
    # extreme table, and every other is more likely, so the two-sided p is 5/3060
    seeds = pd.concat([_seeds("M0", [0.1] * 13 + [2.0]), _seeds("M1", [40.0] * 4)])
    row = slow_seed_table(seeds, {"M1": "M0"}, 1.0).iloc[0]
    assert (row["slow"], row["seeds"], row["baseline_slow"], row["baseline_seeds"]) == (4, 4, 1, 14)
    assert row["p_fisher"] == pytest.approx(5 / math.comb(18, 4), rel=1e-9)


def test_no_threshold_no_slow_seed_table():
    seeds = pd.concat([_seeds("M0", [0.1, 2.0]), _seeds("M1", [3.0, 4.0])])
    assert slow_seed_table(seeds, {"M1": "M0"}, 0.0).empty
    text = next_seed_markdown(prediction_table(seeds, ["CPM"]), slow_seed_table(seeds, {"M1": "M0"}, 0.0), ["CPM"])
    assert "prediction interval" in text and "Slow seeds" not in text
