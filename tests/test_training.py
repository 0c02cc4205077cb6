"""MAPPO training end to end at the smoke budget, plus its pieces against hand-worked numbers.

The module trains a handful of smoke runs once (fixture `runs`) and checks resume, seeding,
checkpoints and the MLflow record against them.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import pytest
import torch
from tensordict import TensorDict
from tensordict.nn import TensorDictModule
from torchrl.envs.utils import ExplorationType, set_exploration_type

from sigmarl.cli import main
from sigmarl.compose import compose_config
from sigmarl.config import PPOConfig
from sigmarl.training import checkpoint as ckpt
from sigmarl.training import load_policy, train
from sigmarl.training.loop import learning_rate
from sigmarl.training.mappo import make_gae, mark_batch_end, rollout_stats
from sigmarl.training.networks import make_actor

SMOKE = ["ppo=smoke", "threads=1"]
LOSSES = ("loss_objective", "loss_critic", "loss_entropy", "entropy")


def _weights(path: Path) -> dict[str, torch.Tensor]:
    state = ckpt.load(path)
    return {**{f"policy.{k}": v for k, v in state["policy"].items()},
            **{f"critic.{k}": v for k, v in state["critic"].items()}}


def _equal(a: dict[str, torch.Tensor], b: dict[str, torch.Tensor]) -> bool:
    return a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Smoke trainings: full (tracked), interrupted + resumed via the CLI (tracked),
    the same seed again and another seed (untracked)."""
    root = tmp_path_factory.mktemp("train")
    uri = f"sqlite:///{root}/mlflow.db"
    tracked = [f"tracking.tracking_uri={uri}", "tracking.experiment=test-training"]
    full = train(compose_config([*SMOKE, *tracked, f"run_dir={root}/full"]))
    stop_rc = main(["train", *SMOKE, *tracked, f"run_dir={root}/resumed", "ppo.stop_after=1"])
    stopped_bytes = (root / "resumed" / ckpt.RESUME_FILE).read_bytes()
    stopped = ckpt.load(root / "resumed" / ckpt.RESUME_FILE)
    resume_rc = main(["train", *SMOKE, *tracked, f"run_dir={root}/resumed", "resume=true"])
    again = train(compose_config([*SMOKE, "tracking.enabled=false", f"run_dir={root}/again"]))
    other = train(compose_config([*SMOKE, "tracking.enabled=false", "seed=1",
                                  f"run_dir={root}/other"]))
    return SimpleNamespace(root=root, uri=uri, full=full, again=again, other=other,
                           stop_rc=stop_rc, resume_rc=resume_rc, stopped=stopped,
                           stopped_bytes=stopped_bytes)


def test_resumed_run_ends_with_the_uninterrupted_weights(runs) -> None:
    assert runs.stop_rc == 0 and runs.resume_rc == 0
    assert runs.stopped["iteration"] == 1
    final = ckpt.load(runs.root / "resumed" / ckpt.FINAL_FILE)
    assert final["iteration"] == 3
    assert _equal(_weights(runs.root / "full" / ckpt.RESUME_FILE),
                  _weights(runs.root / "resumed" / ckpt.RESUME_FILE))


def test_same_seed_same_losses_and_weights_other_seed_differs(runs) -> None:
    for key in LOSSES:
        assert [h[key] for h in runs.full.history] == [h[key] for h in runs.again.history]
        assert [h[key] for h in runs.full.history] != [h[key] for h in runs.other.history]
    full = _weights(runs.root / "full" / ckpt.RESUME_FILE)
    assert _equal(full, _weights(runs.root / "again" / ckpt.RESUME_FILE))
    assert not _equal(full, _weights(runs.root / "other" / ckpt.RESUME_FILE))


def test_training_moves_the_weights_and_losses_are_finite(runs) -> None:
    after_one = {**{f"policy.{k}": v for k, v in runs.stopped["policy"].items()},
                 **{f"critic.{k}": v for k, v in runs.stopped["critic"].items()}}
    assert not _equal(_weights(runs.root / "full" / ckpt.RESUME_FILE), after_one)
    assert ckpt.load(runs.root / "resumed" / ckpt.RESUME_FILE)["iteration"] == 3
    for h in runs.full.history:
        assert all(math.isfinite(h[k]) for k in LOSSES)


def test_best_checkpoint_is_the_first_best_rounded_reward(runs) -> None:
    rewards = [round(h["episode_reward_mean"], 2) for h in runs.full.history]
    best_iteration = rewards.index(max(rewards)) + 1
    best = ckpt.load(runs.root / "full" / ckpt.BEST_FILE)
    assert best["iteration"] == best_iteration
    assert best["best_reward"] == max(rewards) == runs.full.best_reward


def test_mlflow_holds_params_tags_metric_histories_and_artifacts(runs) -> None:
    from mlflow import MlflowClient

    client = MlflowClient(runs.uri)
    exp = client.get_experiment_by_name("test-training")
    by_dir = {r.data.params["run_dir"]: r for r in client.search_runs([exp.experiment_id])}
    assert len(by_dir) == 2  # the resume went into the interrupted run, not a new one
    run = by_dir[str(runs.root / "full")]
    assert run.info.status == "FINISHED" and run.info.run_id == runs.full.run_id
    assert run.data.tags["model"] == "M0" and run.data.tags["obs"] == "E,V,DA,DB,DC"
    assert run.data.tags["seed"] == "0"
    assert run.data.params["ppo.lr"] == "0.0002" and run.data.params["ppo.iterations"] == "3"
    assert run.data.params["network.hidden"] == "[256, 256]"
    # the composed training config and what names the run, not the study's, evaluation's or store's keys
    params = run.data.params
    assert params["env.reward.progress"] and params["rules.drag_dynamics"] == "False" and params["map.route_set"]
    assert not [k for k in params if k.split(".")[0] in ("study", "eval", "tracking", "sweep")]
    assert "map.ramp_angle" not in params  # the CPM map is not built from an on-ramp's keys
    assert len(params) < 90
    for key in ("episode_reward_mean", *LOSSES, "lr", "frames_per_s",
                "train_agent_collision", "train_lane_collision"):
        history = client.get_metric_history(run.info.run_id, key)
        assert sorted(m.step for m in history) == [1, 2, 3], key
    lr = sorted(client.get_metric_history(run.info.run_id, "lr"), key=lambda m: m.step)
    assert [m.value for m in lr] == pytest.approx([2e-4, 1.05e-4, 1e-5])  # linear, by hand
    artifacts = {a.path for a in client.list_artifacts(run.info.run_id)}
    assert artifacts == {"best.pt", "final.pt", "config.yaml"}
    local = client.download_artifacts(run.info.run_id, "final.pt", str(runs.root / "dl"))
    assert Path(local).read_bytes() == (runs.root / "full" / ckpt.FINAL_FILE).read_bytes()


def test_resumed_mlflow_run_has_each_iteration_once(runs) -> None:
    from mlflow import MlflowClient

    client = MlflowClient(runs.uri)
    run_id = (runs.root / "resumed" / "mlflow_run_id").read_text().strip()
    assert runs.stopped["mlflow_run_id"] == run_id
    run = client.get_run(run_id)
    assert run.info.status == "FINISHED"
    history = client.get_metric_history(run_id, "loss_objective")
    assert sorted(m.step for m in history) == [1, 2, 3]
    assert [m.value for m in sorted(history, key=lambda m: m.step)] == pytest.approx(
        [h["loss_objective"] for h in runs.full.history]
    )


def test_metrics_csv_holds_each_iteration_once_with_the_logged_values(runs) -> None:
    import pandas as pd
    from mlflow import MlflowClient

    timing = ["frames_per_s", "time_collect_s", "time_advantage_s", "time_optimise_s"]
    full = pd.read_csv(runs.root / "full" / "metrics.csv")
    assert list(full["iteration"]) == [1, 2, 3]
    for key, values in full.drop(columns="iteration").items():
        assert list(values) == [h[key] for h in runs.full.history], key
    # the resumed run recomputed iteration 1's row once, not twice, with the same values
    resumed = pd.read_csv(runs.root / "resumed" / "metrics.csv")
    assert list(resumed["iteration"]) == [1, 2, 3]
    pd.testing.assert_frame_equal(resumed.drop(columns=timing), full.drop(columns=timing))
    client = MlflowClient(runs.uri)
    run_id = (runs.root / "resumed" / "mlflow_run_id").read_text().strip()
    for key in ("episode_reward_mean", "loss_critic", "frames_per_s"):
        history = sorted(client.get_metric_history(run_id, key), key=lambda m: m.step)
        assert [m.value for m in history] == list(resumed[key]), key


def test_finished_run_resumes_to_nothing(runs, capsys) -> None:
    before = (runs.root / "full" / ckpt.FINAL_FILE).read_bytes()
    assert main(["train", *SMOKE, "tracking.enabled=false", f"run_dir={runs.root}/full",
                 "resume=true"]) == 0
    assert "already finished" in capsys.readouterr().out
    assert (runs.root / "full" / ckpt.FINAL_FILE).read_bytes() == before


def test_policy_loads_for_another_agent_count_and_acts_as_box_tanh_mean(runs) -> None:
    actor, state = load_policy(runs.root / "full" / ckpt.BEST_FILE, n_agents=6)
    obs = torch.randn(5, 6, state["dims"]["obs_dim"])
    td = TensorDict({"agents": TensorDict({"observation": obs}, [5, 6])}, [5])
    with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
        out = actor(td)
    high = state["dims"]["action_high"]
    assert torch.allclose(out["agents", "action"], high * torch.tanh(out["agents", "loc"]))
    assert out["agents", "action"].shape == (5, 6, 2)


# ---- bad input ---------------------------------------------------------------------------


def test_unknown_override_names_the_key(capsys) -> None:
    assert main(["train", "ppo.no_such_key=1"]) == 2
    assert "no_such_key" in capsys.readouterr().err


def test_unreachable_store_fails_before_training(tmp_path, monkeypatch, capsys) -> None:
    monkeypatch.setenv("MLFLOW_HTTP_REQUEST_MAX_RETRIES", "0")
    rc = main(["train", *SMOKE, f"run_dir={tmp_path}/run",
               "tracking.tracking_uri=http://127.0.0.1:9"])
    assert rc == 2
    err = capsys.readouterr().err
    assert "http://127.0.0.1:9" in err and "unreachable" in err and "Traceback" not in err
    assert not (tmp_path / "run" / ckpt.RESUME_FILE).exists()


def test_corrupt_checkpoint_is_one_message_and_nothing_is_touched(runs, tmp_path, capsys) -> None:
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    for name in (ckpt.BEST_FILE, ckpt.FINAL_FILE):
        (run_dir / name).write_bytes((runs.root / "full" / name).read_bytes())
    (run_dir / ckpt.RESUME_FILE).write_bytes(b"PK\x03\x04 half a zip file")
    before = {p.name: p.read_bytes() for p in run_dir.iterdir()}
    rc = main(["train", *SMOKE, "tracking.enabled=false", f"run_dir={run_dir}", "resume=true"])
    assert rc == 2
    err = capsys.readouterr().err
    assert "unreadable" in err and str(run_dir / ckpt.RESUME_FILE) in err
    assert {p.name: p.read_bytes() for p in run_dir.iterdir()} == before


def test_resume_needs_a_checkpoint_and_a_fresh_run_refuses_to_overwrite(tmp_path, capsys) -> None:
    run_dir = tmp_path / "run"
    assert main(["train", *SMOKE, "tracking.enabled=false", f"run_dir={run_dir}",
                 "resume=true"]) == 2
    assert "no checkpoint" in capsys.readouterr().err
    run_dir.mkdir()
    (run_dir / ckpt.RESUME_FILE).write_bytes(b"x")
    assert main(["train", *SMOKE, "tracking.enabled=false", f"run_dir={run_dir}"]) == 2
    assert "resume=true" in capsys.readouterr().err
    assert (run_dir / ckpt.RESUME_FILE).read_bytes() == b"x"


def test_resume_with_another_training_config_is_refused(runs, tmp_path, capsys) -> None:
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    (run_dir / ckpt.RESUME_FILE).write_bytes(runs.stopped_bytes)
    rc = main(["train", *SMOKE, "tracking.enabled=false", f"run_dir={run_dir}", "resume=true",
               "ppo.lr=0.001"])
    assert rc == 2
    assert "ppo.lr" in capsys.readouterr().err


def test_impossible_budget_is_refused(capsys) -> None:
    assert main(["train", "ppo=smoke", "ppo.frames_per_iteration=100", "ppo.num_envs=8"]) == 2
    assert "multiple of" in capsys.readouterr().err


# ---- pieces against hand-worked numbers ---------------------------------------------------


def test_learning_rate_decays_linearly_to_the_final_value() -> None:
    ppo = PPOConfig(lr=2e-4, lr_final=1e-5, iterations=250)
    assert learning_rate(ppo, 0) == pytest.approx(2e-4)
    assert learning_rate(ppo, 249) == pytest.approx(1e-5)
    assert learning_rate(ppo, 83) == pytest.approx(2e-4 - 1.9e-4 * 83 / 249)


def test_fresh_actor_scale_is_one_at_zero_and_floored() -> None:
    net = compose_config([]).network
    high = torch.tensor([0.8, math.radians(35)])
    actor = make_actor(net, obs_dim=3, n_agents=2, action_low=-high, action_high=high)
    last = actor.module[0].module[0].params["4"]  # output layer of the shared MLP
    td = TensorDict({"agents": TensorDict({"observation": torch.randn(1, 2, 3)}, [1, 2])}, [1])
    with torch.no_grad():
        last["weight"].zero_()
        last["bias"].zero_()
        out = actor(td.clone())
        assert torch.allclose(out["agents", "scale"], torch.ones(1, 2, 2))
        assert torch.equal(out["agents", "loc"], torch.zeros(1, 2, 2))
        last["bias"].fill_(-50.0)
        assert torch.allclose(actor(td.clone())["agents", "scale"], torch.full((1, 2, 2), 1e-4))


def _batch(terminated_last: bool) -> TensorDict:
    """1 env, 3 steps, 1 agent; observation = value = t + 1 (next: t + 2); reward 1."""
    obs = torch.tensor([1.0, 2.0, 3.0]).view(1, 3, 1, 1)
    done = torch.zeros(1, 3, 1, dtype=torch.bool)
    term = done.clone()
    term[0, 2] = terminated_last
    done[0, 2] = terminated_last
    return TensorDict(
        {
            "agents": TensorDict({"observation": obs}, [1, 3, 1]),
            "next": TensorDict(
                {
                    "agents": TensorDict(
                        {"observation": obs + 1, "reward": torch.ones(1, 3, 1, 1)}, [1, 3, 1]
                    ),
                    "done": done,
                    "terminated": term,
                },
                [1, 3],
            ),
        },
        [1, 3],
    )


@pytest.mark.parametrize("terminated_last", [False, True])
def test_gae_bootstraps_the_batch_end_and_not_a_termination(terminated_last: bool) -> None:
    gamma, lmbda = 0.99, 0.9
    critic = TensorDictModule(lambda o: o.clone(), [("agents", "observation")],
                              [("agents", "state_value")])
    gae = make_gae(critic, PPOConfig(gamma=gamma, lmbda=lmbda))
    data = mark_batch_end(_batch(terminated_last))
    assert data["next", "done"][0, 2] and data["next", "agents", "done"].shape == (1, 3, 1, 1)
    gae(data)
    v, v_next = [1.0, 2.0, 3.0], [2.0, 3.0, 4.0]
    last_next = 0.0 if terminated_last else v_next[2]  # cut by the batch end: bootstrap
    deltas = [1 + gamma * v_next[0] - v[0], 1 + gamma * v_next[1] - v[1],
              1 + gamma * last_next - v[2]]
    adv = [0.0] * 3
    adv[2] = deltas[2]
    adv[1] = deltas[1] + gamma * lmbda * adv[2]
    adv[0] = deltas[0] + gamma * lmbda * adv[1]
    assert data["agents", "advantage"].flatten().tolist() == pytest.approx(adv)
    assert data["agents", "value_target"].flatten().tolist() == pytest.approx(
        [a + b for a, b in zip(adv, v, strict=True)]
    )


def test_episode_reward_is_summed_per_episode_and_averaged() -> None:
    # env 0: episodes [1, 2] and [3]; env 1: one episode [0, 1, -1]; 2 agents with rewards x, 2x
    r = torch.tensor([[1.0, 2.0, 3.0], [0.0, 1.0, -1.0]])
    reward = torch.stack([r, 2 * r], -1).unsqueeze(-1)  # [2, 3, 2, 1]
    done = torch.tensor([[False, True, False], [False, False, False]]).unsqueeze(-1)
    info = torch.tensor([[1.0, 0.0, 0.0], [0.0, 0.0, 0.0]]).view(2, 3, 1, 1).expand(2, 3, 2, 1)
    data = TensorDict(
        {"next": TensorDict(
            {"agents": TensorDict({"reward": reward,
                                   "info": TensorDict({"agent_collision": info}, [2, 3, 2])},
                                  [2, 3, 2]),
             "done": done, "terminated": done.clone()}, [2, 3])},
        [2, 3],
    )
    stats = rollout_stats(mark_batch_end(data))
    # episodes per agent: 3, 3, 0 for agent 0 (mean 2); 6, 6, 0 for agent 1 (mean 4)
    assert stats["episode_reward_mean"] == pytest.approx(3.0)
    assert stats["episodes"] == 3
    assert stats["train_agent_collision"] == pytest.approx(1 / 6)


COMMITTED = Path(__file__).resolve().parents[1] / "results" / "paper-budget" / "M0" / "seed0" / "checkpoint.pt"


@pytest.mark.slow
def test_a_committed_lone_checkpoint_loads_and_trains_on_in_the_one_path() -> None:
    """results/ holds resume points the former lone path wrote (the torchrl modules' weights, one
    Adam's state): the learner, alone or as seed 1 of a block, loads one as it is, gives it back
    bit for bit, and trains on from it (a smaller batch: the weights do not depend on it)."""
    from sigmarl.training.learner import Learner
    from sigmarl.training.loop import _load_state

    state = ckpt.load(COMMITTED, resume=True)
    cfg = ckpt.config_of(state, COMMITTED)
    small = replace(cfg, ppo=replace(cfg.ppo, num_envs=4, frames_per_iteration=128, minibatch_size=64, epochs=1))
    for seeds, k in (([cfg.seed], 0), ([cfg.seed + 1, cfg.seed], 1)):
        learner = Learner(small, seeds, torch.device("cpu"))
        try:
            _load_state(learner, k, state, COMMITTED)
            back = learner.state(k)
            for part in ("policy", "critic"):
                assert back[part].keys() == state[part].keys()
                assert all(torch.equal(back[part][n], t) for n, t in state[part].items()), part
            assert back["optimizer"]["state"].keys() == state["optimizer"]["state"].keys()
            for i, st in state["optimizer"]["state"].items():
                assert all(torch.equal(back["optimizer"]["state"][i][key], st[key]) for key in st), i
            assert back["optimizer"]["param_groups"][0]["params"] == state["optimizer"]["param_groups"][0]["params"]
            learner.reseed(state["iteration"])
            metrics, _ = learner.iterate()
            assert all(math.isfinite(v) for v in metrics[k].values())
            moved = learner.state(k)["policy"]
            assert any(not torch.equal(moved[n], t) for n, t in state["policy"].items())
        finally:
            learner.close()
