"""The study's metrics, one record each: every module that names, scales, ranks or scores a
metric reads it from here. Adding a metric to Table I is a record here plus its computation in
`sigmarl.evaluation.rollout` (which writes one column of that name per simulation).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from sigmarl.errors import SigmarlError

if TYPE_CHECKING:  # pandas is imported where rows are read
    import pandas as pd


@dataclass(frozen=True)
class Metric:
    name: str  # the evaluation rows' column
    unit: str  # as the table shows it (the paper's reference CSV's unit names)
    scale: float  # a row's value x scale = the table's value (rows hold fractions of steps)
    lower_is_better: bool
    # sign in the paper's composite score (eq. 2), each term divided by its mean over the
    # compared models; 0: not part of it
    composite: int
    collision: bool  # a collision rate: `--trim` drops each evaluation's best and worst simulation
    # the default equivalence margin of a verdict, in the table's units (a study may declare its own)
    margin: float = 0.1
    zero_mean_note: str = ""  # why the composite score is undefined when its mean is 0
    meaning: str = ""

    @property
    def direction(self) -> int:
        """+1 where higher is better, -1 where lower is."""
        return -1 if self.lower_is_better else 1


METRICS: tuple[Metric, ...] = (
    Metric("CR_AA", "percent", 100.0, True, 0, True,
           meaning="steps with at least one agent-agent collision"),
    Metric("CR_AL", "percent", 100.0, True, 0, True,
           meaning="steps with at least one agent-lane (boundary) collision"),
    Metric("CR_total", "percent", 100.0, True, -1, True, 0.1,
           "composite score undefined: no model collided (mean CR_total is 0)",
           "CR_AA + CR_AL"),
    Metric("CD", "cm", 1.0, True, -1, False, 0.1,
           "composite score undefined: mean center-line deviation CD is 0",
           "mean distance of the center of gravity to the own route's center line"),
    Metric("AS", "m/s", 1.0, False, 1, False, 0.01,
           "composite score undefined: no model moved (mean AS is 0)",
           "mean speed over all agent-steps"),
)
BY_NAME = {m.name: m for m in METRICS}
TABLE_DIGITS = 2  # decimals of every table cell, in the table's units (and of the metrics MLflow shows)
METRIC_COLUMNS = [m.name for m in METRICS]  # the evaluation rows' metric columns, in table order
COLLISION_COLUMNS = tuple(m.name for m in METRICS if m.collision)
COMPOSITE = {m.name: float(m.composite) for m in METRICS if m.composite}
# the table's unit of each row; the composite score's own row: unitless, higher is better
UNITS = {**{m.name: m.unit for m in METRICS}, "CS": "1"}
# the evaluation rows' own units (what `scale` turns into the table's)
ROW_UNITS = {m.name: "fraction of steps" if m.unit == "percent" else m.unit for m in METRICS}
LOWER_IS_BETTER = frozenset(m.name for m in METRICS if m.lower_is_better)


def shown_unit(name: str) -> str:
    """A table row's unit as printed: "%" for percent, nothing for the unitless score."""
    unit = UNITS.get(name, "")
    return {"percent": "%", "1": ""}.get(unit, unit)


def label(name: str) -> str:
    """A row or column name with its unit as printed: "CR_AA (%)", "CD (cm)", "CS"."""
    unit = shown_unit(name)
    return f"{name} ({unit})" if unit else name


def units_text(of_steps: bool = False) -> str:
    """The table's units in words: "collision rates in %, CD in cm, AS in m/s"."""
    rates = dict.fromkeys(shown_unit(m.name) + (" of steps" if of_steps else "") for m in METRICS if m.collision)
    return ", ".join([f"collision rates in {' or '.join(rates)}",
                      *(f"{m.name} in {shown_unit(m.name)}" for m in METRICS if not m.collision)])


def scaled(rows: pd.DataFrame) -> pd.DataFrame:
    """The metric columns of evaluation rows in the table's units (collision rates in percent)."""
    out = rows[METRIC_COLUMNS].astype(float)
    for m in METRICS:
        if m.scale != 1.0:
            out[m.name] *= m.scale
    return out


def metric(name: str) -> Metric:
    if name not in BY_NAME:
        raise SigmarlError(f"unknown metric {name!r}; choose from {', '.join(BY_NAME)}")
    return BY_NAME[name]
