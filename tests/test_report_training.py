"""The report's training summary (`training.md`/`training.csv`): per-seed final and best reward,
iterations and compute time, checked on hand-worked curves and on a results folder."""

from __future__ import annotations

import shutil
from pathlib import Path

import pandas as pd
import pytest

from sigmarl.cli import main
from sigmarl.report.tables import paper_curves
from sigmarl.report.training import (
    LAST,
    paper_last_rewards,
    training_markdown,
    training_summary,
)

FIXTURE = Path(__file__).parent / "data" / "results"


def test_summary_of_hand_worked_curves():
    # seed 0: reward = iteration over 30 iterations, 6 s each; seed 1: 10 iterations of 2.0, 3 s each
    curves = pd.concat([
        pd.DataFrame({"model": "M0", "seed": 0, "iteration": range(1, 31), "reward": [float(i) for i in range(1, 31)],
                      "seconds": 6.0}),
        pd.DataFrame({"model": "M0", "seed": 1, "iteration": range(1, 11), "reward": 2.0, "seconds": 3.0}),
    ])
    summary = training_summary(curves, ["M0"]).set_index("seed")
    assert LAST == 25
    assert summary.loc[0, "reward_last"] == pytest.approx(sum(range(6, 31)) / 25)  # iterations 6..30
    assert summary.loc[0, "reward_best"] == 30 and summary.loc[0, "iterations"] == 30
    assert summary.loc[0, "compute_min"] == pytest.approx(3.0)  # 30 x 6 s
    assert summary.loc[1, "reward_last"] == 2.0 and summary.loc[1, "compute_min"] == pytest.approx(0.5)
    text = training_markdown(summary.reset_index(), {"M0": 5.3})
    assert "| M0 | 2 | 18.00 / 2.00 | 10.00 (5.30) | 30 / 10 | 3 / 0 |" in text
    assert "Training compute of the 2 model-seeds: 0.1 h" in text  # 3.5 min


def test_paper_last_rewards_are_the_mean_of_fig5_last_iterations():
    paper = paper_curves()
    m0 = paper[paper["model"] == "M0"].sort_values("iteration")
    assert m0["iteration"].max() == 250
    expected = m0[m0["iteration"] > 250 - LAST]["reward"].mean()
    assert paper_last_rewards(paper)["M0"] == pytest.approx(expected)
    assert set(paper_last_rewards(paper)) == {f"M{i}" for i in range(6)}


def test_folder_report_sums_each_iterations_timings_once(tmp_path):
    source = tmp_path / "results"
    shutil.copytree(FIXTURE, source)
    path = source / "M0" / "seed0" / "metrics.csv"
    metrics = pd.read_csv(path)
    metrics = metrics.assign(time_collect_s=1.0, time_advantage_s=0.5, time_optimise_s=4.5)
    # a resumed run logs the iterations after its checkpoint again: the last record counts
    resumed = pd.concat([metrics, metrics.tail(2).assign(time_optimise_s=10.5)], ignore_index=True)
    resumed.to_csv(path, index=False)
    n = len(metrics)
    assert main(["report", "--from", str(source), "--out", str(tmp_path / "out"), "--no-figures",
                 "tracking.enabled=false"]) == 0
    training = pd.read_csv(tmp_path / "out" / "training.csv").set_index(["model", "seed"])
    assert training.loc[("M0", 0), "iterations"] == n
    assert training.loc[("M0", 0), "compute_min"] == pytest.approx(((n - 2) * 6 + 2 * 12) / 60)
    assert pd.isna(training.loc[("M4", 1), "compute_min"])  # the fixture's metrics carry no timings
    text = (tmp_path / "out" / "training.md").read_text()
    assert "| M4 | 2 |" in text and "| – / – |" in text
    assert "(5.30)" not in text  # no paper column without --compare-paper
