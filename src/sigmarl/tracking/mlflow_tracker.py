"""`tracking.backend=mlflow` (the default): the study's records in an MLflow store.

One connection per tracker, checked when the tracker is made (`store.connect`); training runs
are `MlflowTrainingRun`s, evaluation and report runs are written by `records`.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

from sigmarl.config import Config
from sigmarl.tracking import records
from sigmarl.tracking.store import connect, experiment_id
from sigmarl.tracking.study_run import parent_of, study_run
from sigmarl.tracking.tracker import Tracker, TrainingRun
from sigmarl.tracking.training import MlflowTrainingRun


class MlflowTracker(Tracker):
    def __init__(self, cfg: Config) -> None:
        super().__init__(cfg)
        self.client = connect(cfg)  # one line and a non-zero exit if the store is unusable
        self._experiment_id: str | None = None

    @property
    def experiment(self) -> str:
        return self.cfg.tracking.experiment

    def experiment_id(self) -> str:
        if self._experiment_id is None:
            self._experiment_id = experiment_id(self.client, self.experiment, create=True)
        return self._experiment_id

    def study(self, added: dict[str, list[str]] | None = None):
        return study_run(self.client, self.cfg, added)

    def training_run(self, run_id: str | None = None, reopen: bool = True) -> TrainingRun:
        return MlflowTrainingRun.open(self.cfg, self.client, run_id, reopen)

    def discard_training_run(self, run_id: str) -> None:
        MlflowTrainingRun(self.client, run_id).discard()

    def finished_evaluation(self, train_run_id: str, eval_key: str) -> str | None:
        run = records.finished_evaluation(self.client, self.experiment_id(), train_run_id, eval_key)
        return None if run is None else run.info.run_id

    def log_evaluation(self, rows, tags: dict[str, str], params: dict[str, str]) -> str | None:
        return records.log_evaluation(self.client, self.experiment_id(), rows, tags, params)

    def log_report(self, composite, paths: Iterable[Path], tags: dict[str, str],
                   source: str | None = None) -> str | None:
        # under the study's run where a sweep made one: the runs page opens on the study alone
        study = {"study": self.cfg.study.name, **parent_of(self.client, self.experiment_id(), self.cfg.study.name)}
        return records.log_report(self.client, self.experiment, composite, paths, {**tags, **study}, source)
