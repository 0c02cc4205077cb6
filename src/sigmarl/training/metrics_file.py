"""`metrics.csv` in the run folder: one row per training iteration, the values sent to MLflow.

Rows are appended as iterations finish; a resume from iteration k first drops the rows after
k (the resumed run computes them again), so the file never holds an iteration twice. Values
are written with `repr`, which reads back as the same float, so MLflow can be brought up to
date from this file with exactly the values it would have received.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

from sigmarl.errors import SigmarlError
from sigmarl.readers import read_metrics
from sigmarl.run import METRICS_FILE  # noqa: F401  (its callers name the file through here)


def append(path: Path, iteration: int, metrics: Mapping[str, float]) -> dict[str, float]:
    """Add one iteration's row (the header first, in a new file); returns the row as written.

    A run keeps the columns it began with: resumed by a sigmarl that logs more (e.g.
    `episode_reward_mean_complete`), it leaves the new ones out, so that its file, and the
    history sent to the tracker, stay one table."""
    names = _header(path)
    if names is None:
        names = list(metrics)
        with open(path, "a", encoding="utf-8") as f:
            f.write(",".join(["iteration", *names]) + "\n")
    lacking = [n for n in names if n not in metrics]
    if lacking:
        raise SigmarlError(f"{path} has the column(s) {', '.join(lacking)} that this training does not log; "
                           "resume it with the sigmarl that began it, or move the run folder away")
    row = {n: float(metrics[n]) for n in names}
    with open(path, "a", encoding="utf-8") as f:
        f.write(",".join([str(iteration), *(repr(v) for v in row.values())]) + "\n")
    return row


def _header(path: Path) -> list[str] | None:
    """The metric names of an existing file's header, or None for a new (or empty) file."""
    if not path.exists() or path.stat().st_size == 0:
        return None
    with open(path, encoding="utf-8") as f:
        return f.readline().rstrip("\n").split(",")[1:]


def read(path: Path, upto: int | None = None) -> list[tuple[int, dict[str, float]]]:
    """[(iteration, {name: value})] of iterations 1..`upto` (all with None), checked: each line
    by `sigmarl.readers.read_metrics` (whole-number iterations, finite values), every iteration
    present once and in order. Only the last line may be cut (a kill while appending), and
    rows after `upto` are dropped (a resume computes them again); any other damage is one
    SigmarlError naming the file: a resume never goes on past a lost iteration."""
    rows = read_metrics(path, upto)
    found = [it for it, _ in rows]
    want = list(range(1, (upto if upto is not None else len(found)) + 1))
    if found != want:
        lost = sorted(set(want) - set(found))
        what = (f"lacks iteration(s) {_span(lost)}" if lost else "holds an iteration twice or out of order")
        raise SigmarlError(f"{path} {what} of the {len(want)} its run has done (cut or edited); restore it "
                           "from a copy, or move the run folder away and train again")
    return rows


def _span(its: list[int]) -> str:
    return str(its[0]) if len(its) == 1 else f"{its[0]}-{its[-1]}" if its == list(range(its[0], its[-1] + 1)) \
        else ", ".join(map(str, its[:5])) + (" ..." if len(its) > 5 else "")


def truncate(path: Path, upto: int) -> list[tuple[int, dict[str, float]]]:
    """Keep the rows up to iteration `upto` (rewritten atomically); returns them."""
    rows = read(path, upto)
    if not path.exists():
        return rows
    tmp = path.with_name(f".{path.name}.tmp")
    with open(tmp, "w", encoding="utf-8") as f:
        if rows:
            f.write(",".join(["iteration", *rows[0][1]]) + "\n")
            for it, values in rows:
                f.write(",".join([str(it), *(repr(v) for v in values.values())]) + "\n")
    os.replace(tmp, path)
    return rows
