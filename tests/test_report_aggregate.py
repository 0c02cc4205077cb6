"""Aggregation over simulations and seeds, the t quantiles behind its CIs, trimming."""

from __future__ import annotations

import math

import pandas as pd
import pytest

from sigmarl.errors import SigmarlError
from sigmarl.report.cells import aggregate
from sigmarl.stats.bootstrap import mean_ci, t_critical

T_975_DF2 = 4.302653  # Student t, 97.5% quantile, 2 degrees of freedom (printed tables)


def _rows(model="M0", scenario="CPM", seed=0, **columns) -> pd.DataFrame:
    n = len(next(iter(columns.values())))
    base = {"CR_AA": [0.0] * n, "CR_AL": [0.0] * n, "CD": [1.0] * n, "AS": [0.5] * n}
    base.update(columns)
    base.setdefault("CR_total", [a + b for a, b in zip(base["CR_AA"], base["CR_AL"], strict=True)])
    return pd.DataFrame(
        {
            "model": model,
            "obs": "full",
            "seed": seed,
            "scenario": scenario,
            "simulation": range(n),
            **base,
        }
    )


def _cell(summary: pd.DataFrame, metric: str, model="M0", scenario="CPM") -> pd.Series:
    hit = summary[
        (summary.metric == metric) & (summary.model == model) & (summary.scenario == scenario)
    ]
    assert len(hit) == 1
    return hit.iloc[0]


@pytest.mark.parametrize(
    ("df", "level", "published"),
    [(1, 0.95, 12.706), (2, 0.95, 4.303), (5, 0.95, 2.571), (10, 0.95, 2.228), (30, 0.95, 2.042),
     (31, 0.95, 2.040), (120, 0.95, 1.980), (5, 0.99, 4.032), (20, 0.90, 1.725), (5000, 0.95, 1.960)],
)  # fmt: skip
def test_t_critical_matches_printed_tables(df, level, published):
    assert t_critical(df, level) == pytest.approx(published, abs=6e-4)


def test_mean_ci_of_three_values_by_hand():
    # 2, 4, 9: mean 5, s = sqrt((9 + 1 + 16) / 2) = sqrt(13), half = 4.302653 · sqrt(13) / sqrt(3).
    mean, half, std, n = mean_ci([2.0, 4.0, 9.0, math.nan])
    assert (mean, n) == (5.0, 3)
    assert std == pytest.approx(math.sqrt(13))
    assert half == pytest.approx(T_975_DF2 * math.sqrt(13) / math.sqrt(3), rel=1e-6)
    assert math.isnan(mean_ci([3.0])[1])


def test_collision_rates_in_percent_with_interval():
    # CR_total 1, 2, 3 % of steps, one seed: mean 2 %. The bootstrap resamples the three
    # simulations; "all three at the minimum" has probability 1/27 = 3.7% > 2.5%, so the
    # 95% percentile interval runs from the smallest to the largest value: [1, 3] %.
    rows = _rows(CR_AA=[0.01, 0.02, 0.03], CD=[2.0, 4.0, 9.0])
    s = aggregate(rows)
    cr = _cell(s, "CR_total")
    assert cr["mean"] == pytest.approx(2.0)
    assert (cr["ci_low"], cr["ci_high"]) == pytest.approx((1.0, 3.0))
    assert cr["unit"] == "percent" and cr["n"] == 3 and not cr["trimmed"]
    assert cr["std"] == pytest.approx(1.0)
    cd = _cell(s, "CD")
    assert cd["mean"] == pytest.approx(5.0) and (cd["ci_low"], cd["ci_high"]) == pytest.approx((2.0, 9.0))


def test_trim_drops_the_best_and_worst_simulation_for_collision_rates_only():
    # CR_total 0, 1, 2, 3, 10 %: without the lowest and highest, mean (1 + 2 + 3) / 3 = 2 %.
    # Sim 4 (worst total) has the lowest CR_AA, yet the same two simulations leave CR_AA:
    # CR_AA over sims 1-3 = (1 + 1 + 3) / 3 % = 5/3 %, and CR_total = CR_AA + CR_AL still.
    rows = _rows(
        CR_AA=[0.00, 0.01, 0.01, 0.03, 0.00],
        CR_AL=[0.00, 0.00, 0.01, 0.00, 0.10],
        CD=[1.0, 2.0, 3.0, 4.0, 5.0],
    )
    s = aggregate(rows, trim=True)
    assert _cell(s, "CR_total")["mean"] == pytest.approx(2.0)
    assert _cell(s, "CR_total")["n"] == 3 and _cell(s, "CR_total")["trimmed"]
    assert _cell(s, "CR_AA")["mean"] == pytest.approx(5 / 3)
    assert _cell(s, "CR_AL")["mean"] == pytest.approx(1 / 3)
    assert _cell(s, "CD")["mean"] == pytest.approx(3.0) and _cell(s, "CD")["n"] == 5
    untrimmed = aggregate(rows)
    assert _cell(untrimmed, "CR_total")["mean"] == pytest.approx(16 / 5)


def test_trim_is_per_seed_and_skips_tiny_evaluations():
    # Seed 0: 0, 5, 10 % -> 5 % (one left);  seed 1 has only two simulations: kept whole,
    # mean 3 %. Seeds weigh equally: (5 + 3) / 2 = 4 % (pooled it would be 11/3 %).
    rows = pd.concat(
        [_rows(seed=0, CR_AA=[0.0, 0.05, 0.10]), _rows(seed=1, CR_AA=[0.02, 0.04])],
        ignore_index=True,
    )
    cr = _cell(aggregate(rows, trim=True), "CR_total")
    assert cr["n"] == 3 and cr["n_seeds"] == 2 and cr["mean"] == pytest.approx(4.0)


def test_seeds_are_pooled_and_their_spread_reported():
    # AS seed 0: 0.5, 0.7 (mean 0.6); seed 1: 0.7, 0.9 (mean 0.8). Pooled mean 0.7 over 4;
    # spread of the seed means: s = sqrt((0.1² + 0.1²) / 1) = 0.141421.
    rows = pd.concat(
        [_rows(seed=0, AS=[0.5, 0.7]), _rows(seed=1, AS=[0.7, 0.9])], ignore_index=True
    )
    a = _cell(aggregate(rows), "AS")
    assert a["mean"] == pytest.approx(0.7) and a["n"] == 4 and a["n_seeds"] == 2
    assert a["seed_std"] == pytest.approx(0.141421, abs=1e-6)
    assert math.isnan(_cell(aggregate(_rows(AS=[0.5, 0.7])), "AS")["seed_std"])


def test_model_order_and_selection():
    rows = pd.concat(
        [_rows(model=m, AS=[0.5]) for m in ["M3", "custom_1", "M0"]], ignore_index=True
    )
    assert list(dict.fromkeys(aggregate(rows)["model"])) == ["M0", "M3", "custom_1"]
    assert list(dict.fromkeys(aggregate(rows, ["custom_1", "M3"])["model"])) == ["custom_1", "M3"]
    with pytest.raises(SigmarlError, match="M7"):
        aggregate(rows, ["M0", "M7"])


def test_extra_columns_are_ignored():
    rows = _rows(CR_AA=[0.01, 0.03]).assign(CR_AA_per_agent_step=[0.001, 0.002])
    assert set(aggregate(rows)["metric"]) == {"CR_AA", "CR_AL", "CR_total", "CD", "AS"}


@pytest.mark.parametrize("rows", [None, pd.DataFrame(), _rows(AS=[0.5]).iloc[0:0]])
def test_no_rows_is_a_clear_error(rows):
    with pytest.raises(SigmarlError, match="no finished evaluation runs"):
        aggregate(rows)


def test_missing_metric_column_is_named():
    with pytest.raises(SigmarlError, match="CD"):
        aggregate(_rows(AS=[0.5]).drop(columns="CD"))
