"""The paper's mean episode reward, estimated from a training batch (`episode_reward_mean_complete`).

Hand-worked batches check which episodes it counts; a real training shows the column in
metrics.csv, and a run begun without it (an older sigmarl) resumed without it; episodes whose
expected return is worked out by hand check it, and the paper's own count over a stream that is
never reset, against that number. On the real environment and a committed policy, its agreement
with a torchrl collector that never resets is measured by benchmarks/paper_episode_reward.py
(the figures are in docs/deviations.md)."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch
from tensordict import TensorDict

from sigmarl.cli import main
from sigmarl.errors import SigmarlError
from sigmarl.run import COMPLETE_REWARD_COLUMN, REWARD_COLUMN
from sigmarl.training import metrics_file
from sigmarl.training.mappo import complete_episode_reward, mark_batch_end, rollout_stats


def _batch(rewards: list[list[float]], dones: list[list[bool]], scales=(1.0, 2.0)) -> TensorDict:
    """A batch [E, T] with an agent per scale, each earning the rewards times its scale (by
    default 2 agents, the second earning twice the first's reward)."""
    r = torch.tensor(rewards)
    e, t = r.shape
    reward = torch.stack([r * k for k in scales], -1).unsqueeze(-1)  # [E, T, A, 1]
    done = torch.tensor(dones).unsqueeze(-1)
    nxt = TensorDict({"agents": TensorDict({"reward": reward}, [e, t, len(scales)]), "done": done,
                      "terminated": done.clone()}, [e, t])
    return mark_batch_end(TensorDict({"next": nxt}, [e, t]))


def test_the_episodes_that_began_max_steps_before_the_end_are_counted_whole() -> None:
    # T = 4, max_steps = 2: an episode that begins at step 0, 1 or 2 ends inside the batch.
    # env 0: episodes at steps 0-1 (reward 1 + 2) and 2-3 (4 + 8): both counted;
    # env 1: episodes 0 (5), 1-2 (1 + 1) and 3 (7, begun at step 3, cut by the batch end: left out).
    data = _batch([[1.0, 2.0, 4.0, 8.0], [5.0, 1.0, 1.0, 7.0]],
                  [[False, True, False, False], [True, False, True, False]])
    # agent-episodes: returns 3, 12, 5, 2 for the first agent, twice those for the second
    want = (3 + 12 + 5 + 2) * 3 / 8
    assert float(complete_episode_reward(data, max_steps=2)) == pytest.approx(want)
    stats = rollout_stats(data, max_steps=2)
    assert stats[COMPLETE_REWARD_COLUMN] == pytest.approx(want)
    # ours counts the cut segment (7) as a fifth episode
    assert stats[REWARD_COLUMN] == pytest.approx((3 + 12 + 5 + 2 + 7) * 3 / 10)


def test_with_rollouts_as_long_as_an_episode_each_environment_counts_its_first_episode() -> None:
    # T = max_steps = 3 (training: 128 and 128): env 0 collides at step 0, then runs cut;
    # env 1 runs the whole batch (a time-out at its last step)
    data = _batch([[-1.0, 2.0, 2.0], [1.0, 1.0, 1.0]], [[True, False, False], [False, False, False]])
    assert float(complete_episode_reward(data, max_steps=3)) == pytest.approx((-1 + 3) * 3 / 4)


def test_a_rollout_shorter_than_an_episode_has_no_estimate() -> None:
    data = _batch([[1.0, 1.0]], [[False, False]])
    assert complete_episode_reward(data, max_steps=3) is None
    assert COMPLETE_REWARD_COLUMN not in rollout_stats(data, max_steps=3)
    assert COMPLETE_REWARD_COLUMN not in rollout_stats(data)


def test_metrics_file_keeps_the_columns_its_run_began_with(tmp_path: Path) -> None:
    path = tmp_path / "metrics.csv"
    metrics_file.append(path, 1, {REWARD_COLUMN: 1.0, "lr": 1e-4})
    row = metrics_file.append(path, 2, {REWARD_COLUMN: 2.0, COMPLETE_REWARD_COLUMN: 2.5, "lr": 1e-4})
    assert row == {REWARD_COLUMN: 2.0, "lr": 1e-4}
    assert metrics_file.read(path) == [(1, {REWARD_COLUMN: 1.0, "lr": 1e-4}), (2, row)]
    with pytest.raises(SigmarlError, match="has the column.s. lr that this training does not log"):
        metrics_file.append(path, 3, {REWARD_COLUMN: 3.0})


def test_a_training_logs_the_estimate_and_a_run_begun_without_it_resumes_without_it(tmp_path: Path) -> None:
    # smoke: 8 environments x 32 steps; episodes of 32 steps make it estimable
    args = ["train", "ppo=smoke", "env.max_steps=32", "tracking.enabled=false"]
    new, old = tmp_path / "new", tmp_path / "old"
    assert main([*args, f"run_dir={new}"]) == 0
    rows = metrics_file.read(new / "metrics.csv")
    assert len(rows) == 3 and all(COMPLETE_REWARD_COLUMN in values for _, values in rows)
    assert main([*args, f"run_dir={old}", "ppo.stop_after=1"]) == 0
    path = old / "metrics.csv"
    header, *lines = path.read_text().splitlines()
    drop = header.split(",").index(COMPLETE_REWARD_COLUMN)  # as an older sigmarl wrote it
    path.write_text("\n".join(",".join(c for i, c in enumerate(line.split(",")) if i != drop)
                              for line in [header, *lines]) + "\n")
    assert main([*args, f"run_dir={old}", "resume=true"]) == 0
    rows = metrics_file.read(path)
    assert len(rows) == 3 and all(COMPLETE_REWARD_COLUMN not in values for _, values in rows)
    # the same computation either way: the columns both logged agree
    assert [v[REWARD_COLUMN] for _, v in rows] == [v[REWARD_COLUMN] for _, v in metrics_file.read(new / "metrics.csv")]


# ---- against the paper's definition, on episodes whose expected return is known exactly ----------

P_COLLIDE, MAX_STEPS, ENVS, BATCHES, PENALTY = 0.08, 16, 64, 150, 5.0


def _episode(rng) -> list[float]:
    """One episode's per-step rewards: 1 a step; each step ends it with a collision (reward 1 - 5)
    with probability P_COLLIDE; a time-out after MAX_STEPS."""
    for k in range(1, MAX_STEPS + 1):
        if rng.random() < P_COLLIDE:
            return [1.0] * (k - 1) + [1.0 - PENALTY]
    return [1.0] * MAX_STEPS


def _expected_return() -> float:
    """E[return] = sum_k (k - 5) p (1 - p)^(k - 1) + MAX_STEPS (1 - p)^MAX_STEPS."""
    p = P_COLLIDE
    return (sum((k - PENALTY) * p * (1 - p) ** (k - 1) for k in range(1, MAX_STEPS + 1))
            + MAX_STEPS * (1 - p) ** MAX_STEPS)


def _stream(rng, steps: int) -> tuple[list[float], list[bool]]:
    """One environment's rewards and done flags over `steps` steps, episode after episode."""
    rewards, dones = [], []
    while len(rewards) < steps:
        ep = _episode(rng)
        rewards += ep
        dones += [False] * (len(ep) - 1) + [True]
    return rewards[:steps], dones[:steps]


def test_the_estimate_from_reset_batches_matches_the_papers_mean_of_whole_episodes() -> None:
    """Ours resets every batch; the paper's stream never does and counts each episode whole at
    its end. Both laid out from the same kind of episodes, whose expected return is worked out
    above: the estimate and the paper's logged mean both find it; ours (the cut segment an
    episode) and the mean over the episodes a done ended (short ones favoured) do not."""
    import numpy as np

    rng = np.random.default_rng(0)
    want = _expected_return()
    estimate, ours, ended = [], [], []
    for _ in range(BATCHES):  # ours: every environment from a reset, T = MAX_STEPS
        streams = [_stream(rng, MAX_STEPS) for _ in range(ENVS)]
        data = _batch([r for r, _ in streams], [d for _, d in streams], scales=(1.0,))
        stats = rollout_stats(data, MAX_STEPS)
        estimate.append(stats[COMPLETE_REWARD_COLUMN])
        ours.append(stats[REWARD_COLUMN])
        real = torch.tensor([d for _, d in streams])  # the episodes' own ends, no batch end marked
        r = torch.tensor([x for x, _ in streams])
        starts = torch.cat([torch.ones(ENVS, 1, dtype=torch.bool), real[:, :-1]], 1)
        episode = torch.cumsum(starts.flatten().int(), 0) - 1
        returns = torch.zeros(int(episode.max()) + 1).index_add_(0, episode, r.flatten())
        ended.append(float(returns[torch.unique(episode[real.flatten()])].mean()))
    paper = []  # the paper's: each environment one stream; per batch, the episodes ending in it
    for rewards, dones in (_stream(rng, MAX_STEPS * BATCHES) for _ in range(ENVS)):
        running, per_batch = 0.0, [[] for _ in range(BATCHES)]
        for t, (x, d) in enumerate(zip(rewards, dones, strict=True)):
            running += x
            if d:
                per_batch[t // MAX_STEPS].append(running)
                running = 0.0
        paper.append(per_batch)
    paper_means = [float(np.mean([v for env in paper for v in env[b]])) for b in range(BATCHES)]
    assert want == pytest.approx(5.53, abs=0.01)
    # per batch the estimate's mean over 64 episodes has sd about 5 / 8; over 150 batches about 0.05
    assert np.mean(estimate) == pytest.approx(want, abs=0.2)
    assert np.mean(paper_means[1:]) == pytest.approx(want, abs=0.2)  # the first batch began at a reset
    assert np.mean(ours) < want - 1.0 and np.mean(ended) < want - 0.5
