"""A sweep run again over run folders that lost or damaged their evaluation rows: each such
job measures its rows again (the same rows, bit for bit) instead of counting as finished, and
the store keeps one evaluation run per training."""

from __future__ import annotations

from pathlib import Path

import pytest
from mlflow.tracking import MlflowClient

from sigmarl.cli import main
from sigmarl.run import Run

pytestmark = pytest.mark.slow

SWEEP = ["study=quick", "models=[M0]", "seeds=[0,1,2]", "ppo=smoke", "ppo.iterations=1", "eval.n_sims=2",
         "eval.steps=20", "eval.scenarios=[Roundabout]", "threads=1"]


def _sweep(root: Path) -> int:
    return main(["sweep", *SWEEP, f"tracking.tracking_uri=sqlite:///{root}/mlflow.db", f"runs_root={root}/runs"])


def test_f10_a_sweep_measures_lost_or_damaged_rows_again(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert _sweep(tmp_path) == 0
    runs = [Run(tmp_path / "runs" / "M0" / f"seed{k}") for k in range(3)]
    before = [r.rows_file.read_bytes() for r in runs]
    runs[0].rows_file.unlink()  # lost
    runs[1].rows_file.write_bytes(before[1][:-40])  # its last line cut
    flipped = bytearray(before[2])
    flipped[-5] = ord("7") if flipped[-5] != ord("7") else ord("3")  # one digit of the last AS changed
    runs[2].rows_file.write_bytes(bytes(flipped))
    assert _sweep(tmp_path) == 0
    for k in range(3):  # each job's log (the jobs run in worker processes)
        log = (tmp_path / "multirun" / "sigmarl-quick" / "M0" / f"seed{k}" / "sweep.log").read_text()
        assert "is missing or damaged: evaluating again" in log
    assert [r.rows_file.read_bytes() for r in runs] == before
    client = MlflowClient(f"sqlite:///{tmp_path}/mlflow.db")
    exp = client.get_experiment_by_name("sigmarl-quick")
    kinds = sorted(r.data.tags["kind"] for r in client.search_runs([exp.experiment_id]))
    # the rows restored, not logged twice; the study's one parent run not duplicated either
    assert kinds == ["evaluation"] * 3 + ["study"] + ["training"] * 3
    capsys.readouterr()
    assert _sweep(tmp_path) == 0
    assert "already trained and evaluated" in capsys.readouterr().out
