"""The shipped studies of axes beyond the observation (the critic, the reward), each through
sweep and report at a smoke budget."""

from __future__ import annotations

import pandas as pd
import pytest
import yaml

from sigmarl.cli import main

pytestmark = pytest.mark.slow

SMOKE = ["ppo=smoke", "ppo.iterations=1", "ppo.frames_per_iteration=256", "ppo.minibatch_size=128",
         "ppo.epochs=1", "network.hidden=[16,16]", "eval.n_sims=2", "eval.steps=20",
         "eval.scenarios=[Intersection]", "study.scenarios=[Intersection]"]


def _sweep_and_report(study: str, root, capsys) -> tuple[dict, pd.DataFrame]:
    store = f"tracking.tracking_uri=sqlite:///{root}/mlflow.db"
    rc = main(["sweep", f"study={study}", *SMOKE, store, f"runs_root={root}/runs"])
    assert rc == 0, capsys.readouterr().err
    saved = {p.parent.parent.name: yaml.safe_load(p.read_text()) for p in (root / "runs").glob("*/seed0/config.yaml")}
    out = root / "report"
    assert main(["report", f"study={study}", "study.scenarios=[Intersection]", store, "--no-figures",
                 "--out", str(out)]) == 0, capsys.readouterr().err
    return saved, pd.read_csv(out / "improvement.csv")


def test_the_critic_study_trains_mappo_and_ippo(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    saved, better = _sweep_and_report("critic", tmp_path, capsys)
    assert saved["MAPPO"]["network"]["centralised_critic"] is True
    assert saved["IPPO"]["network"]["centralised_critic"] is False
    assert saved["IPPO"]["fingerprint"] != saved["MAPPO"]["fingerprint"]
    assert set(better["reference"]) == {"MAPPO"} and set(better["model"]) == {"IPPO"}
    header = next(ln for ln in (tmp_path / "report" / "table.md").read_text().splitlines() if ln.startswith("| Scenario"))
    assert header == "| Scenario | Metric | MAPPO | IPPO |"


def test_the_reward_study_trains_the_agent_penalty_at_three_weights(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    saved, better = _sweep_and_report("reward", tmp_path, capsys)
    assert {k: v["env"]["reward"]["near_agents"] for k, v in saved.items()} == {"NA0": 0.0, "NA0.2": -0.2, "NA0.4": -0.4}
    assert len({v["fingerprint"] for v in saved.values()}) == 3
    assert set(better["reference"]) == {"NA0.2"} and set(better["model"]) == {"NA0", "NA0.4"}
    header = next(ln for ln in (tmp_path / "report" / "table.md").read_text().splitlines() if ln.startswith("| Scenario"))
    assert header == "| Scenario | Metric | NA0 | NA0.2 | NA0.4 |"  # the study's order
