"""What a training writes: each seed's records while it trains (its run folder: config.yaml,
metrics.csv, checkpoints; its tracker record, its best reward, the metrics not yet sent), and the
resume points of a block's seeds committed together.

Order of writes per iteration (what a kill at any instant leaves, and how a resume reads it):
metrics.csv gets the row, best.pt is replaced if the reward improved, and every
`ppo.checkpoint_every` iterations the resume point is written and only then are the metrics
sent to the tracker; a kill in between is made good from metrics.csv on the next resume, so no
iteration is lost or doubled.

A block of several seeds also leaves `block.json` in each seed's folder (the block it trained in,
`sigmarl.run.block_membership`), and commits its resume points in two phases: every seed's new
checkpoint is first written beside its old one (`checkpoint.next.pt`), and only when all are on
disk is each renamed over `checkpoint.pt`. A kill in phase 1 leaves every old checkpoint (the new
ones are dropped on resume); a kill in phase 2 leaves all the new ones written (the renames are
finished on resume). So the seeds always resume from one common iteration. One seed's folder is
the same whatever trained it: one atomic write per resume point, no `block.json`.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from sigmarl import crash
from sigmarl.config import Config, as_dict, to_yaml
from sigmarl.errors import SigmarlError, Terminated, was_interrupted
from sigmarl.readers import read_run_config
from sigmarl.run import REWARD_COLUMN, Run, write_atomic
from sigmarl.tracking import Tracker, TrainingRun, provenance
from sigmarl.training import checkpoint as ckpt
from sigmarl.training import metrics_file


class SeedRun:
    """The run folder and tracked record of one seed of a training."""

    def __init__(self, cfg: Config, state: dict[str, Any] | None, resolved: dict[str, Any]):
        self.cfg, self.state, self.resolved = cfg, state, resolved
        self.run = Run(cfg.run_dir)
        self.dir = self.run.dir
        self.start = state["iteration"] if state else 0
        self.best = state.get("best_reward") if state else None
        self.pending: list[tuple[int, dict[str, float]]] = []
        self.history: list[dict[str, float]] = []
        self.record: TrainingRun | None = None
        self.dims: dict[str, Any] = {}
        self.provenance: dict[str, Any] | None = None  # what this start runs on (tracking.provenance)

    @property
    def run_id(self) -> str | None:
        return self.record.run_id if self.record else None

    def open_record(self, tracker: Tracker, tags: dict[str, str]) -> None:
        """Reopen the resumed run's record, or create one; a record left by a start that was
        killed before its first checkpoint is deleted (it holds nothing the new one will not)."""
        old = (self.state or {}).get("mlflow_run_id")
        self.record = tracker.training_run(old)
        id_file = self.run.run_id_file
        if not self.state and id_file.exists():
            tracker.discard_training_run(id_file.read_text().strip())
        if self.record.run_id != old:
            write_atomic(id_file, f"{self.record.run_id}\n")
        self.record.set_tags({**{f"resolved.{k}": str(v) for k, v in self.resolved.items()}, **tags})

    def snapshot(self, iteration: int, reward: float | None, learned: dict[str, Any]) -> dict[str, Any]:
        """A resume point: `learned` holds the weights, the optimiser and the generators."""
        return {"format": ckpt.FORMAT, "kind": "resume", "iteration": iteration, **learned,
                "best_reward": self.best, "mean_episode_reward": reward, "mlflow_run_id": self.run_id,
                "config": as_dict(self.cfg), "dims": self.dims, "resolved": self.resolved}

    def begin(self) -> None:
        """A resume: drop the rows after the resume point (computed again) and send the tracker
        what it missed. A new run: its config.yaml, and no rows."""
        metrics_path = self.run.metrics_file
        if self.state:
            self._repair_config()
            self.record.sync_metrics(metrics_file.truncate(metrics_path, self.start))
        else:
            write_atomic(self.run.config_file, to_yaml(self.cfg))
            metrics_path.unlink(missing_ok=True)
            self.record.log_artifact(self.run.config_file)
        # after the resume's checks: a start they refuse leaves the folder as it was
        if self.provenance is not None:
            provenance.add(self.run, self.provenance, self.start)

    def _repair_config(self) -> None:
        """A resume whose config.yaml a crash or a hand cut, emptied or garbled: the checkpoint
        holds the same config (the resume checked it), so the record is written again rather
        than left for `report` or `evaluate` to refuse after training."""
        path = self.run.config_file
        try:
            read_run_config(path)
            return
        except SigmarlError as e:
            said = str(e).split(";")[0] if path.exists() else f"{path} is missing"
        write_atomic(path, to_yaml(self.cfg))
        print(f"{said}; written again from the checkpoint's config", file=sys.stderr)

    def record_iteration(self, done: int, metrics: dict[str, float], learned) -> float:
        """An iteration's row, and best.pt if its reward is the best so far (to 2 decimals, the
        paper's rule); `learned()` gives the weights when they are needed. Returns the reward."""
        metrics = metrics_file.append(self.run.metrics_file, done, metrics)
        self.history.append(metrics)
        self.pending.append((done, metrics))
        crash.point(f"train:iteration:{done}")
        reward = metrics[REWARD_COLUMN]
        if self.best is None or round(reward, 2) > self.best:
            self.best = round(reward, 2)
            ckpt.save_atomic(ckpt.policy_only(self.snapshot(done, reward, learned())), self.run.best_file)
        return reward

    def send_metrics(self) -> None:
        self.record.log_metrics(self.pending)
        self.pending = []

    def save_final(self, snapshot: dict[str, Any]) -> None:
        ckpt.save_atomic(ckpt.policy_only(snapshot), self.run.final_file)
        crash.point("train:final")

    def complete_record(self, iterations: int) -> None:
        """Bring the finished run's tracked record up to date (metrics, checkpoints, config)."""
        self.record.sync_metrics(metrics_file.read(self.run.metrics_file, iterations))
        self.record.log_missing_artifacts([self.run.config_file, self.run.best_file,
                                           self.run.final_file])
        self.record.finish("FINISHED")

    def complete_finished(self, tracker: Tracker) -> str | None:
        """A re-run of a finished training: finish what a kill after the last iteration left
        undone (final.pt, the tracked record)."""
        state, iterations = self.state, self.state["iteration"]
        if not self.run.final_file.exists():  # the last checkpoint holds the final weights
            ckpt.save_atomic(ckpt.policy_only(state), self.run.final_file)
        # the folder's record of its run first: a store that lacked the checkpoint's run got a
        # new one, whose id only the folder keeps (the checkpoint is not rewritten for it)
        run_id = _recorded_run_id(self.run) or state.get("mlflow_run_id")
        self.record = tracker.training_run(run_id, reopen=False)
        if self.record.run_id != run_id:  # a store that had no record of it
            write_atomic(self.run.run_id_file, f"{self.record.run_id}\n")
        if self.record.status() not in (None, "FINISHED"):
            print(f"{self.dir}: completing the tracker's record of the finished training")
            self.complete_record(iterations)
        print(f"{self.dir}: training already finished ({iterations} iterations)")
        return self.record.run_id


def _recorded_run_id(run: Run) -> str | None:
    """The run id in the folder's `mlflow_run_id`, None where it has none readable."""
    try:
        text = run.run_id_file.read_text(encoding="utf-8").strip()
    except (OSError, UnicodeDecodeError):
        return None
    return text if text and "\n" not in text else None


def finish_records(runs: list[SeedRun], error: BaseException) -> None:
    """End every seed's record KILLED (interrupted: resumable) or FAILED, and re-raise; an
    interruption that a library turned into its own error is raised as the interruption it was."""
    interrupted = was_interrupted(error)
    for r in runs:
        if r.record is not None:
            r.record.finish("KILLED" if interrupted else "FAILED")
    if not interrupted or isinstance(error, KeyboardInterrupt):
        raise error
    raise Terminated() from error


def commit_checkpoints(runs: Sequence[Run], states: Sequence[dict[str, Any]]) -> None:
    """Replace every seed's resume point, all or none (see the module's docstring)."""
    if len(runs) == 1:
        ckpt.save_atomic(states[0], runs[0].resume_file)
        return
    for run, state in zip(runs, states, strict=True):
        ckpt.save_atomic(state, run.next_resume_file)
    crash.point(f"train:block-written:{states[0]['iteration']}")
    for i, run in enumerate(runs):
        os.replace(run.next_resume_file, run.resume_file)
        if i == 0:
            crash.point(f"train:block-renaming:{states[0]['iteration']}")


def settle_checkpoints(runs: Sequence[Run]) -> None:
    """Finish or drop a commit a kill interrupted, before the block resumes."""
    nexts = [run for run in runs if run.next_resume_file.exists()]
    if not nexts:
        return
    target = _iteration(nexts[0].next_resume_file)
    renamed = [run for run in runs if run not in nexts and run.resume_file.exists()
               and _iteration(run.resume_file) == target]
    if len(nexts) + len(renamed) == len(runs):  # phase 1 was complete: finish phase 2
        for run in nexts:
            os.replace(run.next_resume_file, run.resume_file)
    else:  # phase 1 was cut short: the old resume points stand
        for run in nexts:
            run.next_resume_file.unlink()


def _iteration(path: Path) -> int | None:
    try:
        return ckpt.load(path, resume=True)["iteration"]
    except SigmarlError:
        return None
