"""Study commands on bad input and their building blocks: one clear message, non-zero exit."""

from __future__ import annotations

from pathlib import Path

import pytest

from sigmarl.cli import main
from sigmarl.compose import compose_config
from sigmarl.errors import SigmarlError
from sigmarl.run import FAILED_FILE
from sigmarl.sweep import plan_sweep
from sigmarl.sweep.job import run_job
from sigmarl.tracking import connect

RESULTS = Path(__file__).resolve().parents[1] / "results" / "paper-budget"


def test_sweep_defaults_cover_the_six_models_with_one_job_per_core():
    plan = plan_sweep(["tracking.enabled=false"], cores=2)
    assert plan.labels == ["M0", "M1", "M2", "M3", "M4", "M5"]
    assert [j.variant for j in plan.jobs][:2] == [["obs=full"], ["obs=no_ego_view"]]
    assert {j.seed for j in plan.jobs} == {0}
    assert "hydra/launcher=joblib" in plan.hydra and "hydra.launcher.n_jobs=2" in plan.hydra
    assert not any(o.startswith("threads=") for j in plan.jobs for o in j.overrides)  # set from its grant


def test_sweep_shorthands():
    plan = plan_sweep(["models=[M0,M4]", "seeds=[0,1,2]", "tracking.enabled=false"], cores=16)
    assert [j.key for j in plan.jobs] == [f"{m}/seed{s}" for m in ("M0", "M4") for s in (0, 1, 2)]
    assert "hydra.launcher.n_jobs=6" in plan.hydra  # 6 jobs on 16 cores: all at once
    # the user's own choices win
    plan = plan_sweep(["hydra.launcher.n_jobs=1", "threads=4", "tracking.enabled=false"], cores=2)
    assert plan.hydra == ["hydra.launcher.n_jobs=1", "hydra/launcher=joblib"]
    assert all(j.overrides.count("threads=4") == 1 for j in plan.jobs)
    # another launcher gets no joblib settings
    plan = plan_sweep(["hydra/launcher=slurm", "tracking.enabled=false"], cores=2)
    assert plan.hydra == ["hydra/launcher=slurm"]


def test_the_sweeps_hint_keeps_what_finds_its_runs(tmp_path, monkeypatch):
    from sigmarl.sweep.launch import report_hint

    monkeypatch.delenv("SIGMARL_CONFIG_PATH", raising=False)
    # away from the clone: runs/ left there by the README's quick start (study=quick, another
    # training config than env.n_agents=5's) is no part of what this test plans (N3)
    monkeypatch.chdir(tmp_path)
    # ppo=smoke moves the runs into experiment sigmarl-smoke, and is the training config every
    # column composes to: the report needs it too (the evaluation's own settings it does not)
    plan = plan_sweep(["ppo=smoke", "models=[M0]", "eval.n_sims=2", "tracking.enabled=false"])
    assert report_hint(plan) == "sigmarl report ppo=smoke tracking.enabled=false"
    plan = plan_sweep(["study=quick", "models=[M0]", "env.n_agents=5"])
    assert report_hint(plan) == "sigmarl report study=quick env.n_agents=5"
    # where only the study and the store choose them, those alone, quoted for the shell
    plan = plan_sweep(["study=quick", "models=[M0]", "eval.n_sims=2", f"runs_root={tmp_path}/my runs"])
    assert report_hint(plan) == f"sigmarl report study=quick 'runs_root={tmp_path}/my runs'"


def test_sweep_unknown_model():
    with pytest.raises(SigmarlError, match="unknown model"):
        plan_sweep(["models=[M9]"])


def test_sweep_over_unknown_preset_exits_2(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    rc = main(["sweep", "obs=full,no_such_preset", "tracking.enabled=false"])
    assert rc == 2
    assert "no_such_preset" in capsys.readouterr().err


def test_a_failing_job_is_recorded_and_does_not_raise(tmp_path):
    # 400 agents cannot be placed on the intersection: training fails before its first step.
    cfg = compose_config(["ppo=smoke", "env.n_agents=400", "tracking.enabled=false", f"run_dir={tmp_path}/job"])
    assert run_job(cfg) == "failed"
    assert "could not place" in (tmp_path / "job" / FAILED_FILE).read_text()


def test_evaluate_missing_checkpoint_exits_2(capsys):
    rc = main(["evaluate", "/no/such/best.pt", "tracking.enabled=false"])
    assert rc == 2
    assert "checkpoint not found: /no/such/best.pt" in capsys.readouterr().err


def test_evaluate_checkpoint_whose_observation_does_not_fit(tmp_path, capsys):
    # 8 training agents observing 6 neighbours: 10 own entries + 6 x 11 = 76 inputs; on the
    # 6-agent intersection an agent sees only 5 others (65), so the checkpoint is refused
    # before any scenario is built.
    run = tmp_path / "run"
    assert main(["train", "ppo=smoke", "ppo.iterations=1", "env.n_agents=8", "obs.n_nearest=6",
                 "tracking.enabled=false", f"run_dir={run}"]) == 0
    rc = main(["evaluate", str(run / "final.pt"), "--scenario", "Intersection", "eval.n_sims=1",
               "eval.steps=2", "tracking.enabled=false"])
    assert rc == 2
    err = capsys.readouterr().err
    assert "cannot be evaluated on Intersection: its policy takes 76 inputs" in err
    assert "have 65 (6 agents, 5 observed neighbours" in err


def test_report_without_runs_exits_2(tmp_path, capsys):
    uri = f"tracking.tracking_uri=sqlite:///{tmp_path}/mlflow.db"
    connect(compose_config([uri]))  # a store without the experiment
    rc = main(["report", uri, "tracking.experiment=empty"])
    assert rc == 2
    assert "no MLflow experiment named 'empty'" in capsys.readouterr().err


def test_report_without_a_store_creates_none(tmp_path, capsys):
    rc = main(["report", f"tracking.tracking_uri=sqlite:///{tmp_path}/mlflow.db"])
    assert rc == 2
    assert f"nothing to report: no MLflow store at {tmp_path}/mlflow.db" in capsys.readouterr().err
    assert not (tmp_path / "mlflow.db").exists()


def test_report_on_unreachable_store_exits_2(tmp_path, capsys):
    rc = main(["report", "tracking.tracking_uri=sqlite:////proc/sigmarl/mlflow.db"])  # unwritable
    assert rc == 2
    err = capsys.readouterr().err
    assert "MLflow store" in err and "/proc/sigmarl" in err


@pytest.mark.slow
def test_an_interrupted_job_is_unfinished_not_failed(tmp_path):
    # Ctrl-C (or SIGTERM, raised the same way) in the middle of training: the job leaves its
    # resume point and no failed.txt, so the sweep's summary says "unfinished", not "FAILED".
    import os
    import signal
    import threading
    import time

    from sigmarl.compose import compose_config

    run = tmp_path / "job"
    cfg = compose_config(["ppo=smoke", "ppo.iterations=500", "tracking.enabled=false", f"run_dir={run}"])

    def interrupt() -> None:
        deadline = time.time() + 120
        while not (run / "best.pt").exists() and time.time() < deadline:
            time.sleep(0.05)
        os.kill(os.getpid(), signal.SIGINT)

    # Python leaves SIGINT ignored when it starts ignored (a shell's `cmd &`): Ctrl-C's own handler
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        threading.Thread(target=interrupt, daemon=True).start()
        with pytest.raises(KeyboardInterrupt):
            run_job(cfg)
    finally:
        signal.signal(signal.SIGINT, previous)
    assert (run / "checkpoint.pt").exists() and not (run / FAILED_FILE).exists()


def test_train_over_several_seeds_points_to_the_sweep_in_one_line(capsys):
    assert main(["train", "seed=0,1", "ppo=smoke", "tracking.enabled=false"]) == 2
    err = capsys.readouterr().err.strip()
    assert "`sigmarl sweep seed=0,1`" in err and "multirun" not in err and len(err.splitlines()) == 1


def test_a_dict_for_study_variants_says_what_form_they_take(capsys):
    assert main(["train", "study.variants={K4:{x:1}}", "--cfg", "job"]) == 2
    err = capsys.readouterr().err.strip()
    assert "did you mean" not in err and "variants: {LABEL: [override, ...]}" in err and len(err.splitlines()) == 1


def test_an_unknown_scenario_is_refused_before_the_checkpoint_is_looked_at(capsys):
    import time

    start = time.perf_counter()
    assert main(["evaluate", str(RESULTS / "M0" / "seed0" / "best.pt"), "--scenario", "Foo"]) == 2
    assert time.perf_counter() - start < 1.0  # no Hydra composition, no torch
    assert "unknown scenario 'Foo'" in capsys.readouterr().err


def test_help_texts_give_the_evaluations_defaults_and_the_rules_group(capsys):
    from sigmarl.config import EvalConfig

    with pytest.raises(SystemExit):
        main(["evaluate", "--help"])
    text = capsys.readouterr().out
    assert f"eval.n_sims={EvalConfig.n_sims}" in text and f"eval.seed={EvalConfig.seed}" in text
    with pytest.raises(SystemExit):
        main(["sweep", "--help"])
    assert "six models" not in capsys.readouterr().out
    with pytest.raises(SystemExit):
        main(["--info"])
    assert "  rules           ours, paper," in capsys.readouterr().out
