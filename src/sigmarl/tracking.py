"""The one place that talks to MLflow: one run per training, params, tags, metrics, artifacts.

The store is checked (read and write) before training starts, so a wrong or unreachable
`tracking.tracking_uri` ends in one message instead of a failure hours later. Once training
runs, a store that stops answering costs a warning, not the training.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any
from urllib.parse import urlparse

from omegaconf import DictConfig, OmegaConf

from sigmarl.errors import SigmarlError
from sigmarl.study import model_label, obs_strategies


def flatten(d: Mapping[str, Any], prefix: str = "") -> dict[str, str]:
    """{"ppo": {"lr": 2e-4}} -> {"ppo.lr": "0.0002"}; lists stay one value."""
    out: dict[str, str] = {}
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, Mapping):
            out.update(flatten(v, f"{key}."))
        else:
            out[key] = str(v)
    return out


def git_commit(start: Path | None = None) -> str | None:
    """The checkout's commit, read from .git files (no git process); None outside a checkout."""
    here = (start or Path(__file__)).resolve()
    for folder in [here, *here.parents]:
        git = folder / ".git"
        if git.is_file():  # worktree or submodule: "gitdir: <path>"
            text = git.read_text().strip()
            if not text.startswith("gitdir:"):
                return None
            git = (folder / text.removeprefix("gitdir:").strip()).resolve()
        if not git.is_dir():
            continue
        try:
            head = (git / "HEAD").read_text().strip()
            if not head.startswith("ref:"):
                return head or None
            ref = head.removeprefix("ref:").strip()
            common = git / "commondir"
            roots = [git] + ([(git / common.read_text().strip()).resolve()] if common.is_file() else [])
            for root in roots:
                if (root / ref).is_file():
                    return (root / ref).read_text().strip()
                packed = root / "packed-refs"
                if packed.is_file():
                    for line in packed.read_text().splitlines():
                        if line.endswith(f" {ref}"):
                            return line.split()[0]
        except OSError:
            return None
        return None
    return None


def _artifact_location(uri: str) -> str | None:
    """Artifacts of a local SQLite store go beside the database file, not into the cwd."""
    parsed = urlparse(uri)
    if parsed.scheme != "sqlite":
        return None
    db = uri.removeprefix("sqlite:///")
    if not db or db == ":memory:":
        return None
    return (Path(db).resolve().parent / "mlartifacts").as_uri()


def _has_run(client: Any, run_id: str) -> bool:
    from mlflow.exceptions import MlflowException

    try:
        client.get_run(run_id)
    except MlflowException as e:
        if e.error_code == "RESOURCE_DOES_NOT_EXIST":
            return False
        raise
    return True


class Tracker:
    """An MLflow run; `Tracker.disabled()` gives one that records nothing."""

    def __init__(self, client: Any = None, run_id: str | None = None, uri: str = "") -> None:
        self.client = client
        self.run_id = run_id
        self.uri = uri
        self._warned = False

    @classmethod
    def disabled(cls) -> Tracker:
        return cls()

    @property
    def enabled(self) -> bool:
        return self.client is not None

    @classmethod
    def open(cls, cfg: DictConfig, run_id: str | None = None) -> Tracker:
        """Connect, then create the run (or reopen `run_id` for a resume). Fails before training."""
        if not cfg.tracking.enabled:
            return cls.disabled()
        # fail in seconds, not after MLflow's default of 7 retries with exponential backoff
        os.environ.setdefault("MLFLOW_HTTP_REQUEST_MAX_RETRIES", "2")
        os.environ.setdefault("MLFLOW_HTTP_REQUEST_TIMEOUT", "30")
        from mlflow import MlflowClient
        from mlflow.tracking import get_tracking_uri

        uri = cfg.tracking.tracking_uri or get_tracking_uri()
        try:
            client = MlflowClient(tracking_uri=uri)
            if run_id is not None:
                if not _has_run(client, run_id):
                    raise SigmarlError(
                        f"MLflow run {run_id} (the one to resume) is not in the store {uri!r}; "
                        "resume with the tracking_uri it was started with"
                    )
                if client.get_run(run_id).info.lifecycle_stage != "active":
                    raise SigmarlError(f"MLflow run {run_id} was deleted; cannot resume into it")
                client.update_run(run_id, status="RUNNING")
                return cls(client, run_id, uri)
            name = cfg.tracking.experiment
            exp = client.get_experiment_by_name(name)
            exp_id = (
                exp.experiment_id
                if exp is not None
                else client.create_experiment(name, artifact_location=_artifact_location(uri))
            )
            tags = {
                "kind": "training",  # evaluation and report runs share the experiment
                "model": model_label(cfg.obs),
                "obs": obs_strategies(cfg.obs),
                "seed": str(cfg.seed),
            }
            if commit := git_commit():
                tags["git_commit"] = commit
                tags["mlflow.source.git.commit"] = commit
            run_name = f"{tags['model']}-seed{cfg.seed}"
            run = client.create_run(exp_id, run_name=run_name, tags=tags)
        except SigmarlError:
            raise
        except Exception as e:  # any store failure: bad URI, refused connection, unwritable file
            first = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
            raise SigmarlError(
                f"MLflow tracking store {uri!r} is unreachable or not writable: {first[:400]} "
                "(set tracking.tracking_uri=..., or tracking.enabled=false to train without it)"
            ) from e
        tracker = cls(client, run.info.run_id, uri)
        tracker.log_params(flatten(OmegaConf.to_container(cfg, resolve=True)))
        return tracker

    def _guard(self, method: str, *args: Any, **kwargs: Any) -> None:
        """Call client.<method>(run_id, ...) if tracking; a failing store only warns."""
        if not self.enabled:
            return
        try:
            getattr(self.client, method)(self.run_id, *args, **kwargs)
        except Exception as e:  # keep training; the checkpoints are the primary record
            if not self._warned:
                print(f"sigmarl: warning: MLflow {method} failed ({e}); training goes on", file=sys.stderr)
                self._warned = True

    def log_params(self, params: Mapping[str, str]) -> None:
        from mlflow.entities import Param

        items = [Param(k, v[:6000]) for k, v in params.items()]
        for i in range(0, len(items), 100):  # MLflow takes at most 100 params per batch
            self._guard("log_batch", params=items[i : i + 100])

    def log_metrics(self, rows: list[tuple[int, Mapping[str, float]]]) -> None:
        """Metrics of several iterations: [(step, {name: value}), ...]."""
        if not self.enabled or not rows:
            return
        import time

        from mlflow.entities import Metric

        now = int(time.time() * 1000)
        items = [Metric(k, float(v), now, step) for step, row in rows for k, v in row.items()]
        for i in range(0, len(items), 1000):  # MLflow's batch limit
            self._guard("log_batch", metrics=items[i : i + 1000])

    def log_artifact(self, path: Path) -> None:
        self._guard("log_artifact", str(path))

    def finish(self, status: str = "FINISHED") -> None:
        """FINISHED, KILLED (interrupted; resumable) or FAILED."""
        self._guard("set_terminated", status)
