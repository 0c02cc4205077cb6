"""What a seed block leaves in its seeds' run folders, beyond a lone run's files.

- `block.json` in each seed's folder: the block it trained in (`sigmarl.block_membership`).
- The block's resume points are committed together, in two phases: every seed's new
  checkpoint is first written beside its old one (`checkpoint.next.pt`), and only when all are
  on disk is each renamed over `checkpoint.pt`. A kill in phase 1 leaves every old checkpoint
  (the new ones are dropped on resume); a kill in phase 2 leaves all the new ones written (the
  renames are finished on resume). So the seeds always resume from one common iteration.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from sigmarl import crash
from sigmarl.errors import SigmarlError
from sigmarl.run import Run
from sigmarl.training import checkpoint as ckpt


def commit_checkpoints(runs: Sequence[Run], states: Sequence[dict[str, Any]]) -> None:
    """Replace every seed's resume point, all or none (see the module's docstring)."""
    if len(runs) == 1:
        ckpt.save_atomic(states[0], runs[0].resume_file)
        return
    for run, state in zip(runs, states, strict=True):
        ckpt.save_atomic(state, run.next_resume_file)
    crash.point(f"train:block-written:{states[0]['iteration']}")
    for i, run in enumerate(runs):
        os.replace(run.next_resume_file, run.resume_file)
        if i == 0:
            crash.point(f"train:block-renaming:{states[0]['iteration']}")


def settle_checkpoints(runs: Sequence[Run]) -> None:
    """Finish or drop a commit a kill interrupted, before the block resumes."""
    nexts = [run for run in runs if run.next_resume_file.exists()]
    if not nexts:
        return
    target = _iteration(nexts[0].next_resume_file)
    renamed = [run for run in runs if run not in nexts and run.resume_file.exists()
               and _iteration(run.resume_file) == target]
    if len(nexts) + len(renamed) == len(runs):  # phase 1 was complete: finish phase 2
        for run in nexts:
            os.replace(run.next_resume_file, run.resume_file)
    else:  # phase 1 was cut short: the old resume points stand
        for run in nexts:
            run.next_resume_file.unlink()


def _iteration(path: Path) -> int | None:
    try:
        return ckpt.load(path, resume=True)["iteration"]
    except SigmarlError:
        return None
