"""What `sigmarl evaluate` is pointed at: a checkpoint file, a training run folder, or an MLflow
training run id, resolved to a checkpoint file.

Kept apart from the evaluation itself so that a wrong path is answered without importing
torch, the simulator or MLflow (seconds each).
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from sigmarl.config import Config
from sigmarl.errors import SigmarlError
from sigmarl.readers import read_run_config
from sigmarl.run import Run, checkpoint_name

# What `sigmarl evaluate` takes from the command line: the protocol, the store, where it runs, and
# the study (its scenarios and evaluation budget). The policy's own settings (observation,
# network, map, rules, seed) come from the checkpoint's training config.
HONOURED = ("eval", "tracking", "study", "threads", "device")


def check_evaluate_overrides(overrides: list[str]) -> None:
    """Refuse, in one line, overrides that `sigmarl evaluate` would silently drop."""
    def key(o: str) -> str:
        return o.lstrip("+~").split("=", 1)[0].strip()

    dropped = [o for o in overrides if key(o).split(".", 1)[0] not in HONOURED]
    if dropped:
        raise SigmarlError(f"evaluate cannot honour {', '.join(dropped)}: a trained policy keeps its training "
                           f"config (train a model with them instead); evaluate takes only "
                           f"{', '.join(k + ('' if k in ('threads', 'device') else '.*') for k in HONOURED)}")


def resolve_checkpoint(target: str, cfg: Config, download_dir: Path | None = None) -> Path:
    """A checkpoint file from a path, a training run folder, or an MLflow training run id."""
    checkpoint_name(cfg.eval.checkpoint)  # a wrong choice is answered first
    path = Path(target)
    if path.is_file():
        return path
    if not path.is_dir() and ("/" in target or target.endswith(".pt")):
        raise SigmarlError(f"checkpoint not found: {target}")
    if path.is_dir():
        found = Run(path).checkpoint(cfg.eval.checkpoint)
        if found.is_file():
            return found
        raise SigmarlError(f"{path} holds no {found.name} (has the training finished? see eval.checkpoint)")
    # lazy: a wrong path is answered without MLflow (start-up)
    from sigmarl.tracking.store import missing_store

    if db := missing_store(cfg):  # nowhere to look the run id up: create no empty store
        raise SigmarlError(f"{target!r} is no checkpoint file or run folder, and there is no MLflow store "
                           f"at {db} to look it up as a training run id")
    from sigmarl.tracking import connect, records

    name = checkpoint_name(cfg.eval.checkpoint)
    out = download_dir or Path(tempfile.mkdtemp(prefix="sigmarl-ckpt-"))
    return records.training_checkpoint(connect(cfg, write=False), target, name, out)


def into_its_experiment(path: Path, cfg: Config, overrides: list[str]) -> Path:
    """Log the evaluation of a run folder's checkpoint into the experiment it was trained in
    (where MLflow nests it under its training run), unless the command line chose one."""
    chosen = any(o.lstrip("+~").split("=", 1)[0].strip() in ("tracking.experiment", "study") for o in overrides)
    run = Run(path.resolve().parent)
    if not chosen and run.config_file.is_file():
        cfg.tracking.experiment = read_run_config(run.config_file).tracking.experiment
    return path


def run_folder_held(checkpoint: Path):
    """The lock of the run folder holding `checkpoint` (refused in one line while another process
    trains it); nothing to hold for a checkpoint elsewhere or in a folder this user cannot write."""
    import contextlib

    run = Run(checkpoint.resolve().parent)
    if not (run.config_file.exists() or run.resume_file.exists()):
        return contextlib.nullcontext()
    try:
        os.close(os.open(run.lock_file, os.O_RDWR | os.O_CREAT, 0o644))
    except OSError:  # a read-only copy of a results folder: nobody trains there
        return contextlib.nullcontext()
    return run.lock()
