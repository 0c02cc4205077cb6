"""Report runs in MLflow: one killed with SIGKILL while logging (no handler runs) is left
RUNNING, and the next report ends it KILLED, while a report whose process still lives is
never touched."""

from __future__ import annotations

import os
import socket
from pathlib import Path

import forked
from mlflow import MlflowClient

from sigmarl.cli import main
from sigmarl.tracking.records import OWNER_HOST, OWNER_PID

FIXTURE = Path(__file__).parent / "data" / "results"
EXPERIMENT = "reports"


def _report_args(tmp_path: Path, uri: str, out: str) -> list[str]:
    return ["report", "--from", str(FIXTURE), "--no-figures", "--out", str(tmp_path / out),
            f"tracking.tracking_uri={uri}", f"tracking.experiment={EXPERIMENT}"]


def _reports(client: MlflowClient) -> dict[str, str]:
    exp = client.get_experiment_by_name(EXPERIMENT)
    return {r.info.run_id: r.info.status
            for r in client.search_runs([exp.experiment_id], filter_string="tags.kind = 'report'")}


def test_a_report_killed_while_logging_is_ended_by_the_next(tmp_path):
    uri = f"sqlite:///{tmp_path / 'mlflow.db'}"
    killed = forked.run(_report_args(tmp_path, uri, "a"), tmp_path, SIGMARL_CRASH_AT="report:logging")
    assert killed.returncode == -9
    client = MlflowClient(uri)
    (left,) = _reports(client).items()
    assert left[1] == "RUNNING"  # nothing could end it
    # a report still running in another live process (this one) must stay RUNNING
    exp_id = client.get_experiment_by_name(EXPERIMENT).experiment_id
    live = client.create_run(exp_id, tags={"kind": "report", OWNER_HOST: socket.gethostname(),
                                           OWNER_PID: str(os.getpid())}).info.run_id
    assert main(_report_args(tmp_path, uri, "b")) == 0
    states = _reports(client)
    assert states.pop(left[0]) == "KILLED" and states.pop(live) == "RUNNING"
    assert list(states.values()) == ["FINISHED"]  # the new report
