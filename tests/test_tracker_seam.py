"""The tracker seam: the tracking switch is read in one place, and a tracker of one's own is one
class and a config choice (`tracking.backend=package.module:Class`), used by every command."""

from __future__ import annotations

import ast
import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pandas as pd
import pytest

import sigmarl
from sigmarl.compose import compose_config
from sigmarl.errors import SigmarlError
from sigmarl.tracking import NullTracker, open_tracker
from sigmarl.tracking.mlflow_tracker import MlflowTracker
from sigmarl.tracking.tracker import tracker_class

SRC = Path(sigmarl.__file__).parent

# A complete tracker of one's own: every record as one JSON line in a file named by
# tracking.tracking_uri. It is what a TensorBoard or W&B tracker would be, minus the library.
JSONL_TRACKER = '''
import json, os
from pathlib import Path
from sigmarl.tracking import Tracker, TrainingRun

def _write(cfg, **record):
    with open(cfg.tracking.tracking_uri, "a") as f:
        f.write(json.dumps(record) + "\\n")

class JsonlRun(TrainingRun):
    def __init__(self, cfg, run_id):
        self.cfg, self.run_id, self.steps = cfg, run_id, set()
    def set_tags(self, tags): _write(self.cfg, run=self.run_id, tags=dict(tags))
    def log_params(self, params): _write(self.cfg, run=self.run_id, params=dict(params))
    def log_metrics(self, rows):
        for step, row in rows:
            self.steps.add(step)
            _write(self.cfg, run=self.run_id, step=step, metrics=dict(row))
    def sync_metrics(self, rows): self.log_metrics([(s, r) for s, r in rows if s not in self.steps])
    def log_artifact(self, path): _write(self.cfg, run=self.run_id, artifact=Path(path).name)
    def log_missing_artifacts(self, paths):
        for p in paths: self.log_artifact(p)
    def status(self): return None
    def finish(self, status="FINISHED"): _write(self.cfg, run=self.run_id, status=status)

class JsonlTracker(Tracker):
    def __init__(self, cfg):
        super().__init__(cfg)
        Path(cfg.tracking.tracking_uri).touch()  # checked before any work: an unwritable path fails here
    def training_run(self, run_id=None, reopen=True):
        run_id = run_id or f"{self.cfg.model}-{self.cfg.seed}"
        self.params = None
        run = JsonlRun(self.cfg, run_id)
        run.log_params({"seed": str(self.cfg.seed), "model": self.cfg.model})
        return run
    def discard_training_run(self, run_id): _write(self.cfg, run=run_id, status="DISCARDED")
    def finished_evaluation(self, train_run_id, eval_key): return None
    def log_evaluation(self, rows, tags, params):
        _write(self.cfg, evaluation=tags["model"], seed=tags["seed"], n_rows=len(rows),
               means=rows.groupby("scenario")["CR_total"].mean().to_dict())
        return "eval-" + tags["model"]
    def log_report(self, composite, paths, tags, source=None):
        _write(self.cfg, report=source, files=sorted(Path(p).name for p in paths))
        return "report"
'''

TINY = ["study=quick", "models=[M0]", "seeds=[0]", "ppo.iterations=2", "ppo.frames_per_iteration=128",
        "ppo.epochs=1", "ppo.minibatch_size=64", "eval.n_sims=1", "eval.steps=10",
        "eval.scenarios=[Intersection]"]


def _sigmarl(args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(cwd), os.environ.get("PYTHONPATH", "")])}
    return subprocess.run([sys.executable, "-m", "sigmarl", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=900)


def test_the_tracking_switch_is_read_in_one_place() -> None:
    """`tracking.enabled` is read by `open_tracker` and nowhere else in the package."""
    readers = []
    for path in SRC.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if (isinstance(node, ast.Attribute) and node.attr == "enabled"
                    and isinstance(node.value, ast.Attribute) and node.value.attr == "tracking"):
                readers.append(f"{path.relative_to(SRC)}:{node.lineno}")
    assert readers == ["tracking/guard.py:" + str(_line_of("if not cfg.tracking.enabled:"))]


def _line_of(text: str) -> int:
    lines = (SRC / "tracking" / "guard.py").read_text().splitlines()
    return next(i for i, line in enumerate(lines, 1) if text in line)


def test_the_switch_chooses_the_tracker(tmp_path: Path) -> None:
    uri = f"sqlite:///{tmp_path}/mlflow.db"
    off = open_tracker(compose_config(["tracking.enabled=false", f"tracking.tracking_uri={uri}"]))
    assert isinstance(off, NullTracker)
    assert off.log_evaluation(pd.DataFrame(), {}, {}) is None and off.finished_evaluation("x", "k") is None
    assert not (tmp_path / "mlflow.db").exists()  # tracking off touches no store
    on = open_tracker(compose_config([f"tracking.tracking_uri={uri}"]))
    assert isinstance(on, MlflowTracker) and (tmp_path / "mlflow.db").exists()


@pytest.mark.parametrize("backend, says", [
    ("nosuchmodule:Thing", "cannot import nosuchmodule:Thing"),
    ("os.path:join", "is not a sigmarl.tracking.Tracker"),
    ("wandb", "must be one of ['mlflow'] or 'package.module:Class'"),
])
def test_a_bad_backend_is_refused_at_composition(backend: str, says: str) -> None:
    with pytest.raises(SigmarlError, match=r"tracking\.backend") as e:
        compose_config([f"tracking.backend={backend}"])
    assert says in str(e.value)
    with pytest.raises(SigmarlError):
        tracker_class(backend)


def test_a_bad_backend_on_the_command_line_is_one_line_and_exit_2(tmp_path: Path) -> None:
    done = _sigmarl(["train", "tracking.backend=nosuchmodule:Thing", f"runs_root={tmp_path}/runs"], tmp_path)
    assert done.returncode == 2
    assert done.stderr.strip().count("\n") == 0 and "tracking.backend" in done.stderr
    assert not (tmp_path / "runs").exists() and not (tmp_path / "mlflow.db").exists()


@pytest.mark.slow
def test_a_tracker_of_ones_own_records_a_whole_study(tmp_path: Path) -> None:
    """sweep (training in a joblib worker, then evaluation) and report --from, all recorded
    by a tracker defined outside the package; no MLflow store is made."""
    (tmp_path / "jsonl_tracker.py").write_text(textwrap.dedent(JSONL_TRACKER))
    log = tmp_path / "records.jsonl"
    own = ["tracking.backend=jsonl_tracker:JsonlTracker", f"tracking.tracking_uri={log}"]
    done = _sigmarl(["sweep", *TINY, *own, f"runs_root={tmp_path}/runs"], tmp_path)
    assert done.returncode == 0, done.stderr[-3000:]
    done = _sigmarl(["report", "--from", "runs", "--no-figures", *own], tmp_path)
    assert done.returncode == 0, done.stderr[-3000:]
    assert not list(tmp_path.rglob("mlflow.db*")) and not (tmp_path / "mlartifacts").exists()

    records = [json.loads(line) for line in log.read_text().splitlines()]
    run_dir = tmp_path / "runs" / "M0" / "seed0"
    metrics = pd.read_csv(run_dir / "metrics.csv")
    logged = {r["step"]: r["metrics"] for r in records if "step" in r}
    assert sorted(logged) == [1, 2]  # each iteration once
    for _, row in metrics.iterrows():
        assert logged[int(row["iteration"])]["episode_reward_mean"] == pytest.approx(row["episode_reward_mean"])
    assert {"status": "FINISHED", "run": "M0-0"} in records
    assert (run_dir / "mlflow_run_id").read_text().strip() == "M0-0"  # the folder names its record
    assert {r["artifact"] for r in records if "artifact" in r} >= {"config.yaml", "best.pt", "final.pt"}
    assert any("resolved.precision" in r.get("tags", {}) for r in records)

    rows = pd.read_csv(run_dir / "evaluation_rows.csv")
    (evaluation,) = [r for r in records if "evaluation" in r]
    assert evaluation["n_rows"] == len(rows) == 1
    assert evaluation["means"]["Intersection"] == pytest.approx(rows["CR_total"].mean())
    assert (run_dir / "evaluated.txt").read_text().strip() == "eval-M0"
    (report,) = [r for r in records if "report" in r]
    assert report["report"] == "runs" and "table.md" in report["files"]
