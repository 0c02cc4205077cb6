"""What `sigmarl evaluate` is pointed at: a checkpoint file, a training run folder, or an MLflow
training run id, resolved to a checkpoint file.

Kept apart from the evaluation itself so that a wrong path is answered without importing
torch, the simulator or MLflow (seconds each).
"""

from __future__ import annotations

import tempfile
from pathlib import Path

from sigmarl.config import Config
from sigmarl.errors import SigmarlError

CHECKPOINTS = ("best", "final")


def checkpoint_name(which: str) -> str:
    """The file name of eval.checkpoint (`best` or `final`) in a run folder."""
    _check_which(which)
    from sigmarl.training import checkpoint as ckpt

    return ckpt.BEST_FILE if which == "best" else ckpt.FINAL_FILE


def _check_which(which: str) -> None:
    if which not in CHECKPOINTS:
        raise SigmarlError(f"eval.checkpoint must be 'best' or 'final', got {which!r}")


def resolve_checkpoint(target: str, cfg: Config, download_dir: Path | None = None) -> Path:
    """A checkpoint file from a path, a training run folder, or an MLflow training run id."""
    _check_which(cfg.eval.checkpoint)
    path = Path(target)
    if path.is_file():
        return path
    if not path.is_dir() and ("/" in target or target.endswith(".pt")):
        raise SigmarlError(f"checkpoint not found: {target}")
    if path.is_dir():
        name = checkpoint_name(cfg.eval.checkpoint)
        if (path / name).is_file():
            return path / name
        raise SigmarlError(f"{path} holds no {name} (has the training finished? see eval.checkpoint)")
    from sigmarl.tracking.store import missing_store

    if db := missing_store(cfg):  # nowhere to look the run id up: create no empty store
        raise SigmarlError(f"{target!r} is no checkpoint file or run folder, and there is no MLflow store "
                           f"at {db} to look it up as a training run id")
    from sigmarl.tracking import connect, records

    name = checkpoint_name(cfg.eval.checkpoint)
    out = download_dir or Path(tempfile.mkdtemp(prefix="sigmarl-ckpt-"))
    return records.training_checkpoint(connect(cfg, write=False), target, name, out)
