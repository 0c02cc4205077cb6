"""What several probes start from, made once per round (the first probe that asks makes it; a
probe copies it, never changes it): a training killed mid-run, the same training uninterrupted,
and a small finished study in an MLflow store."""

from __future__ import annotations

import shutil
import threading
from collections.abc import Callable
from pathlib import Path

from probe_kit import ROOT as REPO
from probe_kit import SMOKE, TINY_EVAL, sigmarl

ROOT: Path = Path("/nonexistent")  # set by probe.main to a folder of the round's temporary one
ITERATIONS = 8
KILLED_AT = 4  # the crash point after this iteration's checkpoint: SIGKILL, no handler runs
TRAIN = ["train", *SMOKE, f"ppo.iterations={ITERATIONS}", "ppo.checkpoint_every=1", "runs_root=runs"]
RESUME = [*TRAIN, "resume=true"]
RUN = Path("runs") / "M0" / "seed0"
STORE = "tracking.tracking_uri=sqlite:///mlflow.db"
STUDY = ["sweep", "study=quick", "models=[M0]", "ppo=smoke", "threads=1", *TINY_EVAL, STORE, "runs_root=runs"]
RESULTS = REPO / "tests" / "data" / "results"  # the smallest results folder: 3 iterations a run

_made: dict[str, Path] = {}
_locks: dict[str, threading.Lock] = {}
_guard = threading.Lock()


def _once(name: str, make: Callable[[Path], None]) -> Path:
    with _guard:
        lock = _locks.setdefault(name, threading.Lock())
    with lock:
        if name not in _made:
            folder = ROOT / name
            folder.mkdir(parents=True)
            make(folder)
            _made[name] = folder
    return _made[name]


def _expect(done, what: str) -> None:
    if done.returncode != 0:
        raise RuntimeError(f"{what} failed (rc {done.returncode}): {done.stderr[-400:]}")


def _killed(folder: Path) -> None:
    done = sigmarl(TRAIN, folder, SIGMARL_CRASH_AT=f"train:checkpoint:{KILLED_AT}")
    if done.returncode != -9 or (folder / RUN / "final.pt").exists():
        raise RuntimeError(f"the training was not killed at its crash point (rc {done.returncode})")


def killed() -> Path:
    """A folder whose runs/M0/seed0 was killed (SIGKILL) after iteration 4's checkpoint of 8."""
    return _once("killed", _killed)


def whole() -> Path:
    """The same training as `killed`'s, run to its end without a kill."""
    return _once("whole", lambda f: _expect(sigmarl(TRAIN, f), "the uninterrupted training"))


def study() -> Path:
    """A finished study: M0 seed 0 trained, evaluated and logged in ./mlflow.db."""
    return _once("study", lambda f: _expect(sigmarl(STUDY, f), "the quick study's sweep"))


def copy_of(source: Callable[[], Path]) -> Callable[[Path], None]:
    """A probe's setup: the fixture's files copied into the probe's folder."""
    def setup(folder: Path) -> None:
        shutil.copytree(source(), folder, dirs_exist_ok=True, symlinks=True)
    return setup


def results_copy(folder: Path) -> Path:
    shutil.copytree(RESULTS, folder / "results")
    return folder / "results"
