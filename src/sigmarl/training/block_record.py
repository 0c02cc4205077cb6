"""What a seed block leaves in its seeds' run folders, beyond a lone run's files.

- `block.json` in each seed's folder: the block it trained in (its seeds, its label). A folder
  of another block, a lone run's folder, or a block whose seeds changed is refused in one line
  before anything trains; `evaluate`, `report` and the sweep read block seeds as lone ones.
- The block's resume points are committed together, in two phases: every seed's new
  checkpoint is first written beside its old one (`checkpoint.next.pt`), and only when all are
  on disk is each renamed over `checkpoint.pt`. A kill in phase 1 leaves every old checkpoint
  (the new ones are dropped on resume); a kill in phase 2 leaves all the new ones written (the
  renames are finished on resume). So the seeds always resume from one common iteration.
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from sigmarl import crash
from sigmarl.errors import SigmarlError
from sigmarl.run import Run, write_atomic
from sigmarl.training import checkpoint as ckpt


def block_name(label: str, seeds: Sequence[int]) -> str:
    return f"{label} seeds {','.join(str(s) for s in seeds)}"


def read_block(run: Run) -> list[int] | None:
    """The seeds of the block a folder trained in, or None (a lone run, or nothing yet)."""
    path = run.block_file
    if not path.exists():
        return None
    try:
        seeds = json.loads(path.read_text(encoding="utf-8"))["seeds"]
        if not isinstance(seeds, list) or not all(isinstance(s, int) for s in seeds):
            raise ValueError("seeds is not a list of integers")
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise SigmarlError(f"{path} is damaged ({e}); it records the seed block the folder trained "
                           "in: restore it from the other seeds' folders of the block") from e
    return seeds


def check_membership(runs: Sequence[Run], seeds: Sequence[int]) -> None:
    """Refuse, before anything trains, folders that another block (or a lone run) trained in.
    `seeds` of one: a lone run."""
    for run in runs:
        recorded = read_block(run)
        # a finished seed is anyone's to complete and evaluate
        started = run.resume_file.exists() and not run.final_file.exists()
        if recorded is not None and recorded != list(seeds) and started:
            what = f"a block of seeds {list(seeds)}" if len(seeds) > 1 else "a lone run"
            raise SigmarlError(f"{run.dir} belongs to the seed block {recorded}; it cannot go on as {what}: "
                               f"train it with seeds={recorded} (the whole block), or choose another runs_root")
        if recorded is None and started and len(seeds) > 1:
            raise SigmarlError(f"{run.dir} holds a lone training run; a block cannot take it over: "
                               "train it alone, or leave its seed out of seeds=[...]")


def write_membership(runs: Sequence[Run], label: str, seeds: Sequence[int]) -> None:
    text = json.dumps({"block": block_name(label, seeds), "label": label, "seeds": list(seeds)}) + "\n"
    for run in runs:
        if read_block(run) != list(seeds):
            write_atomic(run.block_file, text)


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
