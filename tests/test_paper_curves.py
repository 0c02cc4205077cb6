"""The paper's training curves (Fig. 5) shipped with the package, against figures read off
the paper's Fig. 5, and drawn beside ours when comparing with the paper."""

from __future__ import annotations

import pandas as pd
import pytest

from sigmarl.report.figures import plot_training_curves
from sigmarl.report.tables import paper_curves


def test_shipped_curves_hold_the_quoted_figures():
    curves = paper_curves()
    assert sorted(curves["model"].unique()) == ["M0", "M1", "M2", "M3", "M4", "M5"]
    assert curves.groupby("model")["iteration"].max().eq(250).all()
    last25 = curves[curves["iteration"] > 225].groupby("model")["reward"].mean()
    # the paper's Fig. 5 curves: M0 averages 5.30 over its last 25 iterations, M3 2.66, M1 -0.39.
    assert last25["M0"] == pytest.approx(5.30, abs=0.005)
    assert last25["M3"] == pytest.approx(2.66, abs=0.005)
    assert last25["M1"] == pytest.approx(-0.39, abs=0.005)


def test_training_curves_figure_with_the_papers(tmp_path):
    ours = pd.DataFrame({"model": "M0", "iteration": [1, 2, 3], "reward": [-0.6, 0.1, 0.9]})
    path = plot_training_curves(ours, tmp_path / "curves.png", ["M0"], paper=paper_curves())
    assert path.stat().st_size > 1000
