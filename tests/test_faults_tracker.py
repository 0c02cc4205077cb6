"""A user's tracker (`tracking.backend=module:Class`) is held to MLflow's promise: it fails in
one line when the command starts, and a call that fails once the work runs costs a warning,
not the training."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from sigmarl.cli import main
from sigmarl.compose import compose_config
from sigmarl.errors import Terminated
from sigmarl.tracking import open_tracker
from sigmarl.tracking.guard import GuardedTracker

GOOD = '''
from sigmarl.tracking import Tracker, TrainingRun

class Run(TrainingRun):
    run_id = "r1"
    def __init__(self, fail): self.fail, self.logged = fail, []
    def set_tags(self, tags): pass
    def log_params(self, params): pass
    def log_metrics(self, rows):
        if self.fail:
            raise ConnectionError("the tracker's server went away\\nline two")
        self.logged += [s for s, _ in rows]
    def sync_metrics(self, rows): self.log_metrics(rows)
    def log_artifact(self, path): pass
    def log_missing_artifacts(self, paths): pass
    def status(self): raise TimeoutError("no answer")
    def finish(self, status="FINISHED"): raise Terminated() if status == "interrupt" else None

class Good(Tracker):
    fail = False
    def training_run(self, run_id=None, reopen=True): return Run(self.fail)
    def discard_training_run(self, run_id): pass
    def finished_evaluation(self, train_run_id, eval_key): raise OSError("gone")
    def log_evaluation(self, rows, tags, params): raise OSError("gone")
    def log_report(self, composite, paths, tags, source=None): return "rep"

class Flaky(Good):
    fail = True

class Refuses(Good):
    def __init__(self, cfg): raise PermissionError("no token for the tracker's server")

class OwnInit(Good):
    def __init__(self, cfg): self.url = "https://tracker.example"  # keeps no cfg: its own business

class NoRun(Good):
    def training_run(self, run_id=None, reopen=True): raise ValueError("project not found")
'''

MODULES = {
    "own_tracker.py": "from sigmarl.errors import Terminated\n" + GOOD,
    "broken_syntax.py": "class Tracker(:\n    pass\n",
    "raises_at_import.py": "raise RuntimeError('needs WANDB_API_KEY')\n",
}


@pytest.fixture
def trackers(tmp_path, monkeypatch):
    for name, text in MODULES.items():
        (tmp_path / name).write_text(textwrap.dedent(text))
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.chdir(tmp_path)
    return tmp_path


@pytest.mark.parametrize("backend, says", [
    ("broken_syntax:Tracker", "SyntaxError"),
    ("raises_at_import:X", "needs WANDB_API_KEY"),
    ("own_tracker:Refuses", "its constructor failed (PermissionError: no token"),
    ("own_tracker:NoRun", "creating the training run failed (ValueError: project not found"),
])
def test_f14_a_tracker_that_fails_at_start_is_one_line(backend, says, trackers, capsys):
    rc = main(["train", "ppo=smoke", f"tracking.backend={backend}", f"runs_root={trackers / 'runs'}"])
    err = [line for line in capsys.readouterr().err.strip().splitlines() if not line.startswith("train:")]
    assert rc == 2 and len(err) == 1 and err[0].startswith("sigmarl: error: tracking.backend"), err
    assert says in err[0]
    assert not list(trackers.rglob("checkpoint.pt"))  # nothing trained


def test_a_tracker_whose_constructor_keeps_no_config_is_guarded_all_the_same(trackers):
    cfg = compose_config(["tracking.backend=own_tracker:OwnInit"])
    tracker = open_tracker(cfg)
    assert isinstance(tracker, GuardedTracker) and tracker.cfg is cfg and tracker.training_run().run_id == "r1"


def test_f15_a_tracker_that_fails_mid_run_costs_one_warning(trackers, capsys):
    tracker = open_tracker(compose_config(["tracking.backend=own_tracker:Flaky"]))
    assert isinstance(tracker, GuardedTracker)
    run = tracker.training_run()
    run.log_metrics([(1, {"r": 1.0})])  # raises inside: a warning, not an error
    run.sync_metrics([(2, {"r": 2.0})])
    assert run.status() is None and run.run_id == "r1"
    assert tracker.log_evaluation(None, {}, {}) is None and tracker.finished_evaluation("r1", "k") is None
    assert tracker.log_report(None, [], {}) == "rep"
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "warning" in err[0] and "log_metrics failed (ConnectionError" in err[0]
    with pytest.raises(Terminated):  # an interruption is never swallowed
        run.finish("interrupt")


@pytest.mark.slow
def test_f15_training_with_a_failing_tracker_finishes(trackers, capsys):
    rc = main(["train", "ppo=smoke", "ppo.iterations=2", "ppo.frames_per_iteration=128", "ppo.epochs=1",
               "ppo.minibatch_size=64", "tracking.backend=own_tracker:Flaky", f"runs_root={trackers / 'runs'}"])
    err = capsys.readouterr().err
    assert rc == 0, err
    assert err.count("sigmarl: warning: tracker") == 1
    run = next(Path(trackers / "runs").rglob("final.pt")).parent
    assert len((run / "metrics.csv").read_text().splitlines()) == 3  # header + 2 iterations
