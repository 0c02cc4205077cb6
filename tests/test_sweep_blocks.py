"""`sweep.seeds_per_job=S`: each sweep job trains S seeds of one variant as one seed block,
and the sweep's records are those of lone jobs (one run folder, one MLflow run per seed)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pandas as pd
import pytest

from sigmarl.cli import main
from sigmarl.errors import SigmarlError
from sigmarl.run import Run
from sigmarl.run.block_membership import write_membership
from sigmarl.sweep import plan_sweep

OFF = "tracking.enabled=false"


def test_jobs_are_packed_into_blocks_of_one_variant(tmp_path):
    plan = plan_sweep(["models=[M0,M4]", "seeds=range(5)", "sweep.seeds_per_job=3", OFF,
                       f"runs_root={tmp_path}"], cores=16)
    assert [u.key for u in plan.units] == ["M0/seeds0_1_2", "M0/seeds3_4", "M4/seeds0_1_2", "M4/seeds3_4"]
    assert [[j.seed for j in u.jobs] for u in plan.units] == [[0, 1, 2], [3, 4]] * 2
    assert all(len({j.label for j in u.jobs}) == 1 for u in plan.units)
    assert len(plan.jobs) == 10  # still a job per seed: its folder, its record, its summary line
    assert "hydra.launcher.n_jobs=4" in plan.hydra  # a worker per block, not per seed


def test_a_block_is_its_seeds_and_a_lone_seed_its_own_job(tmp_path):
    plan = plan_sweep(["models=[M0]", "seeds=[4,2,7]", "sweep.seeds_per_job=2", OFF, f"runs_root={tmp_path}"])
    assert [u.key for u in plan.units] == ["M0/seeds4_2", "M0/seed7"]


@pytest.mark.parametrize(("device", "size"), [("cpu", 1), ("cuda", 64), ("cuda:1", 64)])
def test_the_default_block_is_chosen_by_device(device, size, tmp_path):
    """0 (the default): lone jobs on a CPU, where a block seed measured 0.88-1.07 of a lone one;
    blocks on a GPU. Planning never touches the device, so a GPU sweep plans on a laptop."""
    plan = plan_sweep(["models=[M0]", "seeds=range(70)", f"device={device}", OFF, f"runs_root={tmp_path}"])
    assert {len(u.jobs) for u in plan.units[:-1]} == {size}
    assert len(plan.units) == -(-70 // size)


def test_what_training_cannot_run_is_refused_at_planning_and_a_critic_per_agent_is_batched(tmp_path):
    # torchrl's loss is no choice of training, for a block of any size: refused before any job
    for seeds in ("[0,1]", "[0]"):
        with pytest.raises(SigmarlError, match="ppo.loss"):
            plan_sweep(["models=[M0]", f"seeds={seeds}", "sweep.seeds_per_job=2", "ppo.loss=torchrl", OFF,
                        f"runs_root={tmp_path}"])
    # a critic head per agent trains in blocks like any other config
    plan = plan_sweep(["models=[M0]", "seeds=[0,1]", "sweep.seeds_per_job=2", "network.shared_critic_value=false",
                       OFF, f"runs_root={tmp_path}"])
    assert [len(u.jobs) for u in plan.units] == [2]


def test_a_negative_block_size_is_one_line(tmp_path):
    with pytest.raises(SigmarlError, match=r"sweep.seeds_per_job must be in 0\.\.4096"):
        plan_sweep(["sweep.seeds_per_job=-2", OFF, f"runs_root={tmp_path}"])


def test_the_block_size_is_not_a_training_setting(tmp_path):
    lone = plan_sweep(["models=[M0]", "seeds=[0,1]", OFF, f"runs_root={tmp_path}"])
    block = plan_sweep(["models=[M0]", "seeds=[0,1]", "sweep.seeds_per_job=2", OFF, f"runs_root={tmp_path}"])
    assert [j.fingerprint for j in lone.jobs] == [j.fingerprint for j in block.jobs]


def test_a_part_trained_lone_run_goes_on_alone_not_in_a_block(tmp_path):
    """A re-run with a different packing must not take over a half-trained lone run: it
    resumes alone, and the seeds still to train make the blocks."""
    seed1 = tmp_path / "M0" / "seed1"
    seed1.mkdir(parents=True)
    (seed1 / "checkpoint.pt").write_bytes(b"a lone run's resume point")
    plan = plan_sweep(["models=[M0]", "seeds=[0,1,2]", "sweep.seeds_per_job=2", OFF, f"runs_root={tmp_path}"])
    assert [u.key for u in plan.units] == ["M0/seeds0_2", "M0/seed1"]


def test_a_started_block_goes_on_whole_under_another_packing(tmp_path):
    """Seeds 2 and 1 began as one block (block.json, a resume point each): a sweep of four
    seeds keeps them together, in their block's order, and packs the fresh ones apart."""
    runs = [Run(tmp_path / "M0" / f"seed{s}") for s in (2, 1)]
    for run in runs:
        run.dir.mkdir(parents=True)
        run.resume_file.write_bytes(b"the block's resume point")
    write_membership(runs, "M0", [2, 1])
    plan = plan_sweep(["models=[M0]", "seeds=range(4)", "sweep.seeds_per_job=2", OFF, f"runs_root={tmp_path}"])
    assert [u.key for u in plan.units] == ["M0/seeds0_3", "M0/seeds2_1"]
    # a block some of whose seeds are left out is still refused, before any job
    with pytest.raises(SigmarlError, match=r"seed1 belongs to the seed block \[2, 1\]"):
        plan_sweep(["models=[M0]", "seeds=[0,1]", "sweep.seeds_per_job=2", OFF, f"runs_root={tmp_path}"])


def test_a_plan_entry_of_a_block_naming_no_seeds_is_one_line(tmp_path):
    from omegaconf import OmegaConf

    from sigmarl.sweep.job import _job_configs

    plan = tmp_path / "plan.json"
    plan.write_text(json.dumps({"M0/seeds0_1": {"members": ["M0/seed0", "M0/seed1"]}}))
    with pytest.raises(SigmarlError, match=r"plan entry of block 'M0/seeds0_1' does not name its seeds' entries"):
        _job_configs(OmegaConf.create({"study": {"plan": str(plan), "job": "M0/seeds0_1"}}))


@pytest.mark.slow
def test_a_sweep_of_blocks_trains_evaluates_and_reports_as_lone_jobs(tmp_path):
    """Seeds 0 and 1 as one block job and seed 2 as a lone one, in one sweep: the block's seeds
    leave what the lone seed leaves (plus block.json), and the report and MLflow read all three
    alike. That a block seed computes what its lone run computes is tests/test_blocks.py's."""
    env = {**os.environ, "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    done = subprocess.run([sys.executable, "-m", "sigmarl", "sweep", "study=quick", "models=[M0]", "seeds=[0,1,2]",
                           "sweep.seeds_per_job=2", "ppo.iterations=2", "eval.n_sims=2", "eval.steps=40",
                           "study.scenarios=[Intersection,CPM]", "hydra.launcher.n_jobs=1"],
                          cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.count("trained and evaluated") == 3
    # sigmarl's own launch line and plain progress lines, not Hydra's `[HYDRA] #0 : ...` job lines
    assert "[HYDRA]" not in done.stdout + done.stderr and "][INFO] - " not in done.stdout + done.stderr
    assert "sigmarl sweep: 2 job(s) (M0/seeds0_1, M0/seed2)" in done.stdout
    runs = tmp_path / "runs" / "sigmarl-quick" / "M0"
    lone = runs / "seed2"
    assert not (lone / "block.json").exists()
    rows = pd.read_csv(lone / "evaluation_rows.csv")
    for seed in (0, 1):
        b = runs / f"seed{seed}"
        assert json.loads((b / "block.json").read_text())["seeds"] == [0, 1]
        # the same files as a lone run, plus the block's record
        assert {p.name for p in b.iterdir()} - {p.name for p in lone.iterdir()} == {"block.json"}
        assert list(pd.read_csv(b / "metrics.csv")["iteration"]) == [1, 2]
        block_rows = pd.read_csv(b / "evaluation_rows.csv")
        assert list(block_rows.columns) == list(rows.columns) and len(block_rows) == len(rows)
    multirun = tmp_path / "multirun" / "sigmarl-quick" / "M0"
    assert sorted(p.name for p in multirun.iterdir()) == ["seed2", "seeds0_1"]
    # the report reads block seeds as lone ones; MLflow holds a training run per seed, the block's tagged
    report = subprocess.run([sys.executable, "-m", "sigmarl", "report", "study=quick",
                             "study.scenarios=[Intersection,CPM]", "--no-figures", "--out", "report"],
                            cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert report.returncode == 0, report.stderr[-3000:]
    assert sorted(pd.read_csv(tmp_path / "report" / "seeds.csv")["seed"].unique()) == [0, 1, 2]
    import mlflow

    client = mlflow.MlflowClient(f"sqlite:///{tmp_path / 'mlflow.db'}")
    experiment = client.get_experiment_by_name("sigmarl-quick")
    training = client.search_runs([experiment.experiment_id], "tags.kind = 'training'")
    assert sorted(r.data.tags.get("block", "") for r in training) == ["", "M0 seeds 0,1", "M0 seeds 0,1"]


@pytest.mark.slow
def test_g3_blocks_extend_a_study_leaving_its_finished_seeds_alone(tmp_path, monkeypatch):
    """A study trained as `seeds=[0]`, extended by `seeds=[0,1,2] sweep.seeds_per_job=2`: the
    finished seed 0 gets no job (a block with it would stand at two iterations and fail), seeds
    1 and 2 train as a block, and seed 0's folder is left as it was, not marked failed."""
    monkeypatch.chdir(tmp_path)
    tiny = ["study=quick", "models=[M0]", "ppo=smoke", "ppo.iterations=1", "eval.n_sims=1", "eval.steps=5",
            "eval.scenarios=[Roundabout]", "threads=1", "hydra.launcher.n_jobs=1", OFF, f"runs_root={tmp_path}/runs"]
    assert main(["sweep", *tiny, "seeds=[0]"]) == 0
    seed0 = Run(tmp_path / "runs" / "M0" / "seed0")
    before = {p.name: p.stat().st_mtime_ns for p in seed0.dir.iterdir()}
    more = [*tiny, "seeds=[0,1,2]", "sweep.seeds_per_job=2"]
    assert [u.key for u in plan_sweep(more).units] == ["M0/seeds1_2"]
    assert main(["sweep", *more]) == 0
    assert not seed0.failed_file.exists()
    assert {p.name: p.stat().st_mtime_ns for p in seed0.dir.iterdir()} == before
    for seed in (1, 2):
        run = Run(tmp_path / "runs" / "M0" / f"seed{seed}")
        assert run.state == "evaluated"
        assert json.loads(run.block_file.read_text())["seeds"] == [1, 2]
