"""`sigmarl sweep seeds=auto` end to end at a smoke budget: rounds until every comparison is
decided or the cap is reached, every look recorded, and a re-run that finds it done."""

from __future__ import annotations

import json

import pytest

from sigmarl.cli import main
from sigmarl.errors import SigmarlError
from sigmarl.sweep import plan_sweep

STUDY = """\
# @package _global_
study:
  name: tiny_auto
  variants:
    A: ["network.hidden=[8,8]"]
    B: ["network.hidden=[16,16]", obs.noise=0.2]
  baseline: A
  seeds: [0, 1]
  scenarios: [Roundabout]
  max_seeds: 3
tracking:
  experiment: tiny-auto
"""


def test_seeds_auto_needs_two_first_seeds_and_the_baseline():
    from sigmarl.cli.adaptive import run_auto

    with pytest.raises(SigmarlError, match="needs at least two"):
        run_auto(["models=[M0,M4]", "tracking.enabled=false"])
    with pytest.raises(SigmarlError, match="baseline M0, which is not among"):
        run_auto(["models=[M1,M4]", "study.seeds=[0,1]", "tracking.enabled=false"])


@pytest.mark.slow
def test_seeds_auto_runs_rounds_records_them_and_resumes(tmp_path, monkeypatch, capsys):
    conf = tmp_path / "conf" / "study"
    conf.mkdir(parents=True)
    (conf / "tiny_auto.yaml").write_text(STUDY)
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("SIGMARL_CONFIG_PATH", raising=False)
    args = ["--config-dir", str(tmp_path / "conf"), "sweep", "study=tiny_auto", "seeds=auto", "ppo=smoke",
            "ppo.iterations=1", "eval.n_sims=3", "eval.steps=30", "tracking.enabled=false",
            f"runs_root={tmp_path}/runs"]
    assert main(args) == 0, capsys.readouterr().err
    record = json.loads((tmp_path / "runs" / "seeds_auto.json").read_text())
    assert record["n_start"] == 2 and record["max_seeds"] == 3 and record["looks"]
    assert all(max(look["seeds"].values()) <= 3 for look in record["looks"])
    for label, seeds in record["seeds"].items():  # every recorded seed was trained and evaluated
        assert 2 <= len(seeds) <= 3 and seeds == list(range(len(seeds)))
        for seed in seeds:
            assert (tmp_path / "runs" / label / f"seed{seed}" / "evaluated.txt").exists()
    last = record["looks"][-1]
    if any(v == "undecided" for v in last["verdicts"].values()):
        assert max(last["seeds"].values()) == 3  # stopped at the cap
    # a final verdict is never revised at a later look
    for earlier, later in zip(record["looks"], record["looks"][1:], strict=False):
        for k, v in earlier["verdicts"].items():
            if v != "undecided":
                assert later["verdicts"][k] == v
    looks = len(record["looks"])
    capsys.readouterr()
    assert main(args) == 0
    assert "finished earlier" in capsys.readouterr().out
    assert len(json.loads((tmp_path / "runs" / "seeds_auto.json").read_text())["looks"]) == looks
    # a different design is refused rather than mixed with the record
    with pytest.raises(SigmarlError, match="another design"):
        from sigmarl.cli.adaptive import run_auto
        from sigmarl.paths import add_user_conf_dir

        add_user_conf_dir(tmp_path / "conf")
        run_auto([a for a in args[3:] if a != "seeds=auto"] + ["study.max_seeds=4"])
    assert plan_sweep(["study=tiny_auto", "tracking.enabled=false"]).labels == ["A", "B"]
