"""Sweeps through the cluster launchers: submitit (its local executor, the SLURM launcher's code
path) and Ray (a local Ray cluster started here). For each: a failing job is isolated, a re-run
skips finished work and resumes an interrupted job, and `threads` per job is what the launcher
granted. Unit tests of the grant logic first."""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest
import yaml
from mlflow import MlflowClient

from sigmarl.cli import main
from sigmarl.compose import compose_config
from sigmarl.resources import granted_threads, job_threads
from sigmarl.sweep.job import run_job


def test_slurm_grant_wins_over_everything():
    env = {"SLURM_CPUS_PER_TASK": "6"}
    assert granted_threads({"cpus_per_task": 2, "n_jobs": 8}, env, ray_cpus=3.0, cores=64) == 6


def test_ray_grant_then_launcher_config_then_cores_per_job():
    assert granted_threads({}, {}, ray_cpus=3.0, cores=64) == 3
    assert granted_threads({"cpus_per_task": 2}, {}, cores=64) == 2
    # joblib: 64 cores shared by 6 parallel jobs -> 10 each; never below 1
    assert granted_threads({"n_jobs": 6}, {}, cores=64) == 10
    assert granted_threads({"n_jobs": 4}, {}, cores=2) == 1
    assert granted_threads({}, {}, cores=5) == 5


def test_outside_a_hydra_job_the_configured_threads_stay():
    assert job_threads(7) == 7


def test_a_sweep_job_works_in_the_sweep_folder(tmp_path, monkeypatch):
    """Wherever the worker process stands (Ray workers, reused joblib workers), the job's
    relative run folder is taken in the folder the sweep started from."""
    sweep, worker = tmp_path / "sweep", tmp_path / "worker"
    sweep.mkdir()
    worker.mkdir()
    monkeypatch.chdir(worker)
    monkeypatch.setenv("SIGMARL_SWEEP_DIR", str(sweep))
    # 400 agents cannot be placed on the intersection: the job fails at once, leaving failed.txt
    cfg = compose_config(["ppo=smoke", "env.n_agents=400", "tracking.enabled=false", "run_dir=runs/job"])
    assert run_job(cfg) == "failed"
    assert (sweep / "runs" / "job" / "failed.txt").exists() and not (worker / "runs").exists()


# Two models, a tiny budget. M0 is given a corrupt resume checkpoint (its job fails), M4 is
# interrupted after its first of two iterations (its job resumes).
TINY = ["study=quick", "ppo.iterations=2", "ppo.frames_per_iteration=128", "ppo.epochs=1",
        "ppo.minibatch_size=64", "eval.n_sims=2", "eval.steps=20", "eval.scenarios=[Intersection]"]


def _sweep_twice(root: Path, launcher: list[str], granted: int, twice: bool = True) -> None:
    """In this process (the jobs run where the launcher puts them), from the folder root;
    twice=False stops after the first sweep (isolation and resume only)."""
    uri = f"sqlite:///{root}/mlflow.db"
    common = [*TINY, f"tracking.tracking_uri={uri}"]
    dirs = {m: root / compose_config([*common, f"obs={p}"]).run_dir
            for m, p in (("M0", "full"), ("M4", "no_distance_to_boundaries"))}
    assert main(["train", *common, "obs=no_distance_to_boundaries", "ppo.stop_after=1"]) == 0
    m4_run = (dirs["M4"] / "mlflow_run_id").read_text()
    dirs["M0"].mkdir(parents=True)
    (dirs["M0"] / "checkpoint.pt").write_bytes(b"not a checkpoint")

    assert main(["sweep", *common, "models=[M0,M4]", *launcher]) == 1  # one job failed ...
    assert (dirs["M0"] / "failed.txt").exists() and not (dirs["M0"] / "final.pt").exists()
    # ... the other resumed its interrupted training (same MLflow run) and was evaluated
    assert (dirs["M4"] / "evaluated.txt").exists() and (dirs["M4"] / "final.pt").exists()
    assert (dirs["M4"] / "mlflow_run_id").read_text() == m4_run
    final_m4 = (dirs["M4"] / "final.pt").read_bytes()
    if not twice:
        return

    (dirs["M0"] / "checkpoint.pt").unlink()
    assert main(["sweep", *common, "models=[M0,M4]", *launcher]) == 0
    assert not (dirs["M0"] / "failed.txt").exists() and (dirs["M0"] / "evaluated.txt").exists()
    assert (dirs["M4"] / "final.pt").read_bytes() == final_m4  # finished work was skipped
    client = MlflowClient(tracking_uri=uri)
    exp = client.get_experiment_by_name("sigmarl-quick").experiment_id
    evals = client.search_runs([exp], "tags.kind = 'evaluation'")
    assert sorted(r.data.tags["model"] for r in evals) == ["M0", "M4"]  # M4 evaluated once
    # M0 trained fresh in the second sweep: its config records the launcher's grant
    assert yaml.safe_load((dirs["M0"] / "config.yaml").read_text())["threads"] == granted


@pytest.mark.slow
def test_submitit_local_sweep(tmp_path, monkeypatch):
    pytest.importorskip("hydra_plugins.hydra_submitit_launcher")
    monkeypatch.chdir(tmp_path)
    _sweep_twice(tmp_path, ["hydra/launcher=slurm_local", "hydra.launcher.cpus_per_task=3"], 3)


@pytest.fixture
def ray_cluster(tmp_path):
    """A one-node Ray cluster (`ray start --head --block`), ended by its process id; its
    workers inherit this environment (PYTHONPATH), as a cluster's share the job's."""
    pytest.importorskip("hydra_plugins.hydra_ray_launcher")
    import ray as ray_module

    ray = shutil.which("ray", path=str(Path(sys.executable).parent))
    if ray is None:
        pytest.skip("the ray program is not installed beside this Python (pip install \".[ray]\")")
    env = dict(os.environ, RAY_USAGE_STATS_ENABLED="0")
    with socket.socket() as sock:  # a free port for the head's GCS
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    log = tmp_path / "ray_head.log"
    short = tempfile.mkdtemp(prefix="ray", dir="/tmp")  # Ray's socket paths must stay short
    head = subprocess.Popen(
        [ray, "start", "--head", "--block", "--node-ip-address=127.0.0.1", f"--port={port}",
         "--num-cpus=6", "--include-dashboard=false", "--object-store-memory=100000000",
         f"--temp-dir={short}"],
        stdout=log.open("w"), stderr=subprocess.STDOUT, env=env, start_new_session=True)
    for _ in range(240):
        if "Ray runtime started" in log.read_text() or head.poll() is not None:
            break
        time.sleep(0.5)
    assert "Ray runtime started" in log.read_text(), log.read_text()[-3000:]
    address = f"127.0.0.1:{port}"
    yield address
    ray_module.shutdown()  # the sweep made this process a Ray driver
    head.terminate()
    try:
        head.wait(timeout=60)
    except subprocess.TimeoutExpired:
        os.killpg(head.pid, 9)
    shutil.rmtree(short, ignore_errors=True)


@pytest.mark.slow
def test_ray_sweep_on_a_local_cluster(tmp_path, monkeypatch, ray_cluster):
    root = tmp_path / "work"
    root.mkdir()
    monkeypatch.chdir(root)
    _sweep_twice(root, ["hydra/launcher=ray", f"hydra.launcher.ray.init.address={ray_cluster}",
                        "hydra.launcher.ray.remote.num_cpus=3"], 3)


@pytest.fixture
def slurm_cluster(monkeypatch):
    """A one-node SLURM cluster started by scripts/slurm_local.sh (needs root and slurm-wlm)."""
    if os.geteuid() != 0 or not all(shutil.which(p, path="/usr/sbin:/usr/bin") for p in ("slurmctld", "munged")):
        pytest.skip("needs root and Debian's slurm-wlm and munge (apt-get install slurm-wlm munge)")
    pytest.importorskip("hydra_plugins.hydra_submitit_launcher")
    script = Path(__file__).resolve().parents[1] / "scripts" / "slurm_local.sh"
    folder = tempfile.mkdtemp(prefix="slurm", dir="/tmp")
    env = dict(os.environ, SLURM_LOCAL_DIR=folder)
    started = subprocess.run([str(script), "start"], env=env, capture_output=True, text=True)
    try:
        assert started.returncode == 0, started.stdout + started.stderr
        monkeypatch.setenv("SLURM_CONF", f"{folder}/slurm.conf")
        yield
    finally:
        subprocess.run([str(script), "stop"], env=env)
        shutil.rmtree(folder, ignore_errors=True)


@pytest.mark.slow
def test_slurm_sweep_on_a_local_cluster(tmp_path, monkeypatch, slurm_cluster):
    monkeypatch.chdir(tmp_path)
    _sweep_twice(tmp_path, ["hydra/launcher=slurm", "hydra.launcher.cpus_per_task=1",
                            "hydra.launcher.mem_gb=1", "hydra.launcher.timeout_min=10"], 1, twice=False)
