"""A run folder carries on in another MLflow store: a study committed on one machine and
continued on another (or a cluster job's folder reported elsewhere) finds no record of its
MLflow run there. The folder is the primary record, so the new store gets a new run, filled
from the folder's metrics.csv, instead of a refusal."""

from __future__ import annotations

import pandas as pd
import pytest
from mlflow.tracking import MlflowClient

from sigmarl.cli import main

SMOKE = ["ppo=smoke", "threads=1", "tracking.experiment=moved"]


def _training_runs(uri: str):
    client = MlflowClient(tracking_uri=uri)
    exp = client.get_experiment_by_name("moved")
    return client, client.search_runs([exp.experiment_id], "tags.kind = 'training'")


@pytest.mark.slow
def test_a_run_folder_resumes_and_completes_in_a_store_that_never_saw_it(tmp_path, capsys):
    run = tmp_path / "run"
    store = {k: f"sqlite:///{tmp_path}/{k}.db" for k in "abc"}
    assert main(["train", *SMOKE, f"run_dir={run}", f"tracking.tracking_uri={store['a']}",
                 "ppo.stop_after=1"]) == 0  # stopped after iteration 1 of 3
    # Resumed on "another machine": store b has no record of the run.
    assert main(["train", *SMOKE, f"run_dir={run}", f"tracking.tracking_uri={store['b']}",
                 "resume=true"]) == 0
    assert "recording the run folder as a new run" in capsys.readouterr().err
    expected = pd.read_csv(run / "metrics.csv").set_index("iteration")
    assert list(expected.index) == [1, 2, 3]
    client, runs = _training_runs(store["b"])
    assert len(runs) == 1 and runs[0].info.status == "FINISHED"
    rid = runs[0].info.run_id
    assert (run / "mlflow_run_id").read_text().strip() == rid
    history = {m.step: m.value for m in client.get_metric_history(rid, "episode_reward_mean")}
    assert history == pytest.approx(expected["episode_reward_mean"].to_dict())  # iteration 1 too
    # The finished folder in a third store: a re-run (as a sweep does it) records it there.
    assert main(["train", *SMOKE, f"run_dir={run}", f"tracking.tracking_uri={store['c']}",
                 "resume=true"]) == 0
    client, runs = _training_runs(store["c"])
    assert len(runs) == 1 and runs[0].info.status == "FINISHED"
    rid = runs[0].info.run_id
    history = {m.step: m.value for m in client.get_metric_history(rid, "episode_reward_mean")}
    assert history == pytest.approx(expected["episode_reward_mean"].to_dict())
    artifacts = {a.path for a in client.list_artifacts(rid)}
    assert {"best.pt", "final.pt", "config.yaml"} <= artifacts
    assert (run / "mlflow_run_id").read_text().strip() == rid
