"""A re-run of a finished run folder whose store lacks its run records one run for the folder,
however often it is re-run (fault H4): the run id is the folder's `mlflow_run_id`, which the
first re-run rewrote, not the checkpoint's, which no re-run rewrites."""

from __future__ import annotations

import shutil

from mlflow import MlflowClient

from sigmarl.cli import main

SMOKE = ["ppo=smoke", "threads=1", "tracking.experiment=rerun"]


def _training_runs(uri: str) -> list:
    client = MlflowClient(uri)
    exp = client.get_experiment_by_name("rerun")
    return client.search_runs([exp.experiment_id], "tags.kind = 'training'") if exp else []


def test_re_runs_against_a_store_without_the_run_record_one_run(tmp_path, capsys):
    first, other = f"sqlite:///{tmp_path}/first.db", f"sqlite:///{tmp_path}/other.db"
    assert main(["train", *SMOKE, f"tracking.tracking_uri={first}", f"run_dir={tmp_path}/run"]) == 0
    checkpoint = (tmp_path / "run" / "checkpoint.pt").read_bytes()
    for _ in range(3):
        assert main(["train", *SMOKE, f"tracking.tracking_uri={other}", f"run_dir={tmp_path}/run",
                     "resume=true"]) == 0
    runs = _training_runs(other)
    assert len(runs) == 1 and runs[0].info.status == "FINISHED"
    assert (tmp_path / "run" / "mlflow_run_id").read_text().strip() == runs[0].info.run_id
    assert (tmp_path / "run" / "checkpoint.pt").read_bytes() == checkpoint  # the finished work untouched
    assert len(_training_runs(first)) == 1
    shutil.rmtree(tmp_path / "run")
