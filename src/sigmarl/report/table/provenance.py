"""The study page's provenance: what each column's runs were trained on (their run folders'
`provenance.json`, `sigmarl.tracking.provenance`), and which columns differ in library versions
or hardware, so that a difference between columns is not read as the design's when the machine
or the libraries changed too. A run from before the record reads "not recorded"."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import pandas as pd

from sigmarl.run import Run
from sigmarl.tracking.provenance import KEYS, PACKAGES, read

NOT_RECORDED = "not recorded"
LIBRARIES = ("python", *PACKAGES)
HARDWARE = ("cpu", "gpu")

# label -> seed -> the run folder's records (None: not recorded)
Records = Mapping[str, Mapping[int, list[dict[str, Any]] | None]]


def run_records(folders: Sequence[tuple[str, int, Path]], rows: pd.DataFrame) -> dict[str, dict[int, Any]]:
    """label -> seed -> the provenance records of each run folder whose rows the report holds."""
    have = set(zip(rows["model"].astype(str), rows["seed"].astype(int), strict=True))
    out: dict[str, dict[int, Any]] = {}
    for label, seed, path in folders:
        if (str(label), int(seed)) in have:
            out.setdefault(str(label), {})[int(seed)] = read(Run(path))
    return out


def _text(value: Any, key: str) -> str:
    if key == "sigmarl_commit":
        return str(value)[:12] if value else "unknown"
    if key == "dirty":
        return {True: "dirty", False: "clean"}.get(value, "unknown")
    return str(value)


def values(records: Mapping[int, Any] | None, key: str) -> list[str]:
    """The distinct values of `key` over a column's runs and their starts, in order of seed;
    "not recorded" for a run without the record."""
    seen = []
    for seed in sorted(records or {}):
        runs = records[seed]
        for v in ([NOT_RECORDED] if runs is None else [_text(r.get(key), key) for r in runs]):
            if v not in seen:
                seen.append(v)
    return seen or [NOT_RECORDED]


def _differs(records: Records, models: Sequence[str], keys: Sequence[str]) -> list[str]:
    """'key: value (columns); value (columns)' for each key whose recorded values differ between
    or within columns (runs without the record left out)."""
    out = []
    for key in keys:
        by_value: dict[str, list[str]] = {}
        for m in models:
            for v in values(records.get(m), key):
                if v != NOT_RECORDED:
                    by_value.setdefault(v, []).append(m)
        if len(by_value) > 1:
            out.append(f"{key} " + "; ".join(f"{v} ({', '.join(ms)})" for v, ms in by_value.items()))
    return out


def provenance_markdown(records: Records, models: Sequence[str]) -> list[str]:
    """The study page's section: one row per recorded item, one column per model."""
    lines = ["## What the runs were trained on", ""]
    if not any(r is not None for m in models for r in (records.get(m) or {}).values()):
        return lines + [f"Provenance: {NOT_RECORDED} (every run was trained before sigmarl recorded it in "
                        "`provenance.json`)."]
    lines += ["| | " + " | ".join(models) + " |", "|---|" + "---|" * len(models)]
    lines += [f"| {key} | " + " | ".join(" / ".join(values(records.get(m), key)) for m in models) + " |"
              for key in KEYS]
    lines.append("")
    libraries, hardware = _differs(records, models, LIBRARIES), _differs(records, models, HARDWARE)
    if libraries:
        lines.append("**Trained under different library versions**: " + " · ".join(libraries) + ".")
    if hardware:
        lines.append("**Trained on different hardware**: " + " · ".join(hardware) + ".")
    if not libraries and not hardware:
        lines.append("Every recorded run used the same library versions and hardware.")
    if missing := [m for m in models if NOT_RECORDED in values(records.get(m), "python")]:
        lines.append(f"Runs of {', '.join(missing)} are {NOT_RECORDED} (trained before sigmarl recorded it).")
    return lines
