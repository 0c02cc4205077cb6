"""The fifth reliability round's config faults through the command line (fault H2 and
H6-H9): each ends in one line and exit code 2 before any run folder or MLflow store exists.
test_config_fuzz.py covers every key from the schema; these are the round's reproductions."""

from __future__ import annotations

import os

import pytest
from cli_errors import one_line_exit_2

from sigmarl.config import Config
from sigmarl.errors import SigmarlError
from sigmarl.resources import THREADS_PER_CPU, check_threads, use_threads
from sigmarl.training.budget import needed_bytes

SMOKE = ["ppo=smoke", "tracking.enabled=false"]


@pytest.mark.parametrize("override, says", [
    ("ppo.gamma=2", "ppo.gamma must be in [0, 1], got 2.0"),  # H6: trained to losses near 1e14
    ("ppo.lmbda=3", "ppo.lmbda must be in [0, 1], got 3.0"),
    ("ppo.clip_epsilon=1", "ppo.clip_epsilon must be in (0, 1), got 1.0"),  # H8: "math domain error"
    ("device=cuda:abc", "device='cuda:abc' is not cpu, cuda or cuda:N"),  # H9: a traceback
    ("device=cpu:abc", "device='cpu:abc' is not cpu, cuda or cuda:N"),
    ("threads=1000000", "threads must be in 1..1024, got 1000000"),  # H2: the machine ran out of process ids
    ("ppo.frames_per_iteration=1000000000000", "ppo.frames_per_iteration must be in 1..1073741824"),  # H7
    ("network.hidden=[100000,100000]", "network.hidden must be in 1..65536, got 100000"),
])
def test_the_rounds_bad_values_are_one_line_before_anything_exists(override, says, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MLFLOW_TRACKING_URI", f"sqlite:///{tmp_path}/mlflow.db")
    line = one_line_exit_2(["train", *SMOKE, "tracking.enabled=true", override], capsys)
    assert says in line
    assert list(tmp_path.iterdir()) == []  # no run folder, no store


def test_threads_are_held_to_the_cpus_where_the_work_runs():
    """A generous cap of the machine's own CPUs, checked in the process that computes (a sweep
    job's, on its node), not by the schema's fixed cap alone."""
    check_threads(THREADS_PER_CPU * 2, cpus=2)
    with pytest.raises(SigmarlError, match=r"threads=9 is more than 4 x the 2 CPUs of this machine"):
        check_threads(9, cpus=2)
    with pytest.raises(SigmarlError, match="CPUs of this machine"):
        use_threads(THREADS_PER_CPU * (os.cpu_count() or 1) + 1)


def test_threads_beyond_this_machine_are_refused_before_a_run_folder(tmp_path, capsys, monkeypatch):
    threads = THREADS_PER_CPU * (os.cpu_count() or 1) + 1
    if threads > 1024:
        pytest.skip("this machine's cap is above the schema's")
    monkeypatch.chdir(tmp_path)
    line = one_line_exit_2(["train", *SMOKE, f"threads={threads}"], capsys)
    assert f"threads={threads} is more than" in line
    assert list(tmp_path.iterdir()) == []


def test_the_memory_bound_is_hand_worked():
    # hidden 256x256 and an 8-entry input layer: 256*256 + 8*256 = 67584 weights, 4 copies of
    # 2 networks; 4096 frames x 4 agents x 8 entries x 2 = 262144 floats; 4 bytes each
    cfg = Config(model="M0", runs_root="", run_dir="")
    cfg.ppo.frames_per_iteration, cfg.env.n_agents = 4096, 4
    assert needed_bytes(cfg) == 4 * (2 * 4 * 67584 + 262144) == 3211264
    assert needed_bytes(cfg, seeds=3) == 3 * 3211264


def test_the_memory_bound_is_below_what_the_networks_hold():
    """A lower bound: the real actor and critic hold more weights than it counts."""
    import torch

    from sigmarl.config import NetworkConfig
    from sigmarl.training.networks import make_actor, make_critic

    net = NetworkConfig(hidden=[64, 32])
    actor = make_actor(net, 8, 3, torch.full((2,), -1.0), torch.full((2,), 1.0))
    critic = make_critic(net, 8, 3)
    weights = sum(p.numel() for m in (actor, critic) for p in m.parameters())
    counted = 64 * 32 + 8 * 64  # per network
    assert 2 * counted <= weights


def test_a_training_beyond_free_memory_is_refused_before_its_run_exists(tmp_path, capsys, monkeypatch):
    """H7 within the schema's caps: three layers of 65536 need over 250 GiB of weights alone."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MLFLOW_TRACKING_URI", f"sqlite:///{tmp_path}/mlflow.db")
    line = one_line_exit_2(["train", *SMOKE, "tracking.enabled=true", "network.hidden=[65536,65536,65536]"], capsys)
    assert "this training needs at least" in line and "GiB free here" in line
    assert list(tmp_path.iterdir()) == []
