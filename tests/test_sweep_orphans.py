"""A sweep worker killed from outside (SIGKILL: the OOM killer) leaves no MLflow run RUNNING,
whether it was training or evaluating, and the sweep's one line says which it was doing."""

from __future__ import annotations

import forked
import pytest
from joblib.externals.loky.process_executor import TerminatedWorkerError
from mlflow.tracking import MlflowClient

from sigmarl.sweep.launch import launcher_failure

TINY = ["study=quick", "models=[M0]", "seeds=[0]", "ppo=smoke", "ppo.iterations=1", "eval.n_sims=1",
        "eval.steps=5", "eval.scenarios=[Roundabout]", "threads=1"]


def test_the_line_says_what_each_job_cut_short_was_doing():
    died = TerminatedWorkerError("A worker process managed by the executor was unexpectedly terminated. "
                                 "The exit codes of the workers are {SIGKILL(-9)}")
    line = launcher_failure(died, {"M0/seed0": "evaluating", "M0/seed1": "training", "M0/seed2": "training"})
    assert "(exit {SIGKILL(-9)}) while training one of M0/seed1, M0/seed2 or evaluating M0/seed0," in line


@pytest.mark.slow
def test_g2_a_worker_killed_while_evaluating_leaves_its_evaluation_run_killed(tmp_path):
    """The worker dies while logging its evaluation run (a crash point: SIGKILL, no handler
    runs); two worker slots, so that it is a loky worker and the sweep's process lives on."""
    store = f"sqlite:///{tmp_path}/mlflow.db"
    args = ["sweep", *TINY, f"tracking.tracking_uri={store}", f"runs_root={tmp_path}/runs"]
    killed = forked.run([*args, "hydra.launcher.n_jobs=2"], tmp_path, SIGMARL_CRASH_AT="eval:logging")
    assert killed.returncode == 1, killed.stderr[-3000:]
    assert "a worker process died" in killed.stderr and "while evaluating M0/seed0," in killed.stderr, \
        killed.stderr[-3000:]
    client = MlflowClient(store)
    exp = client.get_experiment_by_name("sigmarl-quick")

    def statuses(kind):
        return [r.info.status for r in client.search_runs([exp.experiment_id], f"tags.kind = '{kind}'")]

    assert statuses("training") == ["FINISHED"] and statuses("evaluation") == ["KILLED"]
    # the re-run logs the evaluation again, in place of the killed one
    assert forked.run(args, tmp_path).returncode == 0
    assert statuses("evaluation") == ["FINISHED"]
