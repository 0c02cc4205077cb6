"""A researcher's own ablation: a study declared in a config folder outside the package (with
its own scenario), and a sweep over a key that is not an observation flag, each run through
sweep -> report at a smoke budget. The table's columns are the study's variants in declared
order, compared with its declared baseline."""

from __future__ import annotations

import shlex

import pandas as pd
import pytest
import yaml

from sigmarl.cli import main

pytestmark = pytest.mark.slow

SMOKE = ["ppo=smoke", "ppo.iterations=1", "eval.n_sims=2", "eval.steps=20"]

STUDY = """\
# @package _global_
study:
  name: tiny
  variants:
    Wide: ["network.hidden=[32,32]"]
    Narrow: ["network.hidden=[8,8]"]
    NoDC: [obs=no_distance_to_center_line, "network.hidden=[32,32]"]
  baseline: Narrow
  seeds: [0]
  scenarios: [CPM, Tiny-Intersection]
tracking:
  experiment: tiny
"""


@pytest.fixture(scope="module")
def own(tmp_path_factory):
    root = tmp_path_factory.mktemp("own")
    conf = root / "my_conf"
    (conf / "study").mkdir(parents=True)
    (conf / "scenario").mkdir()
    (conf / "study" / "tiny.yaml").write_text(STUDY)
    # a scenario of one's own: the paper's intersection with fewer agents
    (conf / "scenario" / "Tiny-Intersection.yaml").write_text("map: paper_intersection\nn_agents: 3\n")
    store = f"tracking.tracking_uri=sqlite:///{root}/mlflow.db"
    return root, conf, store


def test_a_study_from_an_outside_folder_runs_through_sweep_and_report(own, monkeypatch, capsys):
    root, conf, store = own
    monkeypatch.chdir(root)
    monkeypatch.delenv("SIGMARL_CONFIG_PATH", raising=False)
    rc = main(["--config-dir", str(conf), "sweep", "study=tiny", *SMOKE, store, f"runs_root={root}/runs"])
    assert rc == 0, capsys.readouterr().err
    run = root / "runs" / "NoDC" / "seed0"
    saved = yaml.safe_load((run / "config.yaml").read_text())
    assert saved["study"]["name"] == "tiny" and saved["model"] == "NoDC"
    assert saved["overrides"] == ["obs=no_distance_to_center_line", "network.hidden=[32,32]"]
    assert saved["obs"]["distance_to_center_line"] is False and saved["network"]["hidden"] == [32, 32]
    rows = pd.read_csv(run / "evaluation_rows.csv")
    assert list(dict.fromkeys(rows["scenario"])) == ["CPM", "Tiny-Intersection"]
    assert set(rows["model"]) == {"NoDC"} and set(rows["study"]) == {"tiny"}
    assert set(rows["fingerprint"]) == {saved["fingerprint"]}
    # Wide and NoDC differ only in the observation: different fingerprints
    wide = yaml.safe_load((root / "runs" / "Wide" / "seed0" / "config.yaml").read_text())
    assert wide["fingerprint"] != saved["fingerprint"]

    # the sweep's closing hint finds the runs as typed, without SIGMARL_CONFIG_PATH in the shell
    out = capsys.readouterr().out
    hint = [line for line in out.splitlines() if line.startswith("next: ")]
    # after its first line the sweep says its workers are starting (no silence while they import)
    assert out.splitlines()[1].startswith("sigmarl sweep: starting "), out
    words = shlex.split(hint[0].removeprefix("next: "))
    assert words[:4] == ["sigmarl", "--config-dir", "my_conf", "report"] and "study=tiny" in words, hint
    monkeypatch.delenv("SIGMARL_CONFIG_PATH")
    assert main([*words[1:], "--no-figures", "--out", str(root / "hinted")]) == 0
    capsys.readouterr()
    out = root / "report"
    assert main(["--config-dir", str(conf), "report", "study=tiny", store, "--no-figures", "--out", str(out)]) == 0
    header = next(ln for ln in (out / "table.md").read_text().splitlines() if ln.startswith("| Scenario"))
    assert header == "| Scenario | Metric | Wide | Narrow | NoDC |"  # declared order
    better = pd.read_csv(out / "improvement.csv")
    assert set(better["reference"]) == {"Narrow"} and set(better["model"]) == {"Wide", "NoDC"}
    assert list(dict.fromkeys(better["scenario"])) == ["CPM", "Tiny-Intersection"]
    # the same from the run folders, without MLflow
    assert main(["--config-dir", str(conf), "report", "study=tiny", "--from", str(root / "runs"),
                 "tracking.enabled=false", "--no-figures", "--out", str(root / "report2")]) == 0
    assert (root / "report2" / "table.md").read_text() == (out / "table.md").read_text()


def test_the_issue_example_has_one_column_per_width(own, monkeypatch, capsys):
    root, _, store = own
    monkeypatch.chdir(root)
    monkeypatch.delenv("SIGMARL_CONFIG_PATH", raising=False)
    rc = main(["sweep", "study=quick", "models=[M0]", "network.hidden=[8,8],[16,16]", *SMOKE,
               "eval.scenarios=[Roundabout]", store, f"runs_root={root}/widths"])
    assert rc == 0, capsys.readouterr().err
    # the widths are a sub-study of their own: the sweep's hint reports exactly them
    hint = [line for line in capsys.readouterr().out.splitlines() if line.startswith("next: ")]
    words = shlex.split(hint[0].removeprefix("next: "))
    assert "--models" in words and "study.baseline=M0_hidden-8-8" in words, hint
    assert main([*words[1:], "--no-figures", "--out", str(root / "widths-report")]) == 0
    header = next(ln for ln in (root / "widths-report" / "table.md").read_text().splitlines() if ln.startswith("| Scenario"))
    assert header == "| Scenario | Metric | M0_hidden-8-8 | M0_hidden-16-16 |"
