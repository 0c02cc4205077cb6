"""Evaluation rows (`evaluation_rows.csv`: one row per simulation, a column per metric of
`sigmarl.metrics`) and the checks every reader trusts them by: a report (`check_rows`) and a
resume or a sweep's plan (`rows_measured`, which takes saved rows' checksum where their note
records one). pandas is imported where rows are checked: a sweep's launcher asks whether its
jobs are done, by checksum, without it."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import TYPE_CHECKING

from sigmarl.errors import SigmarlError
from sigmarl.metrics import AS, BY_NAME, REQUIRED, measured
from sigmarl.params import VEHICLE
from sigmarl.scenarios import scenario_names

if TYPE_CHECKING:
    import pandas as pd

# Speeds are averaged in float32 and written to 8 significant digits: AS may exceed the top
# speed (the vehicle's, env.vehicle.max_speed) by rounding only.
AS_ROUNDING = 1e-4


def check_rows(rows: pd.DataFrame, path: Path, top_speed: float = VEHICLE.max_speed) -> pd.DataFrame:
    """`rows` (as read from `path`) if they are evaluation rows a report can trust: the
    columns, known scenario names, whole simulation numbers, and each metric as its declaration
    in `sigmarl.metrics` says: finite (or NaN where it may be undefined), within its bounds
    (rates in [0, 1], CD >= 0, AS in [0, top speed]) and equal to the sum it is of (CR_total =
    CR_AA + CR_AL). A metric declared after the rows were written may be absent (not measured
    in them). A truncated or edited file fails here, in one line naming it, instead of adding
    a made-up scenario or dropping a seed from the table."""
    import numpy as np
    import pandas as pd

    missing = [c for c in ("scenario", *REQUIRED) if c not in rows.columns]
    if missing:
        raise SigmarlError(f"{path}: evaluation rows lack the column(s) {', '.join(missing)}")

    def bad(what: str, mask: pd.Series) -> None:
        if mask.any():
            first, more = int(np.flatnonzero(mask.to_numpy())[0]), int(mask.sum()) - 1
            raise SigmarlError(f"{path}: {what} on line {first + 2}"  # the header is line 1
                               + (f" and {more} more" if more else ""))

    scenario = rows["scenario"].astype(str)
    unknown = ~scenario.isin(scenario_names())  # conf/scenario, a user's folders included
    bad(f"unknown scenario {scenario[unknown].iloc[0] if unknown.any() else ''!r}", unknown)
    present = measured(rows)
    numbers = [c for c in ("simulation", *present) if c in rows.columns]  # older files lack simulation
    metrics = rows[numbers].apply(pd.to_numeric, errors="coerce").astype(float)
    for column in numbers:
        undefined_ok = column in BY_NAME and BY_NAME[column].undefined
        values = metrics[column]
        bad(f"{column} is not a finite number", np.isinf(values) if undefined_ok else ~np.isfinite(values))
    if "simulation" in metrics:
        bad("simulation is not a whole number >= 0", (metrics["simulation"] < 0) | (metrics["simulation"] % 1 != 0))
    for name in present:
        _check_metric(BY_NAME[name], metrics, bad, top_speed)
    if "simulation" in metrics:
        bad("a simulation is given twice for its scenario", pd.Series(
            pd.DataFrame({"s": scenario, "n": metrics["simulation"]}).duplicated().to_numpy(), index=rows.index))
        _check_simulations(scenario, metrics["simulation"], path)
    return rows


def _check_metric(m, metrics: pd.DataFrame, bad, top_speed: float) -> None:
    """One declared metric's column: within its bounds (AS's top: the vehicle's top speed, up
    to rounding), the sum it is of. NaN (where the metric may be undefined) passes."""
    values = metrics[m.name]
    lo, hi = m.bounds
    if m.name == AS:
        bad(f"{AS} (m/s) is not in [0, {top_speed}]", (values < 0) | (values > top_speed + AS_ROUNDING))
    elif m.scale == 100.0 and (lo, hi) == (0.0, 1.0):
        bad(f"{m.name} is not a rate in [0, 1]", (values < lo) | (values > hi))
    elif hi == float("inf"):
        unit = {"cm": "cm from the center line"}.get(m.unit, m.unit)
        bad(f"{m.name} ({unit}) is negative", values < lo)
    else:
        bad(f"{m.name} is not in [{lo:g}, {hi:g}]", (values < lo) | (values > hi))
    if m.sum_of:
        parts = sum(metrics[p] for p in m.sum_of)
        bad(f"{m.name} is not {' + '.join(m.sum_of)}", (values - parts).abs() > 1e-6 + 1e-5 * parts)


def _check_simulations(scenario: pd.Series, simulation: pd.Series, path: Path) -> None:
    """Every scenario holds simulations 0..n-1, the same n for each (the protocol's eval.n_sims):
    a row dropped from a file otherwise moves a scenario's mean without a word."""
    counts = {}
    for name, sims in simulation.groupby(scenario, sort=False):
        n = len(sims)
        if sorted(sims.astype(int)) != list(range(n)):
            lost = sorted(set(range(int(sims.max()) + 1)) - set(sims.astype(int)))
            raise SigmarlError(f"{path}: scenario {name} lacks simulation(s) {lost[:5]}; restore the file, "
                               "or evaluate the run again (delete evaluation_rows.csv and sweep again)")
        counts[name] = n
    if len(set(counts.values())) > 1:
        raise SigmarlError(f"{path}: the scenarios hold different numbers of simulations ({counts}); restore the "
                           "file, or evaluate the run again (delete evaluation_rows.csv and sweep again)")


def rows_measured(rows_file: Path, meta_file: Path, key: str) -> bool:
    """Whether `rows_file` holds whole evaluation rows measured under the protocol `key`: its
    note (`meta_file`) names that key and, for rows saved since it records one, their SHA-256
    (a cut, edited or duplicated line changes it); older rows must pass the report's checks."""
    try:
        meta = json.loads(meta_file.read_text(encoding="utf-8"))
        data = rows_file.read_bytes()
    except (OSError, ValueError):
        return False
    if not isinstance(meta, dict) or meta.get("eval_key") != key:
        return False
    if "rows_sha256" in meta:
        return hashlib.sha256(data).hexdigest() == meta["rows_sha256"]
    import pandas as pd

    try:
        check_rows(pd.read_csv(rows_file, float_precision="round_trip"), rows_file)
    except (SigmarlError, ValueError):  # pandas' parser errors are ValueErrors
        return False
    return True


def note_protocol(meta: dict) -> str | None:
    """The protocol key (`eval_key.protocol_key`) of the rows a note describes. Notes from before
    the field name only their evaluation key, which equals the protocol's while the metric
    columns are the rules revision's own five (every such note's)."""
    found = meta.get("protocol_key", meta.get("eval_key"))
    return found if isinstance(found, str) else None
