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
from sigmarl.run import METRICS_FILE  # noqa: F401  (its callers name the file through here)


def append(path: Path, iteration: int, metrics: Mapping[str, float]) -> None:
    """Add one iteration's row (the header first, in a new file)."""
    new = not path.exists() or path.stat().st_size == 0
    with open(path, "a", encoding="utf-8") as f:
        if new:
            f.write(",".join(["iteration", *metrics]) + "\n")
        f.write(",".join([str(iteration), *(repr(float(v)) for v in metrics.values())]) + "\n")


def read(path: Path, upto: int | None = None) -> list[tuple[int, dict[str, float]]]:
    """[(iteration, {name: value})] of iterations 1..`upto` (all with None), checked: every one
    present once and in order. Only the last line may be cut (a kill while appending), and
    rows after `upto` are dropped (a resume computes them again); any other damage is one
    SigmarlError naming the file: a resume never goes on past a lost iteration."""
    rows = _parse(path, upto)
    found = [it for it, _ in rows]
    want = list(range(1, (upto if upto is not None else len(found)) + 1))
    if found != want:
        lost = sorted(set(want) - set(found))
        what = (f"lacks iteration(s) {_span(lost)}" if lost else "holds an iteration twice or out of order")
        raise SigmarlError(f"{path} {what} of the {len(want)} its run has done (cut or edited); restore it "
                           "from a copy, or move the run folder away and train again")
    return rows


def _parse(path: Path, upto: int | None) -> list[tuple[int, dict[str, float]]]:
    fix = "restore it from a copy, or move the run folder away and train again"
    if upto == 0:  # a resume before the first iteration needs no row (a cut header included)
        return []
    if not path.exists():
        if upto:
            raise SigmarlError(f"{path} is missing, and its run has done {upto} iteration(s); {fix}")
        return []
    try:
        lines = path.read_bytes().decode("utf-8").split("\n")
    except UnicodeDecodeError as e:
        raise SigmarlError(f"{path} is not a metrics file (byte {e.start} is not text); {fix}") from None
    if lines and lines[-1] == "":
        lines.pop()  # the file ends with a newline
    if not lines:
        if upto:
            raise SigmarlError(f"{path} is empty, and its run has done {upto} iteration(s); {fix}")
        return []
    names = lines[0].split(",")[1:]
    if lines[0].split(",")[0] != "iteration" or not names or len(set(names)) < len(names):
        raise SigmarlError(f"{path}: line 1 is not a header `iteration,<metric>,...`; {fix}")
    rows = []
    for n, line in enumerate(lines[1:], 2):
        try:
            fields = line.split(",")
            if len(fields) != len(names) + 1:
                raise ValueError
            it, values = int(fields[0]), [float(v) for v in fields[1:]]
        except ValueError:
            if n == len(lines):  # the line a kill cut short while it was appended
                break
            raise SigmarlError(f"{path}: line {n} is not a row of {len(names) + 1} numbers; {fix}") from None
        if upto is None or it <= upto:
            rows.append((it, dict(zip(names, values, strict=True))))
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
