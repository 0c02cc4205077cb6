"""Crash consistency: a sweep killed with SIGKILL in every phase, then re-run, ends exactly
where an uninterrupted sweep does.

A tiny sweep (two models, smoke budget, a checkpoint every second iteration) is killed at
named crash points (`sigmarl.crash`), one per run, each re-run going on from what the kill
left: early training before the first periodic checkpoint, between a checkpoint and its
metrics reaching MLflow, right after final.pt, during evaluation, and in the middle of
logging the evaluation run. The last re-run must finish, and the final weights, the
evaluation rows, metrics.csv and the MLflow store must equal those of an uninterrupted sweep
with the same seeds: one FINISHED training and one FINISHED evaluation run per job, none
RUNNING, every iteration's metrics logged once.

The sweeps run in processes forked from a server that has imported the project once
(multiprocessing's forkserver), so each costs its work and not the imports.
"""

from __future__ import annotations

import multiprocessing
import os
from pathlib import Path

import pandas as pd
import pytest
import torch
from mlflow import MlflowClient

pytestmark = pytest.mark.slow

SWEEP = ["study=quick", "models=[M0,M4]", "ppo.iterations=4", "ppo.checkpoint_every=2",
         "ppo.frames_per_iteration=128", "ppo.epochs=1", "ppo.minibatch_size=64",
         "eval.n_sims=2", "eval.steps=20", "hydra.launcher.n_jobs=1", "threads=1"]
# one kill per run, in the order a job meets them; the first job (M0) meets each first
KILLS = ["train:start", "train:iteration:1", "train:checkpoint:2", "train:final",
         "eval:scenario:Intersection", "eval:logging"]
TIMING = ("frames_per_s", "time_collect_s", "time_advantage_s", "time_optimise_s")


def sweep_in(root: str, crash_at: str | None) -> None:
    """A child process: `sigmarl sweep` in `root`, killed at `crash_at` if given."""
    os.chdir(root)
    os.environ.pop("SIGMARL_CRASH_AT", None)
    if crash_at:
        os.environ["SIGMARL_CRASH_AT"] = crash_at
    from sigmarl.cli import main

    os._exit(main(["sweep", *SWEEP, f"tracking.tracking_uri=sqlite:///{root}/mlflow.db"]))


@pytest.fixture(scope="module")
def sweeps(tmp_path_factory):
    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload([__name__, "sigmarl.cli", "sigmarl.sweep", "sigmarl.training.loop",
                                "sigmarl.evaluation.protocol", "sigmarl.cli.report"])

    def run(root: Path, crash_at: str | None) -> int:
        proc = ctx.Process(target=sweep_in, args=(str(root), crash_at))
        proc.start()
        proc.join(timeout=300)
        return proc.exitcode

    calm, crashed = tmp_path_factory.mktemp("uninterrupted"), tmp_path_factory.mktemp("crashed")
    codes = {"uninterrupted": run(calm, None)}
    for point in KILLS:
        codes[point] = run(crashed, point)
    codes["final re-run"] = run(crashed, None)
    return calm, crashed, codes


def test_every_kill_struck_and_the_last_rerun_finished(sweeps) -> None:
    codes = sweeps[2]
    assert codes == {"uninterrupted": 0, **{p: -9 for p in KILLS}, "final re-run": 0}


def _run_dirs(root: Path) -> dict[str, Path]:
    return {str(p.parent.relative_to(root)): p.parent for p in root.glob("runs/**/final.pt")}


def test_weights_rows_and_metrics_equal_the_uninterrupted_sweep(sweeps) -> None:
    calm, crashed, _ = sweeps
    calm_dirs, crashed_dirs = _run_dirs(calm), _run_dirs(crashed)
    assert len(calm_dirs) == 2 and calm_dirs.keys() == crashed_dirs.keys()
    for job, a in calm_dirs.items():
        b = crashed_dirs[job]
        for name in ("final.pt", "best.pt", "checkpoint.pt"):
            sa, sb = (torch.load(d / name, weights_only=True) for d in (a, b))
            assert sa["iteration"] == sb["iteration"]
            for part in ("policy", "critic"):
                if part in sa:
                    assert sa[part].keys() == sb[part].keys()
                    assert all(torch.equal(sa[part][k], sb[part][k]) for k in sa[part]), (job, name)
        pd.testing.assert_frame_equal(pd.read_csv(a / "evaluation_rows.csv"),
                                      pd.read_csv(b / "evaluation_rows.csv"))
        ma, mb = (pd.read_csv(d / "metrics.csv").drop(columns=list(TIMING)) for d in (a, b))
        assert list(mb["iteration"]) == [1, 2, 3, 4]
        pd.testing.assert_frame_equal(ma, mb)


def _store(root: Path):
    client = MlflowClient(f"sqlite:///{root}/mlflow.db")
    exp = client.get_experiment_by_name("sigmarl-quick")
    return client, client.search_runs([exp.experiment_id])


def test_the_store_holds_one_finished_training_and_evaluation_per_job(sweeps) -> None:
    calm, crashed, _ = sweeps
    calm_client, calm_runs = _store(calm)
    client, runs = _store(crashed)
    assert [r for r in runs if r.info.status != "FINISHED"] == []
    # one study parent run, not one per resumed sweep; the jobs' runs are its children
    assert [r.data.tags["kind"] for r in runs].count("study") == 1
    runs = [r for r in runs if r.data.tags["kind"] != "study"]
    calm_runs = [r for r in calm_runs if r.data.tags["kind"] != "study"]
    for kind in ("training", "evaluation"):
        mine = [r for r in runs if r.data.tags["kind"] == kind]
        assert sorted(r.data.tags["model"] for r in mine) == ["M0", "M4"], kind
    baseline = {(r.data.tags["kind"], r.data.tags["model"]): r for r in calm_runs}
    for run in runs:
        key = (run.data.tags["kind"], run.data.tags["model"])
        other = baseline[key]
        if key[0] == "training":
            assert {a.path for a in client.list_artifacts(run.info.run_id)} == {
                "best.pt", "final.pt", "config.yaml"}
            for metric in run.data.metrics:
                if metric in TIMING:
                    continue
                mine = sorted((m.step, m.value) for m in client.get_metric_history(run.info.run_id, metric))
                theirs = sorted((m.step, m.value)
                                for m in calm_client.get_metric_history(other.info.run_id, metric))
                assert mine == theirs, metric
                assert [s for s, _ in mine] == [1, 2, 3, 4]
        else:
            assert run.data.metrics == other.data.metrics
            rows = [pd.read_csv(c.download_artifacts(r.info.run_id, "evaluation_rows.csv", str(root / "dl")))
                    for c, r, root in ((client, run, crashed), (calm_client, other, calm))]
            pd.testing.assert_frame_equal(*rows)
