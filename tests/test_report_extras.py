"""Performance profiles, the seed-bootstrap band, the marl-eval export and `--plan`."""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from sigmarl.cli import main
from sigmarl.report.marl_eval import interval_data, marl_eval_data
from sigmarl.stats.bootstrap import profile, profile_replicates, seed_band

FIXTURE = Path(__file__).parent / "data" / "results"


def test_profile_hand_worked():
    # seed 0: 0, 0.5, 1; seed 1: 1, 1. Above 0: 2/3 and 1 -> 5/6; above 0.5: 1/3 and 1 -> 2/3;
    # above 1: none. Seeds weigh equally, not simulations (pooled it would be 4/5 at 0).
    groups = [np.array([0.0, 0.5, 1.0]), np.array([1.0, 1.0])]
    assert profile(groups, np.array([0.0, 0.5, 1.0])) == pytest.approx([5 / 6, 2 / 3, 0.0])


def test_profile_replicates_centre_on_the_profile():
    rng = np.random.default_rng(0)
    groups = [rng.exponential(0.3, 32) * (rng.random(32) < 0.4) for _ in range(3)]
    taus = np.array([0.0, 0.1, 0.5])
    reps = profile_replicates(groups, taus, 4000, np.random.default_rng(1))
    # resampling seeds then simulations leaves each fraction's expectation unchanged (equal sizes)
    assert reps.mean(0) == pytest.approx(profile(groups, taus), abs=0.01)
    assert ((reps >= 0) & (reps <= 1)).all()


def test_seed_band_is_the_exact_bootstrap_interval():
    # three seeds 1, 2, 6: the 27 equally likely resamples put 1/27 = 3.7 % on a mean of 1 and
    # as much on 6, more than the 2.5 % each tail: the exact percentile interval is [1, 6]
    values = np.array([[1.0, 2.0, 6.0], [0.0, 0.0, 3.0]])
    mean, lo, hi = seed_band(values, 20000, np.random.default_rng(2))
    assert mean == pytest.approx([3.0, 1.0])
    assert lo == pytest.approx([1.0, 0.0]) and hi == pytest.approx([6.0, 3.0])
    exact = sorted(np.mean(c) for c in itertools.product([1.0, 2.0, 6.0], repeat=3))
    assert exact.count(1.0) / len(exact) > 0.025 and exact.count(6.0) / len(exact) > 0.025


def _rows() -> pd.DataFrame:
    rng = np.random.default_rng(3)
    return pd.DataFrame([
        {"model": m, "seed": s, "scenario": sc, "simulation": j, "CR_total": rng.random() / 100,
         "CR_AA": 0.0, "CR_AL": 0.0, "CD": 1.0 + rng.random(), "AS": 0.7}
        for m in ("M0", "M4") for s in (0, 1, 2) for sc in ("CPM", "Roundabout") for j in range(4)
    ])


def test_marl_eval_structure_and_values():
    rows = _rows()
    curves = pd.DataFrame({"model": "M0", "seed": [0, 0], "iteration": [1, 250], "reward": [0.0, 1.0]})
    data = json.loads(json.dumps(marl_eval_data(rows, ["M0", "M4"], curves), allow_nan=False))
    run = data["sigmarl"]["Roundabout"]["M4"]["run_2"]
    mine = rows[(rows.model == "M4") & (rows.seed == 2) & (rows.scenario == "Roundabout")]
    assert run["absolute_metrics"]["CD"] == pytest.approx(mine["CD"].tolist())
    assert run["step_0"]["step_count"] == 0  # no curve for M4
    assert data["sigmarl"]["CPM"]["M0"]["run_0"]["step_0"]["step_count"] == 250
    assert set(data["sigmarl"]["CPM"]["M0"]) == {"run_0", "run_1", "run_2"}


def test_marl_eval_intervals_use_the_real_n_and_t():
    rows = _rows()
    out = interval_data(rows, ["M0", "M4"])
    entry = out["tasks"]["CPM"]["M4"]["CD"]
    seed_means = rows[(rows.model == "M4") & (rows.scenario == "CPM")].groupby("seed")["CD"].mean()
    low, high = stats.t.interval(0.95, len(seed_means) - 1, seed_means.mean(), stats.sem(seed_means))
    assert entry["n"] == 3 and entry["z"] == pytest.approx(stats.t.ppf(0.975, 2))  # 4.303, not 1.96
    assert entry["mean"] - entry["half_width"] == pytest.approx(low)
    assert entry["mean"] + entry["half_width"] == pytest.approx(high)


def test_plan_prints_each_comparison(capsys):
    assert main(["report", "--from", str(FIXTURE), "--plan"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("Seed plan against M0")
    lines = [line for line in out.splitlines() if line.startswith(("CPM ", "Roundabout "))]
    assert len(lines) == 2 and all(" M4 " in line and "2/2" in line for line in lines)


def test_plan_needs_a_folder(capsys):
    assert main(["report", "--plan"]) == 2
    assert capsys.readouterr().err.strip() == "sigmarl: error: --plan reads a results folder: give it with --from FOLDER"
