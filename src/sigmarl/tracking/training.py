"""Training runs in MLflow: one run per training, params, tags, metrics, artifacts.

The store is checked (read and write) before training starts, so a wrong or unreachable
`tracking.tracking_uri` ends in one message instead of a failure hours later. Once training
runs, a store that stops answering costs a warning, not the training: the run folder
(checkpoints, metrics.csv) is the primary record, and `sync_metrics` / `log_missing_artifacts`
bring the MLflow run up to date from it on the next resume or re-run.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from sigmarl.ablation import obs_strategies
from sigmarl.config import Config, as_dict
from sigmarl.config.map import map_keys
from sigmarl.errors import SigmarlError, raise_if_interrupted
from sigmarl.identity import TRAINING_GROUPS
from sigmarl.run import REWARD_COLUMN
from sigmarl.tracking.meta import flatten, git_commit
from sigmarl.tracking.store import experiment_id
from sigmarl.tracking.study_run import describe, parent_of
from sigmarl.tracking.tracker import TrainingRun

# the metric whose history tells which iterations a training run already holds
STEP_MARKER = REWARD_COLUMN


def _has_run(client: Any, run_id: str) -> bool:
    # lazy: MLflow (~1 s) only where a store is used (start-up)
    from mlflow.exceptions import MlflowException

    try:
        client.get_run(run_id)
    except MlflowException as e:
        if e.error_code == "RESOURCE_DOES_NOT_EXIST":
            return False
        raise
    return True




RUN_PARAMS = ("seed", "model", "fingerprint", "device", "threads", "run_dir")


def training_params(cfg: Config) -> dict[str, str]:
    """A training run's MLflow params: the composed training config (every key of the groups
    the fingerprint covers, the map's only where its kind is built from them) and what names
    the run. Where it is tracked, evaluated or swept, and the study's other variants, are not
    this run's settings (the study, overrides and resolved precision are its tags)."""
    values = as_dict(cfg)
    groups = {g: values[g] for g in TRAINING_GROUPS}
    groups["map"] = {k: v for k, v in groups["map"].items() if k in ("name", "kind", *map_keys(cfg.map.kind))}
    return {**flatten(groups), **{k: str(values[k]) for k in RUN_PARAMS}}


class MlflowTrainingRun(TrainingRun):
    """A training run in MLflow; a store that fails while training runs only warns."""

    def __init__(self, client: Any, run_id: str) -> None:
        self.client = client
        self.run_id = run_id
        self._warned = False

    @classmethod
    def open(cls, cfg: Config, client: Any, run_id: str | None = None, reopen: bool = True) -> MlflowTrainingRun:
        """Create the run, or attach to `run_id` (and mark it RUNNING again with `reopen`, for a
        resume)."""
        try:
            if run_id is not None and not _has_run(client, run_id):
                # The run folder came from another machine or store (a committed study, a
                # cluster job's folder): it is the primary record, so this store gets a new run
                # for it, which the caller fills from metrics.csv.
                print(f"sigmarl: MLflow run {run_id} is not in the store {client.tracking_uri!r}; "
                      "recording the run folder as a new run there", file=sys.stderr)
                run_id = None
            if run_id is not None:
                if client.get_run(run_id).info.lifecycle_stage != "active":
                    raise SigmarlError(f"MLflow run {run_id} was deleted; cannot resume into it")
                if reopen:
                    client.update_run(run_id, status="RUNNING")
                return cls(client, run_id)
            exp_id = experiment_id(client, cfg.tracking.experiment, create=True)
            tags = {
                "kind": "training",  # evaluation and report runs share the experiment
                "model": cfg.model,  # the run's label (the study's variant)
                "obs": obs_strategies(cfg.obs),
                "study": cfg.study.name,
                "fingerprint": cfg.fingerprint,
                "overrides": " ".join(cfg.overrides)[:5000],
                "seed": str(cfg.seed),
            }
            if commit := git_commit():
                tags["git_commit"] = commit
                tags["mlflow.source.git.commit"] = commit
            describe(client, exp_id, None)  # an experiment made before its kind was set
            tags.update(parent_of(client, exp_id, cfg.study.name))  # under the sweep's study run
            run_name = f"{tags['model']}-seed{cfg.seed}"
            run = client.create_run(exp_id, run_name=run_name, tags=tags)
        except SigmarlError:
            raise
        except Exception as e:  # the store answered the check but refuses the run
            first = (str(e).strip().splitlines() or [type(e).__name__])[0]
            raise SigmarlError(
                f"MLflow tracking store {client.tracking_uri!r} is not writable: {first[:300]} "
                "(set tracking.tracking_uri=..., or tracking.enabled=false to train without it)"
            ) from e
        tracker = cls(client, run.info.run_id)
        tracker.log_params(training_params(cfg))
        return tracker

    def _guard(self, method: str, *args: Any, **kwargs: Any) -> Any:
        """Call client.<method>(run_id, ...); a failing store only warns."""
        try:
            return getattr(self.client, method)(self.run_id, *args, **kwargs)
        except Exception as e:  # keep training; the run folder is the primary record
            raise_if_interrupted(e)  # a SIGTERM inside MLflow's store code, wrapped by it
            if not self._warned:
                print(f"sigmarl: warning: MLflow {method} failed ({e}); training goes on "
                      "(a re-run brings the MLflow run up to date)", file=sys.stderr)
                self._warned = True
            return None

    def set_tags(self, tags: Mapping[str, str]) -> None:
        for key, value in tags.items():
            self._guard("set_tag", key, value)

    def log_params(self, params: Mapping[str, str]) -> None:
        # lazy: MLflow (~1 s) only where a store is used (start-up)
        from mlflow.entities import Param

        items = [Param(k, v[:6000]) for k, v in params.items()]
        for i in range(0, len(items), 100):  # MLflow takes at most 100 params per batch
            self._guard("log_batch", params=items[i : i + 100])

    def log_metrics(self, rows: Sequence[tuple[int, Mapping[str, float]]]) -> None:
        """Metrics of several iterations: [(step, {name: value}), ...]; whole iterations per
        batch, so a batch that fails leaves no iteration half logged."""
        if not rows:
            return
        # lazy: MLflow (~1 s) only where a store is used (start-up)
        from mlflow.entities import Metric

        now = int(time.time() * 1000)
        batch: list[Metric] = []
        for step, row in rows:
            items = [Metric(k, float(v), now, step) for k, v in row.items()]
            if batch and len(batch) + len(items) > 1000:  # MLflow's batch limit
                self._guard("log_batch", metrics=batch)
                batch = []
            batch.extend(items)
        self._guard("log_batch", metrics=batch)

    def logged_steps(self) -> set[int]:
        """The iterations whose metrics the run holds."""
        history = self._guard("get_metric_history", STEP_MARKER)
        return {m.step for m in history or []}

    def sync_metrics(self, rows: Sequence[tuple[int, Mapping[str, float]]]) -> None:
        """Log the iterations of `rows` that the run lacks (e.g. after a kill between a
        checkpoint and its metrics reaching MLflow); never one twice."""
        if not rows:
            return
        have = self.logged_steps()
        self.log_metrics([(step, row) for step, row in rows if step not in have])

    def log_artifact(self, path: Path) -> None:
        self._guard("log_artifact", str(path))

    def log_missing_artifacts(self, paths: Sequence[Path]) -> None:
        """Log those of `paths` that the run does not hold yet."""
        have = {a.path for a in self._guard("list_artifacts") or []}
        for path in paths:
            if path.name not in have:
                self.log_artifact(path)

    def status(self) -> str | None:
        run = self._guard("get_run")
        return None if run is None else run.info.status

    def finish(self, status: str = "FINISHED") -> None:
        self._guard("set_terminated", status)

    def discard(self) -> None:
        """End and delete the run, unless it finished: for a start from scratch over a run
        that was killed before it left anything. Quiet if the run is gone."""
        try:
            if self.client.get_run(self.run_id).info.status != "FINISHED":
                self.client.set_terminated(self.run_id, "KILLED")
                self.client.delete_run(self.run_id)
        except Exception:
            pass
