"""What every probe of the reliability round is made of (`scripts/probe.py` runs them): the
`Probe` record, the smoke budget, a user's failing trackers, running the CLI in a folder, and
the checks a refusal must pass. The probe lists and their fixtures import it; it imports none
of them, so the round's scripts import one way."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SIGMARL = [sys.executable, "-m", "sigmarl"]
SMOKE = ["ppo=smoke", "tracking.enabled=false", "threads=1"]
# a study small enough for seconds: one iteration's evaluation of 5 steps on one scenario
TINY_EVAL = ["eval.n_sims=1", "eval.steps=5", "eval.scenarios=[Roundabout]"]


# A user's tracker (tracking.backend=module:Class) that fails: when it is made (Refuses), or on
# every metrics call once the work runs (Flaky); a probe writes it into its folder.
TRACKERS = '''
from sigmarl.tracking import Tracker, TrainingRun

class Run(TrainingRun):
    run_id = "r1"
    def set_tags(self, tags): pass
    def log_params(self, params): pass
    def log_metrics(self, rows): raise ConnectionError("the tracker's server went away")
    def sync_metrics(self, rows): self.log_metrics(rows)
    def log_artifact(self, path): pass
    def log_missing_artifacts(self, paths): pass
    def status(self): return "RUNNING"
    def finish(self, status="FINISHED"): pass

class Flaky(Tracker):
    def training_run(self, run_id=None, reopen=True): return Run()
    def discard_training_run(self, run_id): pass
    def finished_evaluation(self, train_run_id, eval_key): return None
    def log_evaluation(self, rows, tags, params): return None
    def log_report(self, composite, paths, tags, source=None): return None

class Refuses(Flaky):
    def __init__(self, cfg): raise PermissionError("no token for the tracker's server")
'''


@dataclass
class Probe:
    name: str  # "<fault>-<what>" (the fault, e.g. F13, selects every probe of it) or a plain name
    fault: str  # what is done, in words
    check: Callable[[Path], str | None]  # run in the probe's own folder: None, or what is wrong
    trains: bool = False  # it trains (or evaluates) a model: left out of `--quick`

    @property
    def fault_id(self) -> str:
        return self.name.split("-")[0]


def env(**extra: str) -> dict[str, str]:
    return {**os.environ, "OMP_NUM_THREADS": "1", "SIGMARL_CONFIG_PATH": "", **extra}


def sigmarl(argv: list[str], cwd: Path, timeout: int = 300, **extra: str) -> subprocess.CompletedProcess:
    return subprocess.run([*SIGMARL, *argv], cwd=cwd, capture_output=True, text=True, timeout=timeout,
                          env=env(**extra))


def start(argv: list[str], cwd: Path, **extra: str) -> subprocess.Popen:
    return subprocess.Popen([*SIGMARL, *argv], cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True, env=env(**extra))


def wait_for(condition: Callable[[], bool], seconds: float = 300) -> bool:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.2)
    return False


def files(folder: Path) -> dict[Path, bytes]:
    """Every file below `folder` with its bytes (to tell that a refusal changed nothing), but for
    the run folders' lock files beside them, which any command that checks a folder takes."""
    return {p.relative_to(folder): p.read_bytes() for p in folder.rglob("*")
            if p.is_file() and not (p.name.startswith(".") and p.name.endswith(".lock"))}


def last_line(done: subprocess.CompletedProcess) -> str:
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    return (lines or ["(no output)"])[-1][:200]


def one_line(done: subprocess.CompletedProcess, says: str) -> str | None:
    """None if `done` is a refusal in one line naming `says`, with exit code 2."""
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    if done.returncode != 2:
        return f"rc {done.returncode}, not 2: {last_line(done)}"
    if len(lines) != 1 or not lines[0].startswith("sigmarl: error:"):
        return f"{len(lines)} lines on stderr, not one `sigmarl: error:` line: {last_line(done)}"
    if says not in lines[0]:
        return f"the line does not name {says!r}: {lines[0][:200]}"
    return None


def refusal(argv: list[str], says: str, setup: Callable[[Path], None] | None = None) -> Callable[[Path], str | None]:
    """A probe: after `setup`, `sigmarl argv` is refused in one line naming `says`, and the folder
    is left exactly as it was (no new file, no changed one)."""
    def check(folder: Path) -> str | None:
        if setup:
            setup(folder)
        before = files(folder)
        wrong = one_line(sigmarl(argv, folder), says)
        if wrong:
            return wrong
        after = files(folder)
        if after != before:
            changed = sorted(str(p) for p in set(after) ^ set(before) | {p for p in after if after.get(p) != before.get(p)})
            return f"the refusal left the folder changed: {changed[:3]}"
        return None
    return check
