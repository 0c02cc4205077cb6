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
