"""Which tracker a command records to (`open_tracker`, the one reader of `tracking.enabled`),
and a user's tracker (`tracking.backend=package.module:Class`) held to the promise MLflow's
keeps: it fails in one line when the command starts (import, constructor, creating the run),
and once the work runs, a failing call costs one warning, not the training or evaluation.
The run folder is the primary record; a re-run brings the tracker up to date from it."""

from __future__ import annotations

import sys
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from sigmarl.errors import SigmarlError, first_line, raise_if_interrupted
from sigmarl.tracking.tracker import (
    BACKENDS,
    NullTracker,
    Rows,
    Tracker,
    TrainingRun,
    tracker_class,
)

if TYPE_CHECKING:
    from sigmarl.config import Config


def at_start(backend: str, what: str, call: Callable[[], Any]) -> Any:
    """`call()`, or one SigmarlError line naming the backend: nothing has run yet."""
    try:
        return call()
    except SigmarlError:
        raise
    except Exception as e:
        raise_if_interrupted(e)
        raise SigmarlError(f"tracking.backend {backend!r}: {what} failed ({first_line(e)}); fix the tracker, "
                           "or set tracking.enabled=false to run without it") from e


class _Warner:
    def __init__(self, backend: str) -> None:
        self.backend = backend
        self.warned = False

    def call(self, method: str, fn: Callable[..., Any], *args: Any, default: Any = None) -> Any:
        try:
            return fn(*args)
        except Exception as e:
            raise_if_interrupted(e)
            if not self.warned:
                print(f"sigmarl: warning: tracker {self.backend!r}: {method} failed ({first_line(e)}); the work "
                      "goes on, the run folder keeps everything (a re-run brings the tracker up to date)",
                      file=sys.stderr)
                self.warned = True
            return default


class GuardedTrainingRun(TrainingRun):
    def __init__(self, inner: TrainingRun, warner: _Warner) -> None:
        self.inner, self.warner = inner, warner

    @property
    def run_id(self) -> str | None:  # type: ignore[override]
        return self.inner.run_id

    def set_tags(self, tags: Mapping[str, str]) -> None:
        self.warner.call("set_tags", self.inner.set_tags, tags)

    def log_params(self, params: Mapping[str, str]) -> None:
        self.warner.call("log_params", self.inner.log_params, params)

    def log_metrics(self, rows: Rows) -> None:
        self.warner.call("log_metrics", self.inner.log_metrics, rows)

    def sync_metrics(self, rows: Rows) -> None:
        self.warner.call("sync_metrics", self.inner.sync_metrics, rows)

    def log_artifact(self, path: Path) -> None:
        self.warner.call("log_artifact", self.inner.log_artifact, path)

    def log_missing_artifacts(self, paths: Sequence[Path]) -> None:
        self.warner.call("log_missing_artifacts", self.inner.log_missing_artifacts, paths)

    def status(self) -> str | None:
        return self.warner.call("status", self.inner.status)

    def finish(self, status: str = "FINISHED") -> None:
        self.warner.call("finish", self.inner.finish, status)


class GuardedTracker(Tracker):
    """A user's tracker behind the guard above."""

    def __init__(self, inner: Tracker, backend: str, cfg) -> None:
        super().__init__(cfg)  # the command's own: a user's __init__ need not keep it
        self.inner, self.backend, self.warner = inner, backend, _Warner(backend)

    def training_run(self, run_id: str | None = None, reopen: bool = True) -> TrainingRun:
        run = at_start(self.backend, "creating the training run",
                       lambda: self.inner.training_run(run_id, reopen))
        return GuardedTrainingRun(run, self.warner)

    def discard_training_run(self, run_id: str) -> None:
        self.warner.call("discard_training_run", self.inner.discard_training_run, run_id)

    def finished_evaluation(self, train_run_id: str, eval_key: str) -> str | None:
        return self.warner.call("finished_evaluation", self.inner.finished_evaluation, train_run_id, eval_key)

    def log_evaluation(self, rows, tags, params) -> str | None:
        return self.warner.call("log_evaluation", self.inner.log_evaluation, rows, tags, params)

    def log_report(self, composite, paths, tags, source=None) -> str | None:
        return self.warner.call("log_report", self.inner.log_report, composite, paths, tags, source)


def open_tracker(cfg: Config) -> Tracker:
    """The tracker the command records to: the one place the tracking switch is decided."""
    if not cfg.tracking.enabled:
        return NullTracker(cfg)
    backend = cfg.tracking.backend
    cls = tracker_class(backend)
    if backend in BACKENDS:  # sigmarl's own: it warns and fails in one line by itself
        return cls(cfg)
    return GuardedTracker(at_start(backend, "its constructor", lambda: cls(cfg)), backend, cfg)
