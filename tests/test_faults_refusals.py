"""Fourth reliability round, G5, G8, G9: a command that could do nothing meaningful with what
it was given refuses in one line (exit 2) before any training or evaluation starts."""

from __future__ import annotations

from pathlib import Path

import pytest
from cli_errors import one_line_exit_2

PAPER_RUN = Path(__file__).resolve().parents[1] / "results" / "paper-budget" / "M0" / "seed0"


def test_g5_seeds_auto_with_only_its_baseline_refuses_before_training(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    line = one_line_exit_2(["sweep", "seeds=auto", "study=quick", "models=[M0]", "study.seeds=[0,1]",
                            "tracking.enabled=false", f"runs_root={tmp_path / 'runs'}"], capsys)
    assert "nothing to compare" in line and "0 variant(s) beside the baseline M0" in line
    assert not (tmp_path / "runs").exists()  # not one seed trained


@pytest.mark.parametrize("override", ["obs=no_ego_view", "env.n_agents=3", "seed=4", "+ppo.lr=1e-3"])
def test_g9_evaluate_refuses_an_override_it_would_drop(override, capsys):
    line = one_line_exit_2(["evaluate", str(PAPER_RUN), override, "eval.n_sims=1", "tracking.enabled=false"],
                           capsys)
    assert f"evaluate cannot honour {override}" in line and "eval.*" in line


def test_g9_evaluate_still_takes_what_it_honours(tmp_path, capsys):
    # a wrong scenario is answered after the overrides are accepted: the honoured ones pass the check
    line = one_line_exit_2(["evaluate", str(PAPER_RUN), "eval.n_sims=1", "threads=1", "device=cpu",
                            "tracking.enabled=false", "study=quick", "--scenario", "Nowhere"], capsys)
    assert "cannot honour" not in line and "Nowhere" in line


def test_g8_a_plan_over_no_metric_is_refused(capsys):
    line = one_line_exit_2(["report", "--plan", "--from", str(PAPER_RUN.parents[1]), "study.metrics=[]"], capsys)
    assert "study.metrics is empty" in line


@pytest.mark.parametrize("name", [".hidden", "-rf", "a b", "x" * 65])
def test_g10_an_experiment_name_keeps_the_label_rule(name, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    line = one_line_exit_2(["train", "ppo=smoke", f"tracking.experiment='{name}'"], capsys)
    assert "tracking.experiment=" in line and "starting with a letter or digit" in line
    assert list(tmp_path.iterdir()) == []  # no runs/.hidden, no runs/-rf


def test_g10_the_studies_own_experiments_keep_it():
    from sigmarl.compose import compose_config
    from sigmarl.paths import config_files

    for name in config_files("study"):
        compose_config([f"study={name}"])  # validates tracking.experiment among the rest


def test_g11_a_plan_error_names_its_folders_as_typed(capsys):
    folder = str(PAPER_RUN.parents[1])
    line = one_line_exit_2(["report", "--plan", "--from", folder, "--models", "M4"], capsys)
    assert f"from {folder} are M4" in line and "PosixPath" not in line
