"""Checkpoints: one dict per file, written atomically so a crash never leaves half a file.

`checkpoint.pt` is the resume point (rewritten every few iterations), `best.pt` holds the policy
with the best mean episode reward, `final.pt` the one after the last iteration. All three have
the same layout, so any of them can be loaded with `load_policy`.
"""

from __future__ import annotations

import os
import random
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import torch

from sigmarl.errors import SigmarlError

FORMAT = 1
RESUME_FILE = "checkpoint.pt"
BEST_FILE = "best.pt"
FINAL_FILE = "final.pt"


def save_atomic(state: dict[str, Any], path: Path) -> None:
    """Write to a temporary file in the same folder, then rename over the target."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            torch.save(state, f)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o644)  # mkstemp makes it owner-only
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def load(path: Path, device: str | torch.device = "cpu") -> dict[str, Any]:
    """Read a checkpoint; anything unreadable or foreign is a SigmarlError (the file is left alone)."""
    if not path.is_file():
        raise SigmarlError(f"no checkpoint at {path}")
    try:
        state = torch.load(path, map_location=device, weights_only=True)
    except Exception as e:  # torch raises many types for truncated or foreign files
        raise SigmarlError(f"checkpoint {path} is unreadable ({type(e).__name__}: {e})") from e
    if not isinstance(state, dict) or state.get("format") != FORMAT:
        raise SigmarlError(f"{path} is not a sigmarl checkpoint (format {FORMAT})")
    missing = {"iteration", "policy", "critic", "optimizer", "config", "dims"} - state.keys()
    if missing:
        raise SigmarlError(f"checkpoint {path} lacks {sorted(missing)}")
    return state


def rng_state() -> dict[str, Any]:
    """Every global generator the training touches (torch CPU/CUDA, numpy, random)."""
    np_state = np.random.get_state()
    state: dict[str, Any] = {
        "torch": torch.get_rng_state(),
        "numpy": [np_state[0], torch.from_numpy(np_state[1].copy()), *np_state[2:]],
        "random": random.getstate(),
    }
    if torch.cuda.is_available() and torch.cuda.is_initialized():
        state["cuda"] = torch.cuda.get_rng_state_all()
    return state


def set_rng_state(state: dict[str, Any]) -> None:
    torch.set_rng_state(state["torch"].cpu())
    name, keys, *rest = state["numpy"]
    np.random.set_state((name, keys.cpu().numpy(), *rest))
    random.setstate(_as_tuple(state["random"]))
    if "cuda" in state and torch.cuda.is_available():
        torch.cuda.set_rng_state_all([s.cpu() for s in state["cuda"]])


def _as_tuple(x: Any) -> Any:
    """random.setstate wants nested tuples; a save/load round trip may turn them into lists."""
    return tuple(_as_tuple(v) for v in x) if isinstance(x, list | tuple) else x
