"""Seed blocks: S seeds of one training config trained in one process as one batched
computation compute what each seed computes alone (a block of one, `train`), keep their seeds
apart, write one seed's records each, and resume whole after a kill at any instant. One seed
trains as the lone path of earlier sigmarl trained it (its committed numbers).

Tolerance of "the same": a block's batched products over S > 1 seeds round differently from a
block of one's in the last bits. Measured at the smoke budget after one iteration (8 Adam
steps): all but a handful of each tensor's elements agree to ~1e-8, and those few (where a
gradient is near zero, so Adam's step m / sqrt(v) turns rounding noise into a step of up to
lr) by up to ~5e-6. So parameters are compared tensor by tensor in relative Frobenius norm
(|x - y| / |y| <= 1e-5), each element within the largest step Adam can take (lr x steps), and
the iteration's metrics within 1e-5 relative; the rollout itself (rewards, collisions,
episodes: spawns, noise and actions) is identical.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import forked
import pytest
import torch

from sigmarl.compose import block_seeds, compose_block, compose_config
from sigmarl.errors import SigmarlError
from sigmarl.run import BLOCK_FILE, NEXT_RESUME_FILE, RESUME_FILE, Run
from sigmarl.run.block_membership import check_membership
from sigmarl.training import checkpoint as ckpt
from sigmarl.training import metrics_file
from sigmarl.training.learner import Learner
from sigmarl.training.loop import train, train_block
from sigmarl.training.mappo import clip_grad_norm_per_seed, update
from sigmarl.training.records import commit_checkpoints, settle_checkpoints

SMOKE = ["ppo=smoke", "threads=1", "tracking.enabled=false"]
SEEDS = [0, 1, 2]
TIMING = ("frames_per_s", "time_collect_s", "time_advantage_s", "time_optimise_s")
ROLLOUT = ("episode_reward_mean", "reward_mean", "episodes", "train_agent_collision", "train_lane_collision")
# what a rollout counts: equal on any CPU (reward means are float sums, whose last bits move with
# the CPU's vector kernels: 4e-7 apart on an AMD EPYC with avx512_bf16)
COUNTS = ROLLOUT[2:]


def _weights(path: Path) -> dict[str, torch.Tensor]:
    state = ckpt.load(path)
    return {**{f"policy.{k}": v for k, v in state["policy"].items()},
            **{f"critic.{k}": v for k, v in state["critic"].items()}}


@pytest.fixture(scope="module")
def one_iteration(tmp_path_factory):
    """A block of three seeds and each seed alone (blocks of one), one smoke iteration each."""
    root = tmp_path_factory.mktemp("blocks")
    stop = [*SMOKE, "ppo.stop_after=1"]
    block = train_block([compose_config([*stop, f"seed={s}", f"run_dir={root}/block/seed{s}"]) for s in SEEDS])
    lone = [train(compose_config([*stop, f"seed={s}", f"run_dir={root}/lone/seed{s}"])) for s in SEEDS]
    return root, block, lone


@pytest.mark.slow
def test_a_block_seed_learns_what_it_learns_alone(one_iteration) -> None:
    root, _, _ = one_iteration
    adam_bound = 2e-4 * 2 * 4 * 1.01  # lr x (2 epochs x 4 minibatches): the most Adam moves an element
    for s in SEEDS:
        mine, alone = _weights(root / f"block/seed{s}/{RESUME_FILE}"), _weights(root / f"lone/seed{s}/{RESUME_FILE}")
        assert mine.keys() == alone.keys()
        for key in alone:
            diff = mine[key] - alone[key]
            assert float(diff.norm() / alone[key].norm()) <= 1e-5, (s, key)
            assert float(diff.abs().max()) <= adam_bound, (s, key)


@pytest.mark.slow
def test_a_block_seed_records_the_metrics_it_records_alone(one_iteration) -> None:
    root, block, lone = one_iteration
    for s, b, a in zip(SEEDS, block, lone, strict=True):
        (_, mine), = metrics_file.read(root / f"block/seed{s}/metrics.csv")
        (_, alone), = metrics_file.read(root / f"lone/seed{s}/metrics.csv")
        assert list(mine) == list(alone)  # the same columns, in the same order
        for name in alone:
            if name in TIMING:
                continue
            if name in ROLLOUT:
                assert mine[name] == alone[name], (s, name)  # same spawns, noise and actions
            else:
                assert math.isclose(mine[name], alone[name], rel_tol=1e-5, abs_tol=1e-9), (s, name)
        assert b.best_reward == a.best_reward and b.iterations == a.iterations == 1


@pytest.mark.slow
def test_a_block_seed_folder_is_its_folder_alone_plus_its_block(one_iteration) -> None:
    root, _, _ = one_iteration
    for s in SEEDS:
        block, lone = root / f"block/seed{s}", root / f"lone/seed{s}"
        assert {p.name for p in block.iterdir()} == {p.name for p in lone.iterdir()} | {BLOCK_FILE}
        assert json.loads((block / BLOCK_FILE).read_text())["seeds"] == SEEDS
        mine, alone = ckpt.load(block / RESUME_FILE), ckpt.load(lone / RESUME_FILE)
        assert mine.keys() == alone.keys()
        assert mine["optimizer"]["param_groups"] == alone["optimizer"]["param_groups"]
        for i, st in alone["optimizer"]["state"].items():  # Adam's moments, seed by seed
            assert torch.equal(mine["optimizer"]["state"][i]["step"], st["step"])
            for key in ("exp_avg", "exp_avg_sq"):
                assert float((mine["optimizer"]["state"][i][key] - st[key]).norm()) <= 1e-4 * float(st[key].norm()) + 1e-12
        # the config a block seed records is the one it records alone (seed and folder aside)
        assert mine["config"]["seed"] == s and mine["config"]["ppo"] == alone["config"]["ppo"]


@pytest.fixture(scope="module")
def learner():
    cfg = compose_config([*SMOKE, "ppo.num_envs=4", "ppo.frames_per_iteration=64", "ppo.minibatch_size=32"])
    block = Learner(cfg, SEEDS, torch.device("cpu"))
    block.reseed(0)
    from sigmarl.training.mappo import collect

    data = block.advantage(collect(block.batches))
    yield block, data
    block.close()


def _update_from(block, data, start_params, start_opt):
    with torch.no_grad():
        for p, q in zip(block.optimiser.param_groups[0]["params"], start_params, strict=True):
            p.copy_(q)
    block.optimiser.load_state_dict(start_opt)
    block.streams.seed([7, 8, 9])
    update(data, block.loss, block.optimiser, block.cfg.ppo)
    return [p.detach().clone() for p in block.optimiser.param_groups[0]["params"]]


def test_one_seeds_data_cannot_move_another_seed(learner) -> None:
    from sigmarl.training.ppo_loss import ADVANTAGE

    block, data = learner
    start = [p.detach().clone() for p in block.optimiser.param_groups[0]["params"]]
    opt = {k: v for k, v in block.optimiser.state_dict().items()}
    calm = _update_from(block, data, start, opt)
    wild = data.clone()
    adv = wild.get(ADVANTAGE).clone()
    e = adv.shape[0] // len(SEEDS)
    adv[e:2 * e] *= 1e6  # seed 1's advantages, a million times larger
    wild.set(ADVANTAGE, adv)
    perturbed = _update_from(block, wild, start, opt)
    for a, b in zip(calm, perturbed, strict=True):
        assert torch.equal(a[0], b[0]) and torch.equal(a[2], b[2])  # seeds 0 and 2: bit for bit
    assert any(not torch.equal(a[1], b[1]) for a, b in zip(calm, perturbed, strict=True))


def test_each_seed_is_clipped_by_its_own_gradient_norm() -> None:
    # seed 0: gradient norm 5 (3-4-0), clipped to 1; seed 1: norm 0.5, kept
    w = torch.zeros(2, 3, requires_grad=True)
    w.grad = torch.tensor([[3.0, 4.0, 0.0], [0.3, 0.0, 0.4]])
    norms = clip_grad_norm_per_seed([w], 1.0)
    assert torch.allclose(norms, torch.tensor([5.0, 0.5]))
    assert torch.allclose(w.grad, torch.tensor([[0.6, 0.8, 0.0], [0.3, 0.0, 0.4]]), atol=1e-6)


def test_one_seed_trains_as_the_lone_path_trained_it(tmp_path) -> None:
    """Seed 0 at the smoke budget against the numbers the former lone path (one seed, torchrl's
    modules, torch's global generator) recorded: tests/data/lone_smoke_seed0.json. On the
    machine that made them every value and weight is equal bit for bit; the tolerances are
    those above, for other kernels on other machines."""
    ref = json.loads((Path(__file__).parent / "data" / "lone_smoke_seed0.json").read_text())
    train(compose_config([*SMOKE, "seed=0", f"run_dir={tmp_path}/run"]))
    rows = metrics_file.read(tmp_path / "run/metrics.csv")
    assert [it for it, _ in rows] == [r["iteration"] for r in ref["metrics"]] == [1, 2, 3]
    for (it, got), want in zip(rows, ref["metrics"], strict=True):
        for name, value in want.items():
            if name in COUNTS and it == 1:
                assert got[name] == value, name  # the first rollout: the same initial weights, spawns, actions
            elif name != "iteration":
                # abs 1e-6: a loss near zero (1e-3 after cancellation) keeps the float32 error of its
                # O(0.1) terms (9e-8 measured on the AMD EPYC above)
                assert math.isclose(got[name], value, rel_tol=1e-5, abs_tol=1e-6), (it, name)
    weights = _weights(tmp_path / f"run/{RESUME_FILE}")
    assert weights.keys() == ref["weights"].keys()
    adam_bound = 2e-4 * 3 * 2 * 4 * 1.01  # lr x (3 iterations x 2 epochs x 4 minibatches)
    for key, want in ref["weights"].items():
        t = weights[key].double()
        assert math.isclose(float(t.norm()), want["norm"], rel_tol=1e-5), key
        assert abs(float(t.sum()) - want["sum"]) <= adam_bound * t.numel(), key
        assert max(abs(a - b) for a, b in zip(t.flatten()[:4].tolist(), want["first"], strict=True)) <= adam_bound


# ---- records, refusals and the two-phase commit ----------------------------------------------

def _state(iteration: int) -> dict:
    t = torch.ones(2)
    return {"format": ckpt.FORMAT, "kind": "resume", "iteration": iteration, "policy": {"w": t},
            "critic": {"w": t}, "optimizer": {"state": {}, "param_groups": []}, "rng": {}, "config": {},
            "dims": {"obs_dim": 1, "n_agents": 1, "action_low": -t, "action_high": t}}


def _iterations(runs) -> list[int]:
    return [ckpt.load(r.path(RESUME_FILE), resume=True)["iteration"] for r in runs]


def test_a_commit_cut_in_phase_one_keeps_the_old_resume_points(tmp_path) -> None:
    runs = [Run(tmp_path / f"seed{k}") for k in range(3)]
    commit_checkpoints(runs, [_state(5)] * 3)
    ckpt.save_atomic(_state(10), runs[0].path(NEXT_RESUME_FILE))  # killed before seed 1's was written
    settle_checkpoints(runs)
    assert _iterations(runs) == [5, 5, 5] and not runs[0].path(NEXT_RESUME_FILE).exists()


def test_a_commit_cut_in_phase_two_is_finished(tmp_path) -> None:
    runs = [Run(tmp_path / f"seed{k}") for k in range(3)]
    commit_checkpoints(runs, [_state(5)] * 3)
    for r in runs:
        ckpt.save_atomic(_state(10), r.path(NEXT_RESUME_FILE))
    runs[0].path(NEXT_RESUME_FILE).replace(runs[0].path(RESUME_FILE))  # killed after the first rename
    settle_checkpoints(runs)
    assert _iterations(runs) == [10, 10, 10]
    assert not any(r.path(NEXT_RESUME_FILE).exists() for r in runs)


def test_a_folder_of_another_block_or_a_lone_run_is_refused(tmp_path) -> None:
    runs = [Run(tmp_path / f"seed{k}") for k in range(3)]
    for r in runs:
        ckpt.save_atomic(_state(5), r.path(RESUME_FILE))
        r.write(BLOCK_FILE, json.dumps({"seeds": [0, 1, 2]}))
    check_membership(runs, [0, 1, 2])  # its own block resumes
    with pytest.raises(SigmarlError, match=r"belongs to the seed block \[0, 1, 2\].*seeds=\[0, 1, 2\]"):
        check_membership(runs[:2], [0, 1])  # the block's composition changed
    with pytest.raises(SigmarlError, match="cannot go on as a lone run"):
        check_membership(runs[:1], [0])
    lone = Run(tmp_path / "lone")
    ckpt.save_atomic(_state(5), lone.path(RESUME_FILE))
    with pytest.raises(SigmarlError, match="holds a lone training run"):
        check_membership([lone, runs[0]], [3, 0])
    (runs[0].dir / ckpt.FINAL_FILE).write_bytes(b"")  # a finished seed is anyone's to complete
    check_membership(runs[:1], [0])


@pytest.mark.parametrize("text, message", [
    ("seeds=[1.5]", "non-negative integers"), ("seeds=[abc]", "non-negative integers"),
    ("seeds=[1,1]", "twice"), ("seeds=[]", "non-negative integers"), ("seeds=[-1]", "non-negative"),
])
def test_bad_block_seeds_are_one_line(text, message) -> None:
    with pytest.raises(SigmarlError, match=message):
        block_seeds(text)


def test_block_seeds_take_lists_and_ranges() -> None:
    assert block_seeds("seeds=[3,1,2]") == [3, 1, 2]
    assert block_seeds("seeds=range(10,14)") == [10, 11, 12, 13]


def test_a_block_needs_a_folder_per_seed_and_no_seed_key(tmp_path) -> None:
    with pytest.raises(SigmarlError, match="not both"):
        compose_block(["seeds=[0,1]", "seed=3"])
    with pytest.raises(SigmarlError, match="run folder each"):
        compose_block(["seeds=[0,1]", f"run_dir={tmp_path}/x"])
    cfgs = compose_block(["seeds=[0,1]", f"runs_root={tmp_path}"])
    assert [Path(c.run_dir).name for c in cfgs] == ["seed0", "seed1"]
    assert len({c.fingerprint for c in cfgs}) == 1


# ---- kill -9 at every instant of a block's checkpoint, then resume -------------------------

# in the order a block meets them, each re-run going on from what the last kill left: before
# the first iteration, before a checkpoint, between the two phases of a commit, between a commit
# and its metrics, and in the middle of the renames of the last commit
KILLS = ["train:start", "train:iteration:1", "train:block-written:2", "train:checkpoint:4",
         "train:iteration:5", "train:block-renaming:6"]


@pytest.mark.slow
def test_a_block_killed_anywhere_resumes_to_the_uninterrupted_end(tmp_path) -> None:
    args = ["train", "seeds=[0,1]", *SMOKE, "ppo.iterations=6", "ppo.checkpoint_every=2"]
    calm = forked.run([*args, f"runs_root={tmp_path}/calm"], tmp_path)
    assert calm.returncode == 0, calm.stderr
    codes = []
    for point in KILLS:
        resume = ["resume=true"] if (tmp_path / "cut/M0/seed0" / RESUME_FILE).exists() else []
        codes.append(forked.run([*args, f"runs_root={tmp_path}/cut", *resume], tmp_path,
                                SIGMARL_CRASH_AT=point).returncode)
    last = forked.run([*args, f"runs_root={tmp_path}/cut", "resume=true"], tmp_path)
    assert codes == [-9] * len(KILLS) and last.returncode == 0, last.stderr
    for s in (0, 1):
        a, b = tmp_path / f"calm/M0/seed{s}", tmp_path / f"cut/M0/seed{s}"
        wa, wb = _weights(a / RESUME_FILE), _weights(b / RESUME_FILE)
        assert all(torch.equal(wa[k], wb[k]) for k in wa)
        fa, fb = ckpt.load(a / ckpt.FINAL_FILE)["policy"], ckpt.load(b / ckpt.FINAL_FILE)["policy"]
        assert all(torch.equal(fa[k], fb[k]) for k in fa)
        rows_a, rows_b = metrics_file.read(a / "metrics.csv"), metrics_file.read(b / "metrics.csv")
        assert [i for i, _ in rows_b] == [1, 2, 3, 4, 5, 6]  # one row per iteration, none lost or doubled
        assert [{k: v for k, v in r.items() if k not in TIMING} for _, r in rows_a] == \
               [{k: v for k, v in r.items() if k not in TIMING} for _, r in rows_b]
        assert not (b / NEXT_RESUME_FILE).exists()


@pytest.mark.parametrize("values", ["[1.5]", "[abc]", "[1,1]", "[-1]", "[4294967296]", "[true]", "range(3,6)", "[0,7]"])
def test_train_and_sweep_read_seeds_alike(values) -> None:
    """`sigmarl train seeds=...` and `sigmarl sweep seeds=...` take the same values, and refuse
    the same ones in the same words: one reader of seeds (`sigmarl.config.study.seed_list`)."""
    from sigmarl.config.study import seed_list
    from sigmarl.sweep.command import read_command

    def answer(read):
        try:
            return read()
        except SigmarlError as e:
            return str(e)

    train = answer(lambda: block_seeds(f"seeds={values}"))
    assert train == answer(lambda: seed_list(read_command([f"seeds={values}"]).seeds))
    assert train == {"range(3,6)": [3, 4, 5], "[0,7]": [0, 7]}.get(values, train)
    assert isinstance(train, list) == (values in ("range(3,6)", "[0,7]"))
