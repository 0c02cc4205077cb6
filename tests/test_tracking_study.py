"""MLflow reads like a study: the experiment opens on its runs (MLflow 3's experiment kind), its
description names the study, its variants and its baseline, a study run holds the training runs
as children and each evaluation is a child of its training, carrying the variant, its overrides
and the fingerprint as params."""

from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import sys
import time
import urllib.request

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


@pytest.fixture(scope="module")
def critic_store(tmp_path_factory):
    """A smoke sweep and report of study=critic: (folder, store URI)."""
    tmp = tmp_path_factory.mktemp("critic")
    here = os.getcwd()
    os.chdir(tmp)
    try:
        uri = f"sqlite:///{tmp}/mlflow.db"
        smoke = ["ppo=smoke", "ppo.iterations=1", "ppo.frames_per_iteration=256", "ppo.minibatch_size=128",
                 "ppo.epochs=1", "network.hidden=[16,16]", "eval.n_sims=2", "eval.steps=20",
                 "eval.scenarios=[Intersection]", "study.scenarios=[Intersection]"]
        assert main(["sweep", "study=critic", *smoke, f"tracking.tracking_uri={uri}", f"runs_root={tmp}/runs"]) == 0
        runs = MlflowClient(tracking_uri=uri).search_runs(
            [MlflowClient(tracking_uri=uri).get_experiment_by_name("sigmarl-critic").experiment_id])
        assert not [r for r in runs if r.data.tags["kind"] == "report"]  # a sweep logs none
        assert main(["report", "study=critic", "study.scenarios=[Intersection]", f"tracking.tracking_uri={uri}",
                     f"runs_root={tmp}/runs", "--no-figures", "--out", str(tmp / "report")]) == 0
    finally:
        os.chdir(here)
    return tmp, uri


@pytest.mark.slow
def test_a_sweep_nests_training_and_evaluation_under_its_study(critic_store):
    _, uri = critic_store
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
    for evaluation in by_kind["evaluation"]:
        params, variant = evaluation.data.params, evaluation.data.tags["model"]
        assert evaluation.data.tags["mlflow.parentRunId"] == trainings[variant].info.run_id
        assert params["variant"] == variant and params["fingerprint"] == trainings[variant].data.tags["fingerprint"]
        assert params["overrides"] == {"MAPPO": "obs=full", "IPPO": "obs=full network.centralised_critic=false"}[variant]
    (report,) = by_kind["report"]
    assert report.data.tags["mlflow.parentRunId"] == study.info.run_id


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _dom(chromium: str, url: str) -> str:
    done = subprocess.run([chromium, "--headless", "--no-sandbox", "--disable-gpu", "--virtual-time-budget=20000",
                           "--dump-dom", url], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout


@pytest.mark.slow
def test_mlflow_ui_lists_the_study_and_compares_its_variants_in_chromium(critic_store):
    """What a person sees in `mlflow ui` (MLflow's own server and page, in headless Chromium):
    the runs page holds the study run with the description, and the compare view of the two
    evaluations shows both variants and their CR_total."""
    chromium = next((p for p in map(shutil.which, ("chromium", "chromium-browser", "google-chrome")) if p), None)
    if chromium is None:
        pytest.skip("no Chromium (apt-get install chromium)")
    tmp, uri = critic_store
    client = MlflowClient(tracking_uri=uri)
    exp = client.get_experiment_by_name("sigmarl-critic").experiment_id
    evaluations = client.search_runs([exp], filter_string="tags.kind = 'evaluation'")
    port = _free_port()
    server = subprocess.Popen([sys.executable, "-m", "mlflow", "server", "--backend-store-uri", uri,
                               "--host", "127.0.0.1", "--port", str(port), "--workers", "1"],
                              cwd=tmp, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    base = f"http://127.0.0.1:{port}"
    try:
        for _ in range(120):
            try:
                if urllib.request.urlopen(f"{base}/health", timeout=2).status == 200:
                    break
            except OSError:
                time.sleep(0.5)
        else:
            pytest.fail("mlflow server did not answer on /health")
        runs_page = _dom(chromium, f"{base}/#/experiments/{exp}/runs?workflowType=machine_learning")
        assert "study critic" in runs_page and "Study critic" in runs_page and "baseline" in runs_page
        ids = ",".join(f'"{r.info.run_id}"' for r in evaluations)
        compare = _dom(chromium, f"{base}/#/compare-runs?runs=[{ids}]&experiments=[\"{exp}\"]")
        assert "eval-MAPPO-seed0" in compare and "eval-IPPO-seed0" in compare
        assert "Intersection/CR_total_pct" in compare and "variant" in compare
    finally:
        os.killpg(server.pid, signal.SIGTERM)
        server.wait(timeout=30)


def test_the_description_keeps_every_variant_a_sweep_added(tmp_path):
    """A command-line sweep's variants join the description (never "2 variant(s)" after more
    were run), and a later sweep's join those recorded before."""
    uri = f"sqlite:///{tmp_path}/mlflow.db"
    cfg = compose_config(["study=critic", f"tracking.tracking_uri={uri}"])
    client = connect(cfg)
    with study_run(client, cfg, {"MAPPO_max_speed-0.6": ["obs=full", "env.vehicle.max_speed=0.6"]}):
        pass
    with study_run(client, cfg, {"MAPPO_max_speed-0.7": ["obs=full", "env.vehicle.max_speed=0.7"]}):
        pass
    note = MlflowClient(tracking_uri=uri).get_experiment_by_name("sigmarl-critic").tags["mlflow.note.content"]
    assert note.startswith("**Study critic**: 4 variant(s), baseline **MAPPO**")
    assert "- MAPPO_max_speed-0.6: `obs=full env.vehicle.max_speed=0.6` (added by a command-line sweep)" in note
    assert "- MAPPO_max_speed-0.7: `obs=full env.vehicle.max_speed=0.7` (added by a command-line sweep)" in note


def test_a_report_run_is_named_by_what_it_compares():
    from sigmarl.tracking.records import report_name

    tags = {"baseline": "M0", "models": "M0,M1,M4", "scenarios": "CPM,Roundabout"}
    assert report_name("sigmarl-ablation", tags) == "report sigmarl-ablation: M0 vs M1,M4 on CPM,Roundabout"
    assert report_name("x", {**tags, "baseline": "M3", "models": "M3"}) == "report x: M3 alone on CPM,Roundabout"
    many = {**tags, "scenarios": ",".join(f"S{i}" for i in range(12))}
    assert report_name("x", many) == "report x: M0 vs M1,M4 on 12 scenarios"
    assert len(report_name("x", {**tags, "models": ",".join(f"V{i}" for i in range(99))})) == 200


@pytest.mark.slow
def test_report_runs_carry_what_tells_them_apart_and_evaluate_twice_is_one_run(critic_store, tmp_path):
    tmp, _ = critic_store
    copy = tmp_path / "copy"
    shutil.copytree(tmp, copy)
    uri = f"sqlite:///{copy}/mlflow.db"
    assert main(["report", "study=critic", "study.scenarios=[Intersection]", "study.baseline=IPPO",
                 f"tracking.tracking_uri={uri}", f"runs_root={copy}/runs", "--no-figures",
                 "--out", str(copy / "other")]) == 0
    client = MlflowClient(tracking_uri=uri)
    exp = client.get_experiment_by_name("sigmarl-critic").experiment_id
    reports = {r.info.run_name: r.data.params for r in client.search_runs([exp], "tags.kind = 'report'")}
    assert reports["report sigmarl-critic: MAPPO vs IPPO on Intersection"]["baseline"] == "MAPPO"
    assert reports["report sigmarl-critic: IPPO vs MAPPO on Intersection"]["models"] == "MAPPO,IPPO"
    # a lone evaluate, twice: one evaluation run of the training run, nested under it, in its experiment
    protocol = ["eval.n_sims=2", "eval.steps=20", "eval.scenarios=[Intersection]", f"tracking.tracking_uri={uri}"]
    for _ in range(2):
        assert main(["evaluate", str(copy / "runs" / "MAPPO" / "seed0"), *protocol]) == 0
    training = client.search_runs([exp], "tags.kind = 'training' and tags.model = 'MAPPO'")[0]
    (evaluation,) = client.search_runs([exp], f"tags.kind = 'evaluation' and tags.train_run_id = "
                                              f"'{training.info.run_id}'")
    assert evaluation.data.tags["mlflow.parentRunId"] == training.info.run_id
    assert evaluation.data.metrics and all(v == round(v, 2) for v in evaluation.data.metrics.values())
