"""`train(cfg)` and `train_block(cfgs)`: the MAPPO training loop, checkpointed, resumable,
tracked in MLflow, for the seeds of one training config trained as one batched computation
(`learner.Learner`); one seed is a block of one, and runs the same code.

Exact resume: every iteration starts from a state that depends only on (seed, iteration): the
generators and the environment are reseeded and every environment is reset. A checkpoint after
iteration k (weights, optimiser, best reward) is therefore all that iteration k+1 needs, and a
resumed run ends with the same weights as an uninterrupted one. A block resumes whole, from the
one iteration its seeds' checkpoints share (`records`).
"""

from __future__ import annotations

import contextlib
import os
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import torch

from sigmarl import crash
from sigmarl.compose.validate import check
from sigmarl.config import Config, PPOConfig, as_dict
from sigmarl.env.factory import check_room
from sigmarl.errors import SigmarlError
from sigmarl.identity import differences
from sigmarl.maps import load_map
from sigmarl.paths import ensure_writable
from sigmarl.progress import Progress
from sigmarl.run import Run
from sigmarl.run.block_membership import block_name, check_membership, write_membership
from sigmarl.run_owner import check_ours
from sigmarl.tracking import Tracker, flatten, open_tracker, provenance
from sigmarl.training import checkpoint as ckpt
from sigmarl.training.budget import check_fits
from sigmarl.training.learner import Learner, iteration_seed
from sigmarl.training.networks import make_actor
from sigmarl.training.ppo_loss import resolve_precision
from sigmarl.training.records import SeedRun, commit_checkpoints, finish_records, settle_checkpoints

__all__ = ["TrainResult", "iteration_seed", "learning_rate", "load_policy", "train", "train_block"]


@dataclass
class TrainResult:
    run_dir: Path
    iterations: int  # completed so far
    finished: bool
    best_reward: float | None
    run_id: str | None
    history: list[dict[str, float]] = field(default_factory=list)  # this invocation's iterations


# what a resume must share with the interrupted run (anything else, e.g. threads, device,
# evaluation settings, may change); ppo.stop_after is the interruption itself
RESUME_MUST_MATCH = ("map.", "obs.", "env.", "network.", "ppo.", "seed", "rules.")


def learning_rate(ppo: PPOConfig, iteration: int) -> float:
    """Linear from ppo.lr at the first iteration (0) to ppo.lr_final at the last."""
    frac = iteration / max(ppo.iterations - 1, 1)
    return ppo.lr + (ppo.lr_final - ppo.lr) * frac


def _device(name: str) -> torch.device:
    """The device to train on. Its name was checked at composition; whether this machine has
    the GPU it names is known only here."""
    device = torch.device(name)
    if device.type == "cuda" and not torch.cuda.is_available():
        raise SigmarlError("device=cuda but no CUDA GPU is available; use device=cpu")
    return device


def config_changes(saved: dict[str, Any], cfg: Config) -> list[str]:
    """Training settings in which `cfg` differs from a checkpoint's config (the plain dict it
    holds). A knob the saved config lacks (added to sigmarl since) counts only if set away from
    its default, and one that no longer exists cannot change anything: a checkpoint from an
    older sigmarl resumes."""
    old, new = flatten(saved), flatten(as_dict(cfg))
    default = flatten(as_dict(Config()))
    return [key for key in sorted(new)
            if key.startswith(RESUME_MUST_MATCH) and key != "ppo.stop_after"
            and new[key] != old.get(key, default.get(key))]


def _resume_point(cfg: Config, run: Run, device: torch.device) -> dict[str, Any] | None:
    """The checkpoint to resume from, or None to start from scratch.

    A folder without `checkpoint.pt` holds no training to continue (a run killed before its
    first checkpoint leaves at most config.yaml and mlflow_run_id), so it starts from scratch
    without asking; one with `checkpoint.pt` is resumed with resume=true and never overwritten.
    """
    path, run_dir = run.resume_file, run.dir
    if not path.exists():
        if run.final_file.exists():
            raise SigmarlError(f"{run_dir} holds a finished model ({run.final_file.name}) but no "
                               f"{path.name}; choose another run_dir=...")
        if cfg.resume and not run_dir.is_dir():
            raise SigmarlError(f"no checkpoint at {path} to resume from")
        if run_dir.is_dir() and any(run_dir.iterdir()):
            print(f"{run_dir}: no resume point yet (stopped before its first checkpoint); "
                  "training from scratch", file=sys.stderr)
        return None
    if not cfg.resume:
        raise SigmarlError(
            f"{run_dir} already holds a training run ({path.name}); pass resume=true "
            "to continue it, or choose another run_dir=..."
        )
    state = ckpt.load(path, device, resume=True)
    changed = config_changes(state["config"], cfg)
    if changed:
        old, new = flatten(state["config"]), flatten(as_dict(cfg))
        diffs = ", ".join(f"{k}: {old.get(k, '(default)')} -> {new.get(k)}" for k in changed[:5])
        raise SigmarlError(f"cannot resume {path} with a different config ({diffs})")
    _compare_resolved(state.get("resolved"), resolved_settings(cfg), path)
    return state


def resolved_settings(cfg: Config) -> dict[str, Any]:
    """What this machine makes of the settings that depend on it: the precision `auto` resolves
    to, the device and the threads. Recorded in every checkpoint and the MLflow run."""
    return {"precision": resolve_precision(cfg), "device": str(cfg.device), "threads": int(cfg.threads)}


def _compare_resolved(saved: dict[str, Any] | None, now: dict[str, Any], path: Path) -> None:
    """A resume must compute as the run did: the same resolved precision (a run resumed with
    `auto` on a CPU without native bf16 would silently switch to fp32). Device and threads may
    change (the weights are the same), and are only noted. Checkpoints from before this record
    trained in the precision their config names (`auto` did not exist without it)."""
    if saved is None:
        return
    if saved.get("precision") != now["precision"]:
        raise SigmarlError(
            f"cannot resume {path}: it trained in {saved.get('precision')} and this machine resolves "
            f"ppo.precision to {now['precision']} (bf16 needs a CPU with avx512_bf16 or amx_bf16, or a "
            "GPU with bf16); resume where it ran, or with ppo.precision set to what it ran in")
    moved = [f"{k} {saved.get(k)} -> {now[k]}" for k in ("device", "threads") if saved.get(k) != now[k]]
    if moved:
        print(f"{path}: resuming with {', '.join(moved)} (same weights; the numbers may differ in the "
              "last bits)", file=sys.stderr)




def train(cfg: Config, tracker: Tracker | None = None) -> TrainResult:
    """Train (or resume, or complete) the run of `cfg` in its run folder, which this process
    holds for the whole time (a second process is refused in one line). Recorded to `tracker`
    (default: the one `cfg` chooses)."""
    return train_block([cfg], [tracker] if tracker else None)[0]


def train_block(cfgs: Sequence[Config], trackers: Sequence[Tracker] | None = None) -> list[TrainResult]:
    """Train the seeds of `cfgs` (one training config, one config per seed) together: one
    process, one batched computation (one seed: a block of one). Every seed's folder is held
    for the whole time."""
    cfgs = [check(c) for c in cfgs]  # a no-op for a composed config; one built in code is checked too
    _check_block(cfgs)
    # agents the training map cannot hold are refused before a run folder exists
    check_room(load_map(cfgs[0].map), cfgs[0].env.n_agents)
    check_fits(cfgs)  # and tensors beyond this machine's memory
    for c in cfgs:  # a folder that is not a run's is refused before its lock or a file is made
        check_ours(Path(c.run_dir))
    for c in cfgs:
        ensure_writable(Path(c.run_dir).parent, "choose another run_dir=...")
    with contextlib.ExitStack() as held:
        for c in cfgs:
            held.enter_context(Run(c.run_dir).lock())
        return _train(cfgs, trackers)


def _check_block(cfgs: Sequence[Config]) -> None:
    """One training config, distinct seeds, distinct folders, refused before anything is built."""
    first = cfgs[0]
    seeds = [c.seed for c in cfgs]
    if len(set(seeds)) != len(seeds):
        raise SigmarlError(f"a seed block needs distinct seeds, got {seeds}")
    for c in cfgs[1:]:
        if c.fingerprint != first.fingerprint or c.model != first.model:
            raise SigmarlError(f"a seed block trains one config; seed {c.seed} differs from seed {first.seed} "
                               f"({differences(first, c) or 'label ' + c.model})")


def _train(cfgs: list[Config], trackers: Sequence[Tracker] | None) -> list[TrainResult]:
    first = cfgs[0]
    resolved = resolved_settings(first)
    torch.set_num_threads(first.threads)
    device = _device(first.device)
    folders = [Run(c.run_dir) for c in cfgs]
    check_membership(folders, [c.seed for c in cfgs])
    settle_checkpoints(folders)
    states = [_resume_point(c, f, device) for c, f in zip(cfgs, folders, strict=True)]
    for c in cfgs:
        ensure_writable(Path(c.run_dir), "choose another run_dir=...")
    runs = [SeedRun(c, s, resolved) for c, s in zip(cfgs, states, strict=True)]
    trackers = list(trackers) if trackers else [open_tracker(c) for c in cfgs]
    if all(s and s["iteration"] >= first.ppo.iterations for s in states):
        return [_result(r, r.state["iteration"], True, r.complete_finished(t)) for r, t in zip(runs, trackers,
                                                                                                strict=True)]
    if len({r.start for r in runs}) > 1:
        raise SigmarlError("the block's seeds stand at different iterations ("
                           + ", ".join(f"seed {r.cfg.seed}: {r.start}" for r in runs)
                           + "); they were not trained as this block: train them alone, or as the block they were")
    several = len(cfgs) > 1  # a block of one leaves what it always left: no block tag, no block.json
    tags = {"block": block_name(first.model, [c.seed for c in cfgs])} if several else {}
    record = provenance.collect(first.threads, str(device))  # what this start runs on
    for r, t in zip(runs, trackers, strict=True):  # the stores are checked before any work
        r.provenance = record
        r.open_record(t, {**tags, **provenance.as_tags(record)})
    try:
        learner = Learner(first, [c.seed for c in cfgs], device)
        for k, r in enumerate(runs):
            r.dims = learner.dims
            if r.state:
                _load_state(learner, k, r.state, r.run.resume_file)
    except BaseException as e:
        finish_records(runs, e)
    if several:
        write_membership(folders, first.model, [c.seed for c in cfgs])
    return _iterate(cfgs, runs, learner)


def _iterate(cfgs: list[Config], runs: list[SeedRun], learner) -> list[TrainResult]:
    """The iterations from the seeds' common resume point to the end (or ppo.stop_after)."""
    ppo = cfgs[0].ppo
    start = runs[0].start
    stop = min(ppo.stop_after, ppo.iterations) if ppo.stop_after > 0 else ppo.iterations
    label = f"{cfgs[0].model} seed {cfgs[0].seed}" if len(cfgs) == 1 else \
        block_name(cfgs[0].model, [c.seed for c in cfgs])
    bar = Progress(ppo.iterations, label, "train", initial=start)
    folders = [_hold(r.run.dir) for r in runs]
    try:
        for r in runs:
            r.begin()
        if start == 0:
            crash.point("train:start")
            # a resume point before the first iteration: a kill at any later instant resumes
            _checkpoint(runs, learner, 0, [None] * len(runs))
        for it in range(start, stop):
            if moved := _moved(runs, folders):  # gone, or made anew by a checkpoint's write since
                raise SigmarlError(_deleted(moved[0]))
            rewards = _one_iteration(runs, learner, ppo, it, stop)
            bar.update(1, reward=" ".join(f"{x:.3f}" for x in rewards), fps=f"{runs[0].history[-1]['frames_per_s']:.0f}")
        if stop == ppo.iterations:
            for r in runs:
                r.complete_record(stop)
    except BaseException as e:  # Ctrl-C, or SIGTERM through the CLI's handler, or a failure
        finish_records(runs, _explained(e, _moved(runs, folders)))
    finally:
        bar.close()
        learner.close()
        for fd in folders:
            if fd is not None:
                os.close(fd)
    finished = stop == ppo.iterations
    if not finished:
        for r in runs:
            r.record.finish("KILLED")  # ppo.stop_after: stopped on purpose, resumable
    return [_result(r, stop, finished, r.run_id) for r in runs]


def _explained(error: BaseException, moved: list[Path]) -> BaseException:
    """A file error because a run folder vanished under the training, as the one line it is."""
    if isinstance(error, OSError | SigmarlError) and moved:  # the checkpoint writer says "cannot write"
        return SigmarlError(_deleted(moved[0]))
    return error


def _hold(folder: Path) -> int | None:
    """The run folder held open while it trains: deleted, it keeps its inode (so a folder made
    anew at its path has another) and counts no links."""
    try:
        return os.open(folder, os.O_RDONLY)
    except OSError:  # a system that opens no folders: not checked
        return None


def _moved(runs: list[SeedRun], folders: list[int | None]) -> list[Path]:
    """The run folders that are no longer the ones the training began in."""
    moved = []
    for r, fd in zip(runs, folders, strict=True):
        held = os.fstat(fd) if fd is not None else None
        if held is not None and (held.st_nlink == 0 or _identity(r.run.dir) != (held.st_dev, held.st_ino)):
            moved.append(r.run.dir)
    return moved


def _deleted(folder: Path) -> str:
    return f"{folder}: the run folder was deleted during training (its record ends FAILED); train again to start over"


def _identity(folder: Path) -> tuple[int, int] | None:
    """Which folder `folder` names (None: none): a checkpoint's write makes a deleted one anew."""
    try:
        st = folder.stat()
    except OSError:
        return None
    return st.st_dev, st.st_ino


def _one_iteration(runs: list[SeedRun], learner, ppo: PPOConfig, it: int, stop: int) -> list[float]:
    learner.reseed(it)
    learner.set_lr(learning_rate(ppo, it))
    per_seed, times = learner.iterate()
    done = it + 1
    rewards = []
    for k, (r, metrics) in enumerate(zip(runs, per_seed, strict=True)):
        metrics = {**metrics, "lr": learning_rate(ppo, it),
                   "frames_per_s": len(runs) * ppo.frames_per_iteration / times["total"],
                   "time_collect_s": times["collect"], "time_advantage_s": times["advantage"],
                   "time_optimise_s": times["optimise"]}
        rewards.append(r.record_iteration(done, metrics, lambda k=k: learner.state(k)))
    if done % ppo.checkpoint_every == 0 or done == stop:
        _checkpoint(runs, learner, done, rewards)
        crash.point(f"train:checkpoint:{done}")
        for r in runs:
            r.send_metrics()
    if done == ppo.iterations:
        for k, r in enumerate(runs):
            r.save_final(r.snapshot(done, rewards[k], learner.state(k)))
    return rewards


def _checkpoint(runs: list[SeedRun], learner, iteration: int, rewards: list[float | None]) -> None:
    states = [r.snapshot(iteration, rewards[k], learner.state(k)) for k, r in enumerate(runs)]
    commit_checkpoints([r.run for r in runs], states)


def _result(r: SeedRun, iterations: int, finished: bool, run_id: str | None) -> TrainResult:
    return TrainResult(r.dir, iterations, finished, r.best, run_id, r.history)


def _load_state(learner, k: int, state: dict[str, Any], path: Path) -> None:
    """Weights, optimiser and generators of a resume point, checked against the networks."""
    actor, critic = learner.networks(k)
    ckpt.check_weights(state["policy"], actor, "policy", path)
    ckpt.check_weights(state["critic"], critic, "critic", path)
    try:
        learner.load(k, state)
    except SigmarlError as e:
        raise SigmarlError(f"checkpoint {path}: {e}") from e
    except (ValueError, KeyError, RuntimeError) as e:
        raise SigmarlError(f"checkpoint {path}: the optimiser state does not fit ({e})") from e


def load_policy(
    path: str | Path, n_agents: int | None = None, device: str | torch.device = "cpu"
) -> tuple[torch.nn.Module, dict[str, Any]]:
    """The trained actor of a checkpoint (best.pt, final.pt, checkpoint.pt) and the checkpoint.

    `n_agents` may differ from training: the policy's parameters are shared by all agents.
    """
    state = ckpt.load(Path(path), device)
    dims = state["dims"]
    net = ckpt.config_of(state, Path(path)).network
    try:
        actor = make_actor(net, dims["obs_dim"], n_agents or dims["n_agents"], dims["action_low"],
                           dims["action_high"], device)
    except Exception as e:  # a config that builds no network
        raise SigmarlError(f"checkpoint {path}: its config builds no policy ({type(e).__name__}: "
                           f"{str(e).splitlines()[0] if str(e) else ''})") from e
    ckpt.check_weights(state["policy"], actor, "policy", Path(path))
    actor.load_state_dict(state["policy"])
    return actor, state
