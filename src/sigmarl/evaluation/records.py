"""The study's evaluation and report runs in MLflow: writing them and finding them again.

Training runs are written by `sigmarl.tracking.Tracker`; this module adds one
evaluation run per trained model (tag kind=evaluation, per-simulation rows as a
CSV artifact, scenario means as metrics) and reads them back for the report.
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from pathlib import Path

import pandas as pd
from omegaconf import DictConfig, OmegaConf

from sigmarl.errors import SigmarlError
from sigmarl.study import METRIC_COLUMNS, SCENARIOS

ROWS_ARTIFACT = "evaluation_rows.csv"
# A report downloads one small CSV per run: MLflow's progress bars would only be noise.
os.environ.setdefault("MLFLOW_ENABLE_ARTIFACTS_PROGRESS_BAR", "false")


def client_for(cfg: DictConfig):
    """An MlflowClient on the configured store, or a clear error if it cannot be reached."""
    from mlflow import MlflowClient
    from mlflow.tracking import get_tracking_uri

    uri = cfg.tracking.tracking_uri or get_tracking_uri()
    try:
        client = MlflowClient(tracking_uri=uri)
        client.search_experiments(max_results=1)
    except Exception as e:
        first = (str(e).strip().splitlines() or [type(e).__name__])[0]
        raise SigmarlError(f"MLflow tracking store {uri!r} is unreachable: {first[:300]}") from e
    return client


def experiment_id(client, name: str, create: bool = False) -> str | None:
    exp = client.get_experiment_by_name(name)
    if exp is not None:
        return exp.experiment_id
    if not create:
        return None
    from sigmarl.tracking import _artifact_location

    return client.create_experiment(name, artifact_location=_artifact_location(client.tracking_uri))


def eval_key(eval_cfg: DictConfig) -> str:
    """A short hash of the evaluation protocol: runs with equal keys are interchangeable."""
    protocol = OmegaConf.to_container(eval_cfg, resolve=True)
    # A scenario's name does not say which map it ran on (Table I's names moved from the
    # procedural maps to the paper's own): the key holds each scenario's map and agents.
    protocol["maps"] = {s: list(SCENARIOS[s]) for s in protocol["scenarios"] if s in SCENARIOS}
    blob = json.dumps(protocol, sort_keys=True)
    return hashlib.sha1(blob.encode()).hexdigest()[:12]


def finished_evaluation(client, exp_id: str, train_run_id: str, key: str):
    """The FINISHED evaluation run of a training run under an evaluation protocol, if any."""
    runs = client.search_runs(
        [exp_id],
        filter_string=(
            f"tags.kind = 'evaluation' and tags.train_run_id = '{train_run_id}' "
            f"and tags.eval_key = '{key}' and attributes.status = 'FINISHED'"
        ),
        max_results=1,
    )
    return runs[0] if runs else None


def log_evaluation(client, exp_id: str, rows: pd.DataFrame, tags: dict[str, str],
                   params: dict[str, str]) -> str:
    """One evaluation run: rows as a CSV artifact, per-scenario means as metrics."""
    run = client.create_run(exp_id, run_name=f"eval-{tags.get('model', 'policy')}-seed{tags.get('seed', '')}",
                            tags={"kind": "evaluation", **tags})
    rid = run.info.run_id
    try:
        for k, v in params.items():
            client.log_param(rid, k, v)
        means = rows.groupby("scenario")[METRIC_COLUMNS].mean()
        for scenario, row in means.iterrows():
            for metric, value in row.items():
                client.log_metric(rid, f"{scenario}/{metric}", float(value))
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / ROWS_ARTIFACT
            rows.to_csv(path, index=False)
            client.log_artifact(rid, str(path))
        client.set_terminated(rid, "FINISHED")
    except BaseException:
        client.set_terminated(rid, "FAILED")
        raise
    return rid


def load_evaluation_rows(client, experiment: str) -> pd.DataFrame:
    """All per-simulation rows of the experiment's finished evaluation runs."""
    exp_id = experiment_id(client, experiment)
    if exp_id is None:
        raise SigmarlError(f"no MLflow experiment named {experiment!r} (set tracking.experiment=...)")
    runs = client.search_runs(
        [exp_id], filter_string="tags.kind = 'evaluation' and attributes.status = 'FINISHED'",
        order_by=["attributes.start_time ASC"],
    )
    frames = []
    # Keep the newest evaluation of each (model, seed) so a re-evaluation replaces the old one.
    latest = {}
    for run in runs:
        latest[(run.data.tags.get("model"), run.data.tags.get("seed"), run.data.tags.get("obs"))] = run
    with tempfile.TemporaryDirectory() as tmp:
        for run in latest.values():
            path = client.download_artifacts(run.info.run_id, ROWS_ARTIFACT, tmp)
            frame = pd.read_csv(path)
            frame["eval_run_id"] = run.info.run_id
            frames.append(frame)
    if not frames:
        raise SigmarlError(
            f"no finished evaluation runs in experiment {experiment!r}: run `sigmarl sweep` "
            "or `sigmarl evaluate <run>` first"
        )
    return pd.concat(frames, ignore_index=True)


def load_training_curves(client, experiment: str, metric: str = "episode_reward_mean") -> pd.DataFrame:
    """(model, seed, iteration, reward) for the experiment's training runs."""
    exp_id = experiment_id(client, experiment)
    if exp_id is None:
        return pd.DataFrame(columns=["model", "seed", "iteration", "reward"])
    runs = client.search_runs([exp_id], filter_string="tags.kind = 'training'")
    rows = []
    for run in runs:
        for m in client.get_metric_history(run.info.run_id, metric):
            rows.append({"model": run.data.tags.get("model"), "seed": run.data.tags.get("seed"),
                         "iteration": m.step, "reward": m.value})
    return pd.DataFrame(rows, columns=["model", "seed", "iteration", "reward"])
