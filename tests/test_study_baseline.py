"""A study's baseline that is neither M0 nor its first variant goes through the sweep's plan,
the report and the seed plan as declared. The rows: tests/data/results (M0 and M4, seeds 0 and
1) relabelled A (M0's rows) and B (M4's), with B the baseline; every number the test expects is
computed here from the rows themselves."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from cli_errors import one_line_exit_2

from sigmarl.cli import main

FIXTURE = Path(__file__).parent / "data" / "results"
STUDY = """# @package _global_
study:
  name: ab
  variants:
    A: [obs=full]
    B: [obs=no_distance_to_boundaries]
  baseline: {baseline}
"""


@pytest.fixture
def conf(tmp_path, monkeypatch):
    (tmp_path / "conf" / "study").mkdir(parents=True)
    for name, baseline in (("ab", "B"), ("ab_m0", "M0")):
        (tmp_path / "conf" / "study" / f"{name}.yaml").write_text(STUDY.format(baseline=baseline))
    monkeypatch.setenv("SIGMARL_CONFIG_PATH", str(tmp_path / "conf"))  # what --config-dir sets
    return tmp_path / "conf"


def _relabelled(tmp_path: Path) -> tuple[Path, pd.DataFrame]:
    root = tmp_path / "results"
    for old, new in (("M0", "A"), ("M4", "B")):
        for seed in (0, 1):
            run = root / new / f"seed{seed}"
            shutil.copytree(FIXTURE / old / f"seed{seed}", run)
            rows = pd.read_csv(run / "evaluation_rows.csv", float_precision="round_trip")
            rows.assign(model=new).to_csv(run / "evaluation_rows.csv", index=False)
    return root, pd.concat(pd.read_csv(p) for p in root.glob("*/seed*/evaluation_rows.csv"))


def test_the_report_compares_with_the_declared_baseline(tmp_path, conf):
    root, rows = _relabelled(tmp_path)
    out = tmp_path / "out"
    assert main(["report", "--from", str(root), "study=ab", "--no-figures", "--out", str(out),
                 "tracking.enabled=false"]) == 0
    assert next(ln for ln in (out / "table.md").read_text().splitlines() if ln.startswith("| Scenario")) == "| Scenario | Metric | A | B |"
    verdicts = pd.read_csv(out / "verdicts.csv")
    assert set(verdicts["model"]) == {"A"} and set(verdicts["baseline"]) == {"B"}
    # A's mean minus B's, in % of steps: the mean over seeds of each seed's mean
    seed_means = rows.groupby(["scenario", "model", "seed"])["CR_total"].mean().groupby(["scenario", "model"]).mean()
    cpm = verdicts[(verdicts["scenario"] == "CPM") & (verdicts["metric"] == "CR_total")].iloc[0]
    assert cpm["difference"] == pytest.approx(100 * (seed_means["CPM", "A"] - seed_means["CPM", "B"]), abs=1e-6)
    better = pd.read_csv(out / "improvement.csv")
    assert set(better["reference"]) == {"B"} and set(better["model"]) == {"A"}
    for _, row in better.iterrows():  # P(a simulation of a random seed of B beats one of A), ties half
        sc = rows[rows["scenario"] == row["scenario"]]
        b, a = ([g["CR_total"].to_numpy() for _, g in sc[sc["model"] == m].groupby("seed")] for m in "BA")
        p = np.mean([np.mean((x[:, None] < y[None, :]) + 0.5 * (x[:, None] == y[None, :])) for x in b for y in a])
        assert row["probability"] == pytest.approx(p, abs=1e-9)  # written to 10 digits


def test_the_seed_plan_takes_the_declared_baseline(tmp_path, conf, capsys):
    root, _ = _relabelled(tmp_path)
    assert main(["report", "--from", str(root), "--plan", "study=ab"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("Seed plan against B ")


def test_a_sweep_refuses_a_baseline_that_is_not_a_variant_before_any_job(tmp_path, conf, capsys):
    line = one_line_exit_2(["sweep", "study=ab_m0", f"runs_root={tmp_path}/runs", "tracking.enabled=false"], capsys)
    assert line == "sigmarl: error: study.baseline 'M0' is not one of the study's variants (A, B) nor a label a sweep derived from one"
    assert not (tmp_path / "runs").exists()
