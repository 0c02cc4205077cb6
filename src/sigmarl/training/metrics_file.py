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

from sigmarl.run import METRICS_FILE  # noqa: F401  (its callers name the file through here)


def append(path: Path, iteration: int, metrics: Mapping[str, float]) -> None:
    """Add one iteration's row (the header first, in a new file)."""
    new = not path.exists() or path.stat().st_size == 0
    with open(path, "a", encoding="utf-8") as f:
        if new:
            f.write(",".join(["iteration", *metrics]) + "\n")
        f.write(",".join([str(iteration), *(repr(float(v)) for v in metrics.values())]) + "\n")


def read(path: Path, upto: int | None = None) -> list[tuple[int, dict[str, float]]]:
    """[(iteration, {name: value})] in file order, up to iteration `upto`; a line a kill cut
    short is skipped."""
    if not path.exists():
        return []
    lines = path.read_text(encoding="utf-8").splitlines()
    if not lines:
        return []
    names = lines[0].split(",")[1:]
    rows = []
    for line in lines[1:]:
        fields = line.split(",")
        if len(fields) != len(names) + 1:
            continue
        try:
            it, values = int(fields[0]), [float(v) for v in fields[1:]]
        except ValueError:
            continue
        if upto is None or it <= upto:
            rows.append((it, dict(zip(names, values, strict=True))))
    return rows


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
