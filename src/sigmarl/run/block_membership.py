"""Which seed block a run folder trained in: `block.json` in each seed's folder (its seeds, its
label). A folder of another block, a lone run's folder, or a block whose seeds changed is
refused in one line before anything trains: by `sigmarl train seeds=[...]` and, before any job
starts, by the sweep's plan. `evaluate`, `report` and the sweep read block seeds as lone ones.
Torch-free, so that planning a sweep stays so."""

from __future__ import annotations

import json
from collections.abc import Sequence

from sigmarl.errors import SigmarlError
from sigmarl.run import Run, write_atomic


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
