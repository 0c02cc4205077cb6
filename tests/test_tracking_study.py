"""MLflow reads like a study: the experiment opens on its runs (MLflow 3's experiment kind), its
description names the study, its variants and its baseline, a study run holds the training runs
as children and each evaluation is a child of its training, carrying the variant, its overrides
and the fingerprint as params."""

from __future__ import annotations

import pytest
from mlflow import MlflowClient

from sigmarl.cli import main
from sigmarl.compose import compose_config
from sigmarl.tracking.store import connect
from sigmarl.tracking.study_run import description, study_run
from sigmarl.tracking.training import MlflowTrainingRun


def test_the_study_run_and_the_experiment_description(tmp_path):
    uri = f"sqlite:///{tmp_path}/mlflow.db"
    cfg = compose_config(["study=critic", f"tracking.tracking_uri={uri}", "model=IPPO",
                          "network.centralised_critic=false", f"runs_root={tmp_path}/runs"])
    client = connect(cfg)
    with study_run(client, cfg) as rid:
        training = MlflowTrainingRun.open(cfg, client)
        assert client.get_run(rid).info.status == "RUNNING"
    raw = MlflowClient(tracking_uri=uri)
    exp = raw.get_experiment_by_name("sigmarl-critic")
    assert exp.tags["mlflow.experimentKind"] == "custom_model_development"
    note = exp.tags["mlflow.note.content"]
    assert note.startswith("**Study critic**: 2 variant(s), baseline **MAPPO**")
    assert "- MAPPO: `obs=full`" in note and "- IPPO: `obs=full network.centralised_critic=false`" in note
    study = raw.get_run(rid)
    assert study.info.status == "FINISHED" and study.info.run_name == "study critic"
    assert study.data.tags["kind"] == "study" and study.data.tags["variants"] == "MAPPO, IPPO"
    assert raw.get_run(training.run_id).data.tags["mlflow.parentRunId"] == rid
    # a second sweep of the study reuses its study run
    with study_run(client, cfg) as again:
        assert again == rid


def test_a_study_run_ends_killed_with_an_interrupted_sweep(tmp_path):
    cfg = compose_config(["study=reward", f"tracking.tracking_uri=sqlite:///{tmp_path}/mlflow.db"])
    client = connect(cfg)
    with pytest.raises(KeyboardInterrupt), study_run(client, cfg) as rid:
        raise KeyboardInterrupt
    assert client.get_run(rid).info.status == "KILLED"
    assert "- NA0: `obs=full env.reward.near_agents=0`" in description(cfg.study)


@pytest.mark.slow
def test_a_sweep_nests_training_and_evaluation_under_its_study(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    uri = f"sqlite:///{tmp_path}/mlflow.db"
    smoke = ["ppo=smoke", "ppo.iterations=1", "ppo.frames_per_iteration=256", "ppo.minibatch_size=128",
             "ppo.epochs=1", "network.hidden=[16,16]", "eval.n_sims=2", "eval.steps=20",
             "eval.scenarios=[Intersection]", "study.scenarios=[Intersection]"]
    assert main(["sweep", "study=critic", *smoke, f"tracking.tracking_uri={uri}", f"runs_root={tmp_path}/runs"]) == 0
    client = MlflowClient(tracking_uri=uri)
    exp = client.get_experiment_by_name("sigmarl-critic").experiment_id
    runs = client.search_runs([exp])
    by_kind = {}
    for run in runs:
        by_kind.setdefault(run.data.tags["kind"], []).append(run)
    (study,) = by_kind["study"]
    assert study.info.status == "FINISHED"
    trainings = {r.data.tags["model"]: r for r in by_kind["training"]}
    assert set(trainings) == {"MAPPO", "IPPO"}
    assert {r.data.tags["mlflow.parentRunId"] for r in trainings.values()} == {study.info.run_id}
    assert "report" not in by_kind  # a sweep logs none; `sigmarl report` nests its own under the study run
    for evaluation in by_kind["evaluation"]:
        params, variant = evaluation.data.params, evaluation.data.tags["model"]
        assert evaluation.data.tags["mlflow.parentRunId"] == trainings[variant].info.run_id
        assert params["variant"] == variant and params["fingerprint"] == trainings[variant].data.tags["fingerprint"]
        assert params["overrides"] == {"MAPPO": "obs=full", "IPPO": "obs=full network.centralised_critic=false"}[variant]
    assert main(["report", "study=critic", "study.scenarios=[Intersection]", f"tracking.tracking_uri={uri}",
                 f"runs_root={tmp_path}/runs", "--no-figures", "--out", str(tmp_path / "report")]) == 0
    (report,) = client.search_runs([exp], filter_string="tags.kind = 'report'")
    assert report.data.tags["mlflow.parentRunId"] == study.info.run_id
