"""The report's figures read at 1280 px: axes chosen from the data, grids not strips, and no
certainty drawn where one seed cannot give it."""

from __future__ import annotations

import matplotlib.image as mpimg
import numpy as np
import pandas as pd
import pytest

from sigmarl.report.figures import (
    ProfileAxis,
    plot_heatmap,
    plot_performance_profiles,
    profile_axis,
    profile_thresholds,
)


@pytest.mark.parametrize(("rates", "axis"), [
    # 0.08 .. 40 %: a log axis from the round number at or below the smallest rate (0.05) to the
    # one at or above the largest (50, from 40 x 1.02), its decades between as ticks (0.1 is
    # left out: within 3x of 0.05, its label would touch)
    ([0.0, 0.08, 40.0], ProfileAxis(True, 0.05, 50.0, (0.0, 0.05, 1.0, 10.0, 50.0))),
    ([0.0, 0.3, 18.0], ProfileAxis(True, 0.2, 20.0, (0.0, 0.2, 1.0, 10.0, 20.0))),
    # 0.3 .. 2 %: less than 20x apart, linear; steps of 0.5 (2.04 / 5 = 0.41 rounded up), to 2.5
    ([0.0, 0.3, 2.0], ProfileAxis(False, 2.5, 2.5, (0.0, 0.5, 1.0, 1.5, 2.0, 2.5))),
    ([0.0, 0.0], ProfileAxis(False, 1.0, 1.0, (0.0, 0.2, 0.4, 0.6, 0.8, 1.0))),  # nothing collided
    ([0.5], ProfileAxis(False, 0.6, 0.6, (0.0, 0.2, 0.4, 0.6))),  # one value: 0.51 / 5 -> steps of 0.2
])
def test_profile_axis_from_the_rates(rates, axis):
    got = profile_axis(np.array(rates))
    assert (got.log, got.linthresh, got.top) == (axis.log, pytest.approx(axis.linthresh), pytest.approx(axis.top))
    assert got.ticks == pytest.approx(axis.ticks)


def test_thresholds_follow_the_axis():
    taus = profile_thresholds(ProfileAxis(True, 0.05, 50.0, (0.0, 0.05, 1.0, 10.0, 50.0)))
    assert taus[0] == 0 and taus[-1] == pytest.approx(50.0) and 0.05 in taus
    assert np.all(np.diff(taus) > 0)
    assert np.sum(taus <= 0.05) == 21  # even steps up to the linear threshold
    linear = profile_thresholds(ProfileAxis(False, 2.5, 2.5, (0.0, 0.5, 1.0, 1.5, 2.0, 2.5)))
    assert linear[-1] == pytest.approx(2.5) and np.allclose(np.diff(linear), 2.5 / 200)


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
