"""The report's figures read at 1280 px: axes chosen from the data, grids not strips, and no
certainty drawn where one seed cannot give it."""

from __future__ import annotations

import matplotlib.image as mpimg
import numpy as np
import pandas as pd
import pytest

from sigmarl.report.exports.figures import (
    plot_heatmap,
    plot_performance_profiles,
    profile_axis,
    profile_thresholds,
)


@pytest.mark.parametrize(("rates", "axis"), [
    ([0.0, 0.08, 40.0], (0.05, 42.0)),  # the round number at or below the smallest rate: 5e-2
    ([0.0, 0.3, 2.0], (0.2, 2.1)),
    ([0.0, 0.0], (0.1, 1.0)),  # nothing collided: a default axis, not a division by zero
    ([0.5], (0.0525, 0.525)),  # one value: the linear part held to a tenth of the axis
])
def test_profile_axis_from_the_rates(rates, axis):
    assert profile_axis(np.array(rates)) == pytest.approx(axis)


def test_thresholds_follow_the_axis():
    taus = profile_thresholds(0.05, 42.0)
    assert taus[0] == 0 and taus[-1] == pytest.approx(42.0) and 0.05 in taus
    assert np.all(np.diff(taus) > 0)
    assert np.sum(taus <= 0.05) == 21  # even steps up to the linear threshold


def _rows(scenarios: list[str], models: list[str]) -> pd.DataFrame:
    rng = np.random.default_rng(0)
    return pd.DataFrame([{"model": m, "scenario": s, "seed": seed, "simulation": k,
                          "CR_total": rng.uniform(0, 0.05)} for m in models for s in scenarios
                         for seed in (0, 1) for k in range(4)])


def test_profiles_are_a_grid_readable_at_1280px(tmp_path):
    scenarios = ["CPM", "Intersection", "On-Ramp", "Roundabout"]
    path = plot_performance_profiles(_rows(scenarios, ["M0", "M4"]), ["M0", "M4"], scenarios, tmp_path / "p.png")
    height, width = mpimg.imread(path).shape[:2]
    assert width <= 1400 and height > width / 3  # five panels: 3 + 2, not a 2040 x 360 strip


def test_heatmap_splits_many_scenarios(tmp_path):
    scenarios = [f"map_{k}" for k in range(14)]
    models = [f"M{k}" for k in range(6)]
    summary = pd.DataFrame([{"metric": "CR_total", "model": m, "scenario": s, "mean": 0.5, "ci_low": 0.1,
                             "ci_high": 0.9} for m in models for s in scenarios])
    height, width = mpimg.imread(plot_heatmap(summary, models, scenarios, tmp_path / "h.png")).shape[:2]
    assert width <= 1400  # 7 scenarios a panel, stacked
    assert height > 700
