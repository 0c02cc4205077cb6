"""Will the training's tensors fit? A lower bound of the memory a training needs, held against
what the machine it runs on has free, before a run folder or an MLflow run exists: a config
far beyond memory (network.hidden=[60000,60000], 10**9 frames per iteration) is one line, not
an out-of-memory traceback after the run was recorded.

The bound counts only what surely exists, so that it never refuses a training that fits:
the actor's and the critic's hidden weights (a 4-byte float each; with their gradients and
Adam's two moments, four copies), and an iteration's frames of observations (collected, and
once more as the critic's input), at an observation of at least `MIN_OBS` entries.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

from sigmarl.config import Config
from sigmarl.errors import SigmarlError

FLOAT = 4  # bytes: training runs in fp32 (bf16 only inside the update's forward passes)
COPIES = 4  # weights, gradients, Adam's first and second moments
NETWORKS = 2  # the actor and the critic
MIN_OBS = 8  # every observation design observes more than this (ego speed, reference points, ...)
GIB = 2**30


def needed_bytes(cfg: Config, seeds: int = 1) -> int:
    """A lower bound of the memory `seeds` seeds of `cfg` need to train."""
    hidden = list(cfg.network.hidden)
    weights = sum(a * b for a, b in zip(hidden, hidden[1:], strict=False)) + MIN_OBS * hidden[0]
    frames = cfg.ppo.frames_per_iteration * cfg.env.n_agents * MIN_OBS * 2
    return seeds * FLOAT * (NETWORKS * COPIES * weights + frames)


def available_bytes(device: str) -> int | None:
    """Memory free on `device` of this machine (a GPU's, or the system's for cpu); None where
    it cannot be told."""
    if device.startswith("cuda"):
        # lazy: torch only where a training is about to start anyway
        import torch

        try:
            return int(torch.cuda.mem_get_info(torch.device(device))[0])
        except (RuntimeError, AssertionError, ValueError):  # no GPU, or not that one: said where it is used
            return None
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def check_fits(cfgs: Sequence[Config]) -> None:
    """One line if the seeds of `cfgs` (a seed block) surely need more memory than is free here."""
    first = cfgs[0]
    need, free = needed_bytes(first, len(cfgs)), available_bytes(first.device)
    if free is not None and need > free:
        raise SigmarlError(
            f"this training needs at least {need / GIB:.1f} GiB ({len(cfgs)} seed(s) of network.hidden="
            f"{list(first.network.hidden)}, ppo.frames_per_iteration={first.ppo.frames_per_iteration}, "
            f"env.n_agents={first.env.n_agents}), but {first.device} has {free / GIB:.1f} GiB free here; "
            "use smaller values")
