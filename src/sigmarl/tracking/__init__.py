"""Experiment tracking: where sigmarl records its runs; no other package imports mlflow.

- `tracker`: the seam (`Tracker`, `TrainingRun`, the null tracker, the class a backend names);
- `guard`: `open_tracker(cfg)` decides, in one place, which `Tracker` a command records to
  (`NullTracker` with `tracking.enabled=false`, else `tracking.backend`; a user's one guarded);
- `mlflow_tracker`: the MLflow tracker; `training`: its training runs;
- `store`: connecting to MLflow (fast failures, one clear line, a lock around a store's first use);
- `records`: MLflow's evaluation and report runs, and reading the study back for the report;
- `meta`: flat params, git commit.

MLflow's telemetry is switched off in `sigmarl/__init__.py`, before mlflow can be imported.
"""

from sigmarl.tracking.guard import open_tracker
from sigmarl.tracking.meta import flatten, git_commit
from sigmarl.tracking.store import artifact_location, connect, experiment_id
from sigmarl.tracking.tracker import NullTracker, Tracker, TrainingRun

__all__ = ["NullTracker", "Tracker", "TrainingRun", "artifact_location", "connect", "experiment_id",
           "flatten", "git_commit", "open_tracker"]
