"""The tracker seam: where sigmarl records its runs, decided in one place.

A `Tracker` receives what the commands record: training runs (params, per-iteration metrics,
artifacts, how they ended), evaluation runs and report runs. `tracker_class` finds the class a
`tracking.backend` names (`mlflow`, or `package.module:Class` for a tracker of your own, e.g.
TensorBoard or W&B: one subclass of `Tracker` and one of `TrainingRun`);
`sigmarl.tracking.guard.open_tracker(cfg)` decides which one a command records to.

Run folders stay the primary record. A tracker is a view of them: a store that stops answering
costs a warning, not the training, and a re-run brings the view up to date (`sync_metrics`,
`log_missing_artifacts`). Reading a study back for `sigmarl report` is MLflow's alone
(`tracking.records`); `report --from FOLDER` needs no tracker.
"""

from __future__ import annotations

import importlib
from abc import ABC, abstractmethod
from collections.abc import Iterable, Mapping, Sequence
from contextlib import AbstractContextManager, nullcontext
from pathlib import Path
from typing import TYPE_CHECKING

from sigmarl.errors import SigmarlError, first_line

if TYPE_CHECKING:
    import pandas as pd

    from sigmarl.config import Config

# backend name -> "module:Class"; any other `module:Class` is imported as given
BACKENDS = {"mlflow": "sigmarl.tracking.mlflow_tracker:MlflowTracker"}

Rows = Sequence[tuple[int, Mapping[str, float]]]  # [(iteration, {metric: value}), ...]


class TrainingRun(ABC):
    """One training's record in a tracker. `run_id` is stored in the run folder
    (`mlflow_run_id`) and its checkpoints, so that a resume reopens the same record."""

    run_id: str | None = None

    @abstractmethod
    def set_tags(self, tags: Mapping[str, str]) -> None: ...

    @abstractmethod
    def log_params(self, params: Mapping[str, str]) -> None: ...

    @abstractmethod
    def log_metrics(self, rows: Rows) -> None:
        """Whole iterations; a failure leaves none half logged."""

    @abstractmethod
    def sync_metrics(self, rows: Rows) -> None:
        """Log the iterations of `rows` the record lacks, never one twice."""

    @abstractmethod
    def log_artifact(self, path: Path) -> None: ...

    @abstractmethod
    def log_missing_artifacts(self, paths: Sequence[Path]) -> None: ...

    @abstractmethod
    def status(self) -> str | None:
        """RUNNING, FINISHED, KILLED or FAILED; None where nothing is recorded or known."""

    @abstractmethod
    def finish(self, status: str = "FINISHED") -> None:
        """FINISHED, KILLED (interrupted; resumable) or FAILED."""


class Tracker(ABC):
    """Where a command's records go. Constructing one checks its store, so that a store that
    cannot be used ends the command before any work."""

    def __init__(self, cfg: Config) -> None:
        self.cfg = cfg

    def study(self, added: dict[str, list[str]] | None = None) -> AbstractContextManager[str | None]:
        """Around a sweep's jobs: the study's own record, if the tracker keeps one (MLflow: a
        parent run of its training runs); its id, or None. `added`: the variants the sweep runs
        beyond the study's declared ones (label -> overrides), for the study's description."""
        return nullcontext()

    @abstractmethod
    def training_run(self, run_id: str | None = None, reopen: bool = True) -> TrainingRun:
        """Create the training run of `self.cfg`, or attach to `run_id` (marked RUNNING again
        with `reopen`). A run id the store does not hold gets a new run."""

    @abstractmethod
    def discard_training_run(self, run_id: str) -> None:
        """End and delete a training run that never finished (a start killed before its first
        checkpoint); quiet if it is gone."""

    @abstractmethod
    def finished_evaluation(self, train_run_id: str, eval_key: str) -> str | None:
        """The id of a finished evaluation of the training run under this protocol, if any."""

    @abstractmethod
    def log_evaluation(self, rows: pd.DataFrame, tags: dict[str, str], params: dict[str, str]) -> str | None:
        """One evaluation run (per-simulation rows, scenario means); its id."""

    @abstractmethod
    def log_report(self, composite: pd.DataFrame, paths: Iterable[Path], tags: dict[str, str],
                   source: str | None = None) -> str | None:
        """One report run (table files, figures, composite scores); its id."""


class NullTrainingRun(TrainingRun):
    """Records nothing; keeps the run id it was given (that of an earlier, tracked attempt),
    so that the run folder goes on naming it."""

    def __init__(self, run_id: str | None = None) -> None:
        self.run_id = run_id

    def set_tags(self, tags: Mapping[str, str]) -> None:
        pass

    def log_params(self, params: Mapping[str, str]) -> None:
        pass

    def log_metrics(self, rows: Rows) -> None:
        pass

    def sync_metrics(self, rows: Rows) -> None:
        pass

    def log_artifact(self, path: Path) -> None:
        pass

    def log_missing_artifacts(self, paths: Sequence[Path]) -> None:
        pass

    def status(self) -> str | None:
        return None

    def finish(self, status: str = "FINISHED") -> None:
        pass


class NullTracker(Tracker):
    """`tracking.enabled=false`: the run folders are the only record."""

    def training_run(self, run_id: str | None = None, reopen: bool = True) -> TrainingRun:
        return NullTrainingRun(run_id)

    def discard_training_run(self, run_id: str) -> None:
        pass

    def finished_evaluation(self, train_run_id: str, eval_key: str) -> str | None:
        return None

    def log_evaluation(self, rows, tags, params) -> str | None:
        return None

    def log_report(self, composite, paths, tags, source=None) -> str | None:
        return None


def tracker_class(backend: str) -> type[Tracker]:
    """The Tracker subclass a `tracking.backend` value names; SigmarlError if none."""
    target = BACKENDS.get(backend, backend)
    module_name, _, class_name = target.partition(":")
    if not module_name or not class_name:
        raise SigmarlError(f"tracking.backend must be one of {sorted(BACKENDS)} or 'package.module:Class', "
                           f"got {backend!r}")
    try:
        cls = getattr(importlib.import_module(module_name), class_name)
    except Exception as e:  # not found, a syntax error, or whatever its import raised
        raise SigmarlError(f"tracking.backend {backend!r}: cannot import {target} ({first_line(e)}); fix it, "
                           "or set tracking.enabled=false to run without it") from e
    if not (isinstance(cls, type) and issubclass(cls, Tracker)):
        raise SigmarlError(f"tracking.backend {backend!r}: {target} is not a sigmarl.tracking.Tracker")
    return cls
