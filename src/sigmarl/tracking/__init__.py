"""Everything that talks to MLflow; no other package imports mlflow.

- `store`: connecting (fast failures, one clear line, a lock around a store's first use);
- `training`: the training run (`Tracker`);
- `records`: evaluation and report runs, and reading the study back for the report;
- `meta`: flat params, git commit.

MLflow's telemetry is switched off in `sigmarl/__init__.py`, before mlflow can be imported.
"""

from sigmarl.tracking.meta import flatten, git_commit
from sigmarl.tracking.store import artifact_location, connect, experiment_id
from sigmarl.tracking.training import Tracker

__all__ = ["Tracker", "artifact_location", "connect", "experiment_id", "flatten", "git_commit"]
