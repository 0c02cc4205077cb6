"""`train(cfg)`: the MAPPO training loop, checkpointed, resumable, tracked in MLflow.

Exact resume: every iteration starts from a state that depends only on (seed, iteration):
the global generators and the environment are reseeded and every environment is reset. A
checkpoint after iteration k (weights, optimiser, best reward, RNG states) is therefore all
that iteration k+1 needs, and a resumed run ends with the same weights as an uninterrupted one.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NoReturn

import numpy as np
import torch

from sigmarl import crash
from sigmarl.config import Config, PPOConfig, as_dict, to_yaml
from sigmarl.errors import SigmarlError, Terminated, was_interrupted
from sigmarl.paths import ensure_writable
from sigmarl.progress import Progress
from sigmarl.run import CONFIG_FILE, REWARD_COLUMN, RUN_ID_FILE, Run, write_atomic
from sigmarl.tracking import Tracker, TrainingRun, flatten, open_tracker
from sigmarl.training import checkpoint as ckpt
from sigmarl.training import metrics_file
from sigmarl.training.mappo import (
    collect,
    make_collector,
    make_gae,
    rollout_stats,
    update,
)
from sigmarl.training.metrics_file import METRICS_FILE
from sigmarl.training.networks import ACTION, OBS, make_actor, make_critic, make_sampler
from sigmarl.training.ppo_loss import make_loss, resolve_precision
from sigmarl.validate import check

# what a resume must share with the interrupted run (anything else, e.g. threads, device,
# evaluation settings, may change); ppo.stop_after is the interruption itself
RESUME_MUST_MATCH = ("map.", "obs.", "env.", "network.", "ppo.", "seed", "rules.")


@dataclass
class TrainResult:
    run_dir: Path
    iterations: int  # completed so far
    finished: bool
    best_reward: float | None
    run_id: str | None
    history: list[dict[str, float]] = field(default_factory=list)  # this invocation's iterations


def iteration_seed(seed: int, iteration: int) -> int:
    """A well-mixed 31-bit seed per (run seed, iteration)."""
    return int(np.random.SeedSequence([seed, iteration]).generate_state(1)[0] >> 1)


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
    changed = []
    for key in sorted(new):
        if not key.startswith(RESUME_MUST_MATCH) or key == "ppo.stop_after":
            continue
        if new[key] != old.get(key, default.get(key)):
            changed.append(key)
    return changed


def _resume_point(cfg: Config, run_dir: Path, device: torch.device) -> dict[str, Any] | None:
    """The checkpoint to resume from, or None to start from scratch.

    A folder without `checkpoint.pt` holds no training to continue (a run killed before its
    first checkpoint leaves at most config.yaml and mlflow_run_id), so it starts from scratch
    without asking; one with `checkpoint.pt` is resumed with resume=true and never overwritten.
    """
    path = run_dir / ckpt.RESUME_FILE
    if not path.exists():
        if (run_dir / ckpt.FINAL_FILE).exists():
            raise SigmarlError(f"{run_dir} holds a finished model ({ckpt.FINAL_FILE}) but no "
                               f"{ckpt.RESUME_FILE}; choose another run_dir=...")
        if cfg.resume and not run_dir.is_dir():
            raise SigmarlError(f"no checkpoint at {path} to resume from")
        if run_dir.is_dir() and any(run_dir.iterdir()):
            print(f"{run_dir}: no resume point yet (stopped before its first checkpoint); "
                  "training from scratch", file=sys.stderr)
        return None
    if not cfg.resume:
        raise SigmarlError(
            f"{run_dir} already holds a training run ({ckpt.RESUME_FILE}); pass resume=true "
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


def _env_dims(env: Any) -> dict[str, Any]:
    obs_shape = env.full_observation_spec[OBS].shape
    box = env.full_action_spec[ACTION].space
    n_act = box.low.shape[-1]
    return {
        "obs_dim": int(obs_shape[-1]),
        "n_agents": int(obs_shape[-2]),
        "action_low": box.low.reshape(-1, n_act)[0].cpu(),
        "action_high": box.high.reshape(-1, n_act)[0].cpu(),
    }


@dataclass
class Parts:
    """Everything one training run is made of (also used by the benchmark)."""

    env: Any
    actor: Any
    critic: Any
    loss: Any
    gae: Any
    optimiser: torch.optim.Optimizer
    dims: dict[str, Any]
    collector: Any

    def close(self) -> None:
        self.collector.shutdown()
        if not self.env.is_closed:
            self.env.close()


def build(cfg: Config, device: torch.device) -> Parts:
    """Training environment, networks (initialised from cfg.seed), loss, GAE and optimiser."""
    from sigmarl.env import make_env

    env = make_env(cfg, num_envs=cfg.ppo.num_envs, mode="train", seed=cfg.seed, device=str(device))
    dims = _env_dims(env)
    torch.manual_seed(cfg.seed)  # network initialisation
    actor = make_actor(cfg.network, dims["obs_dim"], dims["n_agents"], dims["action_low"],
                       dims["action_high"], device)
    critic = make_critic(cfg.network, dims["obs_dim"], dims["n_agents"], device)
    optimiser = torch.optim.Adam([*actor.parameters(), *critic.parameters()], lr=cfg.ppo.lr)
    collector = make_collector(env, make_sampler(actor), cfg.ppo.frames_per_iteration, device)
    return Parts(env, actor, critic, make_loss(actor, critic, cfg.ppo, resolve_precision(cfg)), make_gae(critic, cfg.ppo),
                 optimiser, dims, collector)


def train(cfg: Config, tracker: Tracker | None = None) -> TrainResult:
    """Train (or resume, or complete) the run of `cfg` in its run folder, which this process
    holds for the whole time (a second process is refused in one line). Recorded to `tracker`
    (default: the one `cfg` chooses)."""
    check(cfg)  # a no-op for a composed config; a Config built in code is checked too
    run_dir = Path(cfg.run_dir)
    ensure_writable(run_dir.parent, "choose another run_dir=...")
    with Run(run_dir).lock():
        return _train(cfg, run_dir, tracker)


def _train(cfg: Config, run_dir: Path, tracker: Tracker | None) -> TrainResult:
    resolved = resolved_settings(cfg)
    torch.set_num_threads(cfg.threads)
    device = _device(cfg.device)
    state = _resume_point(cfg, run_dir, device)
    ensure_writable(run_dir, "choose another run_dir=...")
    if state and state["iteration"] >= cfg.ppo.iterations:
        return _complete(cfg, run_dir, state, tracker)

    start = state["iteration"] if state else 0
    best = state.get("best_reward") if state else None
    record = _open_record(tracker or open_tracker(cfg), run_dir, state)  # the store is checked before any work
    record.set_tags({f"resolved.{k}": str(v) for k, v in resolved.items()})  # what actually ran
    run_id = record.run_id
    try:
        parts = build(cfg, device)
        if state:
            _load_state(parts, state, run_dir / ckpt.RESUME_FILE)
    except BaseException as e:
        _finish_and_raise(record, e)
    actor, critic, optimiser = parts.actor, parts.critic, parts.optimiser

    def snapshot(iteration: int, reward: float | None) -> dict[str, Any]:
        return {
            "format": ckpt.FORMAT,
            "kind": "resume",
            "iteration": iteration,
            "policy": actor.state_dict(),
            "critic": critic.state_dict(),
            "optimizer": optimiser.state_dict(),
            "rng": ckpt.rng_state(),
            "best_reward": best,
            "mean_episode_reward": reward,
            "mlflow_run_id": run_id,
            "config": as_dict(cfg),
            "dims": parts.dims,
            "resolved": resolved,
        }

    ppo = cfg.ppo
    stop = min(ppo.stop_after, ppo.iterations) if ppo.stop_after > 0 else ppo.iterations
    pending: list[tuple[int, dict[str, float]]] = []  # metrics not yet sent (see below)
    history: list[dict[str, float]] = []
    metrics_path = run_dir / METRICS_FILE
    bar = Progress(ppo.iterations, f"{cfg.model} seed {cfg.seed}", "train", initial=start)
    try:
        if state:
            # the rows after the resume point are computed again; MLflow gets what it missed
            record.sync_metrics(metrics_file.truncate(metrics_path, start))
        else:
            write_atomic(run_dir / CONFIG_FILE, to_yaml(cfg))
            metrics_path.unlink(missing_ok=True)
            record.log_artifact(run_dir / CONFIG_FILE)
            crash.point("train:start")
            # a resume point before the first iteration: a kill at any later instant resumes
            ckpt.save_atomic(snapshot(0, None), run_dir / ckpt.RESUME_FILE)
        batches = iter(parts.collector)
        for it in range(start, stop):
            t0 = time.perf_counter()
            s = iteration_seed(cfg.seed, it)
            torch.manual_seed(s)
            parts.env.set_seed(s)
            for group in optimiser.param_groups:
                group["lr"] = learning_rate(ppo, it)
            data = collect(batches)
            t1 = time.perf_counter()
            with torch.no_grad():
                parts.gae(data)
            t2 = time.perf_counter()
            losses = update(data, parts.loss, optimiser, ppo)
            t3 = time.perf_counter()
            metrics = {
                **rollout_stats(data),
                **losses,
                "lr": optimiser.param_groups[0]["lr"],
                "frames_per_s": ppo.frames_per_iteration / (t3 - t0),
                "time_collect_s": t1 - t0,
                "time_advantage_s": t2 - t1,
                "time_optimise_s": t3 - t2,
            }
            done_its = it + 1
            history.append(metrics)
            pending.append((done_its, metrics))
            metrics_file.append(metrics_path, done_its, metrics)
            crash.point(f"train:iteration:{done_its}")
            reward = metrics[REWARD_COLUMN]
            if best is None or round(reward, 2) > best:  # the paper: best reward to 2 decimals
                best = round(reward, 2)
                ckpt.save_atomic(ckpt.policy_only(snapshot(done_its, reward)), run_dir / ckpt.BEST_FILE)
            if done_its % ppo.checkpoint_every == 0 or done_its == stop:
                ckpt.save_atomic(snapshot(done_its, reward), run_dir / ckpt.RESUME_FILE)
                crash.point(f"train:checkpoint:{done_its}")
                # metrics go out after their checkpoint; a kill in between is made good
                # from metrics.csv on the next resume, so no iteration is lost or doubled
                record.log_metrics(pending)
                pending = []
            if done_its == ppo.iterations:
                ckpt.save_atomic(ckpt.policy_only(snapshot(done_its, reward)), run_dir / ckpt.FINAL_FILE)
                crash.point("train:final")
            bar.update(1, reward=f"{reward:.3f}", fps=f"{metrics['frames_per_s']:.0f}")
        if stop == ppo.iterations:
            _complete_record(record, run_dir, stop)
    except BaseException as e:  # Ctrl-C, or SIGTERM through the CLI's handler, or a failure
        _finish_and_raise(record, e)
    finally:
        bar.close()
        parts.close()
    finished = stop == ppo.iterations
    if not finished:
        record.finish("KILLED")  # ppo.stop_after: stopped on purpose, resumable
    return TrainResult(run_dir, stop, finished, best, run_id, history)


def _load_state(parts: Parts, state: dict[str, Any], path: Path) -> None:
    """Weights, optimiser and generators of a resume point, checked against the networks."""
    ckpt.check_weights(state["policy"], parts.actor, "policy", path)
    ckpt.check_weights(state["critic"], parts.critic, "critic", path)
    parts.actor.load_state_dict(state["policy"])
    parts.critic.load_state_dict(state["critic"])
    try:
        parts.optimiser.load_state_dict(state["optimizer"])
    except (ValueError, KeyError, RuntimeError) as e:
        raise SigmarlError(f"checkpoint {path}: the optimiser state does not fit ({e})") from e
    ckpt.set_rng_state(state["rng"])


def _finish_and_raise(record: TrainingRun, error: BaseException) -> NoReturn:
    """End the run KILLED (interrupted: resumable) or FAILED, and re-raise; an interruption
    that a library turned into its own error is raised as the interruption it was."""
    if not was_interrupted(error):
        record.finish("FAILED")
        raise error
    record.finish("KILLED")
    if isinstance(error, KeyboardInterrupt):
        raise error
    raise Terminated() from error


def _open_record(tracker: Tracker, run_dir: Path, state: dict[str, Any] | None) -> TrainingRun:
    """Reopen the resumed run's record, or create one; a record left by a start that was killed
    before its first checkpoint is deleted (it holds nothing the new one will not)."""
    old = (state or {}).get("mlflow_run_id")
    record = tracker.training_run(old)
    id_file = run_dir / RUN_ID_FILE
    if not state and id_file.exists():
        tracker.discard_training_run(id_file.read_text().strip())
    if record.run_id != old:
        write_atomic(id_file, f"{record.run_id}\n")
    return record


def _complete_record(record: TrainingRun, run_dir: Path, iterations: int) -> None:
    """Bring the finished run's tracked record up to date (metrics, checkpoints, config)."""
    record.sync_metrics(metrics_file.read(run_dir / METRICS_FILE, iterations))
    record.log_missing_artifacts([run_dir / CONFIG_FILE, run_dir / ckpt.BEST_FILE,
                                  run_dir / ckpt.FINAL_FILE])
    record.finish("FINISHED")


def _complete(cfg: Config, run_dir: Path, state: dict[str, Any], tracker: Tracker | None) -> TrainResult:
    """A re-run of a finished training: finish what a kill after the last iteration left
    undone (final.pt, the MLflow record), then report it finished."""
    iterations = state["iteration"]
    if not (run_dir / ckpt.FINAL_FILE).exists():  # the last checkpoint holds the final weights
        ckpt.save_atomic(ckpt.policy_only(state), run_dir / ckpt.FINAL_FILE)
    run_id = state.get("mlflow_run_id")
    record = (tracker or open_tracker(cfg)).training_run(run_id, reopen=False)
    if record.run_id != run_id:  # a store that had no record of it (see MlflowTrainingRun.open)
        run_id = record.run_id
        write_atomic(run_dir / RUN_ID_FILE, f"{run_id}\n")
    if record.status() not in (None, "FINISHED"):
        print(f"{run_dir}: completing the tracker's record of the finished training")
        _complete_record(record, run_dir, iterations)
    print(f"{run_dir}: training already finished ({iterations} iterations)")
    return TrainResult(run_dir, iterations, True, state.get("best_reward"), run_id)


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
