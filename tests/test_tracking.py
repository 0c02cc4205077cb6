"""tracking.py without training: model tags, flattened params, git commit, store checks."""

from __future__ import annotations

import os
import signal
import sys
from pathlib import Path

import pytest
from omegaconf import OmegaConf

from sigmarl.compose import compose_config
from sigmarl.config import as_dict
from sigmarl.errors import SigmarlError
from sigmarl.tracking import (
    NullTracker,
    TrainingRun,
    artifact_location,
    flatten,
    git_commit,
    open_tracker,
)


def test_flatten_dotted_keys_and_lists_as_one_value() -> None:
    d = OmegaConf.to_container(OmegaConf.create({"ppo": {"lr": 2e-4}, "net": {"h": [256, 256]}}))
    assert flatten(d) == {"ppo.lr": "0.0002", "net.h": "[256, 256]"}


def test_every_config_value_becomes_one_param() -> None:
    cfg = compose_config(["seed=3"])
    params = flatten(as_dict(cfg))
    assert params["seed"] == "3" and params["ppo.epochs"] == "60"
    assert params["ppo.minibatch_size"] == "512" and params["obs.preset"] == "full"
    assert params["model"] == "M0" and params["run_dir"].endswith("M0/seed3")


def _fake_git(root: Path, head: str) -> Path:
    (root / ".git" / "refs" / "heads").mkdir(parents=True)
    (root / ".git" / "HEAD").write_text(head)
    sub = root / "pkg" / "mod"
    sub.mkdir(parents=True)
    return sub


def test_git_commit_from_a_branch_ref(tmp_path: Path) -> None:
    sub = _fake_git(tmp_path, "ref: refs/heads/main\n")
    (tmp_path / ".git" / "refs" / "heads" / "main").write_text("a" * 40 + "\n")
    assert git_commit(sub) == "a" * 40


def test_git_commit_from_packed_refs_and_detached_head(tmp_path: Path) -> None:
    sub = _fake_git(tmp_path, "ref: refs/heads/dev\n")
    (tmp_path / ".git" / "packed-refs").write_text(f"# pack-refs\n{'b' * 40} refs/heads/dev\n")
    assert git_commit(sub) == "b" * 40
    (tmp_path / ".git" / "HEAD").write_text("c" * 40 + "\n")
    assert git_commit(sub) == "c" * 40


def test_no_commit_outside_a_checkout(tmp_path: Path) -> None:
    assert git_commit(tmp_path) is None


def test_sqlite_artifacts_live_beside_the_database(tmp_path: Path) -> None:
    uri = f"sqlite:///{tmp_path}/db/mlflow.db"
    assert artifact_location(uri) == (tmp_path / "db" / "mlartifacts").as_uri()
    assert artifact_location("http://localhost:5000") is None


def test_disabled_tracking_records_nothing(tmp_path: Path) -> None:
    tracker = open_tracker(compose_config(["tracking.enabled=false", f"tracking.tracking_uri=sqlite:///{tmp_path}/m.db"]))
    assert isinstance(tracker, NullTracker)
    assert tracker.training_run("abc").run_id == "abc"  # an earlier tracked attempt's id is kept
    tracker = tracker.training_run()
    assert tracker.run_id is None and tracker.status() is None
    tracker.log_metrics([(1, {"x": 1.0})])
    tracker.log_artifact(tmp_path / "missing")
    tracker.finish()
    assert not list(tmp_path.iterdir())  # no store was created


@pytest.mark.parametrize(
    "uri",
    ["http://127.0.0.1:9", "sqlite:///{tmp}/a_file/mlflow.db", "nosuchscheme://x"],
    ids=["refused", "path-under-a-file", "unknown-scheme"],
)
def test_unusable_store_is_one_clear_error(uri: str, tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setenv("MLFLOW_HTTP_REQUEST_MAX_RETRIES", "0")
    (tmp_path / "a_file").write_text("not a folder")
    cfg = compose_config([f"tracking.tracking_uri={uri.format(tmp=tmp_path)}"])
    with pytest.raises(SigmarlError, match="MLflow (tracking )?store"):
        open_tracker(cfg)


def _run_traced(call, sigterm_at: int | None = None) -> int:
    """Run `call()` under a line tracer; send this process SIGTERM when the `sigterm_at`-th
    Python line starts (once: a second SIGTERM would not wait, errors.on_signal). Returns the
    number of lines run."""
    count = 0

    def trace(frame, event, arg):
        nonlocal count
        if event == "line":
            count += 1
            if count == sigterm_at:
                os.kill(os.getpid(), signal.SIGTERM)
        return trace

    sys.settrace(trace)
    try:
        call()
    finally:
        sys.settrace(None)
    return count


def test_a_sigterm_inside_a_store_call_is_raised_when_the_call_has_ended(
        tmp_path: Path, monkeypatch, capfd) -> None:
    """SIGTERM at 20 points spread over one `log_batch` call of a training run's client:
    each time (but at its first line, before the call) the call stores all its metrics,
    `Terminated` comes when it returns, and the run is then ended KILLED with nothing on stderr.
    Measured before store calls held signals: a SIGTERM after the call's first INSERT left the
    SQLite connection holding its write lock, so ending the run waited 20 s for the lock and
    failed with MLflow's "database is locked" traceback, and the run stayed RUNNING (the flaky
    `test_sigterm_ends_the_training_run_killed`)."""
    from mlflow.entities import Metric

    from sigmarl import errors
    from sigmarl.errors import handle_sigterm

    monkeypatch.setattr(errors, "_terminating", False)
    previous = signal.getsignal(signal.SIGTERM), signal.getsignal(signal.SIGINT)
    handle_sigterm()
    try:
        cfg = compose_config([f"tracking.tracking_uri=sqlite:///{tmp_path}/mlflow.db",
                              "tracking.experiment=sig"])
        metrics = [Metric(name, float(step), 0, step) for step in range(1, 6) for name in "ab"]

        def log(tracker: TrainingRun) -> None:
            tracker.client.log_batch(tracker.run_id, metrics=metrics)

        log(open_tracker(cfg).training_run())  # warm: the first call also compiles its statements
        tracker = open_tracker(cfg).training_run()
        lines = _run_traced(lambda: log(tracker))
        assert lines > 1000  # the tracer sees MLflow's and SQLAlchemy's lines
        capfd.readouterr()
        for k in range(20):
            errors._terminating = False
            tracker = open_tracker(cfg).training_run()
            with pytest.raises(errors.Terminated):
                _run_traced(lambda t=tracker: log(t), sigterm_at=1 + lines * k // 20)
            tracker.finish("KILLED")
            client = tracker.client
            logged = [m.step for m in client.get_metric_history(tracker.run_id, "a")]
            assert logged == ([] if k == 0 else [1, 2, 3, 4, 5]), k
            assert client.get_run(tracker.run_id).info.status == "KILLED", k
            assert capfd.readouterr().err == "", k
    finally:
        signal.signal(signal.SIGTERM, previous[0])
        signal.signal(signal.SIGINT, previous[1])


def _nudged(value):
    """A value near `value` that a builder would build differently from."""
    if isinstance(value, bool) or not isinstance(value, (int, float, list)):
        raise TypeError(value)
    if isinstance(value, list):
        return [round(v * 1.05, 6) for v in value] or [1.3, 1.1]
    return value - 1 if isinstance(value, int) else round(value * 1.05, 6)


PROCEDURAL = ("lane_width", "arm_length", "arm_lengths", "n_arms", "junction_offset", "radius", "entry_radius",
              "n_ramps", "main_length", "ramp_drop", "ramp_angle", "ramp_radius")


@pytest.mark.parametrize("kind", ["intersection", "roundabout", "on_ramp"])
def test_the_map_params_are_the_keys_the_map_is_built_from(kind):
    """A training run's MLflow params leave out the map keys its kind ignores: each key left out
    leaves the built map as it is, and each kept one changes it (arm_length only where no
    arm_lengths are given, which these maps give)."""
    from dataclasses import replace

    import numpy as np

    from sigmarl.compose import compose_config
    from sigmarl.config.map import map_keys
    from sigmarl.maps import load_map

    base = compose_config([f"map={kind}"]).map

    def drawn(cfg):
        return [np.round(np.stack([lane.left, lane.right]), 9).tolist() for lane in load_map(cfg).lanelets.values()]

    before = drawn(base)
    for key in PROCEDURAL:
        same = drawn(replace(base, **{key: _nudged(getattr(base, key))})) == before
        shadowed = key == "arm_length" and base.arm_lengths
        assert same == (key not in map_keys(kind) or bool(shadowed)), (kind, key)
