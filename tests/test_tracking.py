"""tracking.py without training: model tags, flattened params, git commit, store checks."""

from __future__ import annotations

from pathlib import Path

import pytest
from omegaconf import OmegaConf

from sigmarl.compose import compose_config
from sigmarl.config import as_dict
from sigmarl.errors import SigmarlError
from sigmarl.tracking import Tracker, artifact_location, flatten, git_commit


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
    tracker = Tracker.open(compose_config(["tracking.enabled=false"]))
    assert not tracker.enabled and tracker.run_id is None
    tracker.log_metrics([(1, {"x": 1.0})])
    tracker.log_artifact(tmp_path / "missing")
    tracker.finish()


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
        Tracker.open(cfg)
