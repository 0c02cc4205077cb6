"""The study's metrics, one declaration each: every module that names, scales, ranks, checks,
tables or plots a metric reads it from here. A metric is a `Metric` record in `METRICS` plus its
computation in `sigmarl.evaluation` (which writes one column of that name per simulation); the
record says which tables show it (`tables`), how a cell is written (`unit`, `scale`, `digits`),
which way is better, and what a row may hold (`bounds`, `sum_of`, `undefined`). A metric declared
after row files were written (`required=False`) is "not measured" in them: they stay valid, a
report shows it as `–`, and `sigmarl evaluate --add-metrics` measures it into them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

from sigmarl.errors import SigmarlError

if TYPE_CHECKING:  # pandas is imported where rows are read
    import pandas as pd

# The metrics' names, for the code that needs one by name (the rows' columns are these strings).
CR_AA, CR_AL, CR_TOTAL, CD, AS = "CR_AA", "CR_AL", "CR_total", "CD", "AS"
TS, CAA_100M, CAL_100M, LV_100M = "TS", "CAA_100m", "CAL_100m", "LV_100m"
CS = "CS"  # the composite score's row of Table I (eq. 2): computed from the means, never a row column
HEADLINE = CR_TOTAL  # the study's headline metric: what verdicts decide on and figures rank by default

# The tables a metric can belong to (`Metric.tables`).
TABLE_I = "table1"  # the paper's Table I: one row per scenario and metric, a column per model
PER_SEED = "per_seed"  # the per-seed table (the headline first, then the others in this order)
FIGURES = "figures"  # the per-simulation distribution figure
BENCHMARK = "benchmark"  # the CPM Lab benchmark's table: task success and per-100 m counts
TABLE_DIGITS = 2  # decimals of every table cell, in the table's units (and of the metrics MLflow shows)

# The CPM Lab benchmark's counting rules (`sigmarl.evaluation.benchmark`; docs/concepts.md).
PER_M = 100.0  # the per-distance counts are per this many metres driven
MIN_DISTANCE_M = 10.0  # a simulation whose agents drove less has no per-100 m value (shown as –)
CONTACT_STEPS = 1  # consecutive steps in contact that start a collision event
CLEAR_STEPS = 5  # consecutive steps out of contact before the same agent's next event counts


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
    title: str = ""  # the words a table's note or a figure gives it (default: `meaning`)
    tables: tuple[str, ...] = (TABLE_I, PER_SEED)  # which tables show it (TABLE_I, PER_SEED, FIGURES, BENCHMARK)
    digits: int = TABLE_DIGITS  # decimals of a cell, in the table's units
    # False: declared after row files were written; rows without the column did not measure it
    required: bool = True
    bounds: tuple[float, float] = (0.0, math.inf)  # a row's value lies in [lo, hi] (rows' units)
    sum_of: tuple[str, ...] = ()  # a row's value is the sum of these metrics' values
    # why a simulation may have no value (the row holds NaN); empty: every row's value is finite
    undefined: str = ""

    @property
    def direction(self) -> int:
        """+1 where higher is better, -1 where lower is."""
        return -1 if self.lower_is_better else 1

    @property
    def heading(self) -> str:
        """The name with its unit as a table prints it: "CR_AA (%)", "CAA_100m (per 100 m)"."""
        return label(self.name)

    def cell(self, value: float | None) -> str:
        """A table's cell: the row value in the table's units at the declared decimals; `–` for
        none (not measured in these rows, or undefined in every simulation)."""
        if value is None or not math.isfinite(value):
            return NOT_MEASURED
        return f"{value:.{self.digits}f}"


NOT_MEASURED = "–"  # what a table shows where a metric has no value

METRICS: tuple[Metric, ...] = (
    Metric(CR_AA, "percent", 100.0, True, 0, True, bounds=(0.0, 1.0),
           meaning="steps with at least one agent-agent collision"),
    Metric(CR_AL, "percent", 100.0, True, 0, True, bounds=(0.0, 1.0),
           meaning="steps with at least one agent-lane (boundary) collision"),
    Metric(CR_TOTAL, "percent", 100.0, True, -1, True, 0.1,
           "composite score undefined: no model collided (mean CR_total is 0)",
           "CR_AA + CR_AL", tables=(TABLE_I, PER_SEED, FIGURES), bounds=(0.0, 1.0), sum_of=(CR_AA, CR_AL)),
    Metric(CD, "cm", 1.0, True, -1, False, 0.1,
           "composite score undefined: mean center-line deviation CD is 0",
           "mean distance of the center of gravity to the own route's center line",
           tables=(TABLE_I, PER_SEED, FIGURES)),
    Metric(AS, "m/s", 1.0, False, 1, False, 0.01,
           "composite score undefined: no model moved (mean AS is 0)",
           "mean speed over all agent-steps", tables=(TABLE_I, PER_SEED, FIGURES)),
    # The CPM Lab benchmark's metrics (docs/concepts.md, "The CPM Lab benchmark's metrics").
    Metric(TS, "percent", 100.0, False, 0, False, 1.0,
           meaning="tries that reached their goal: the route's exit, or one lap of a looping route",
           title="task success", tables=(BENCHMARK,), required=False, bounds=(0.0, 1.0),
           undefined="no try ended (no goal reached, no collision)"),
    Metric(CAA_100M, "per 100 m", 1.0, True, 0, False, 0.1,
           meaning="agent-agent collision events per 100 m driven (an agent's contact counts once "
                   f"until it has been clear {CLEAR_STEPS} steps)",
           title="agent-agent collisions per 100 m", tables=(BENCHMARK,), required=False,
           undefined=f"its agents drove under {MIN_DISTANCE_M:g} m"),
    Metric(CAL_100M, "per 100 m", 1.0, True, 0, False, 0.1,
           meaning="agent-lane collision events per 100 m driven (an agent's contact counts once "
                   f"until it has been clear {CLEAR_STEPS} steps)",
           title="agent-lane collisions per 100 m", tables=(BENCHMARK,), required=False,
           undefined=f"its agents drove under {MIN_DISTANCE_M:g} m"),
    Metric(LV_100M, "m per 100 m", 1.0, True, 0, False, 0.1,
           meaning="metres driven while touching the own lane's boundary, per 100 m driven",
           title="lane violation per 100 m", tables=(BENCHMARK,), required=False,
           undefined=f"its agents drove under {MIN_DISTANCE_M:g} m"),
)
BY_NAME = {m.name: m for m in METRICS}


def in_table(table: str) -> tuple[Metric, ...]:
    """The metrics `table` shows, in its order (declaration order; the per-seed table's
    headline first)."""
    found = tuple(m for m in METRICS if table in m.tables)
    if table == PER_SEED:
        found = tuple(sorted(found, key=lambda m: m.name != HEADLINE))
    return found


def names(table: str) -> list[str]:
    """The names of the metrics `table` shows, in its order."""
    return [m.name for m in in_table(table)]


MEASURED = [m.name for m in METRICS]  # every metric column `sigmarl evaluate` writes, in order
REQUIRED = [m.name for m in METRICS if m.required]  # the columns every row file holds
ADDED = [m.name for m in METRICS if not m.required]  # the columns older row files may lack
METRIC_COLUMNS = names(TABLE_I)  # Table I's metric columns, in table order
COLLISION_COLUMNS = tuple(m.name for m in METRICS if m.collision)
COMPOSITE = {m.name: float(m.composite) for m in METRICS if m.composite}
# the table's unit of each row; the composite score's own row: unitless, higher is better
UNITS = {**{m.name: m.unit for m in METRICS}, CS: "1"}
# the evaluation rows' own units (what `scale` turns into the table's)
ROW_UNITS = {m.name: "fraction of steps" if m.unit == "percent" else m.unit for m in in_table(TABLE_I)}
LOWER_IS_BETTER = frozenset(m.name for m in METRICS if m.lower_is_better)


def measured(rows: pd.DataFrame) -> list[str]:
    """The declared metrics `rows` hold a column of (the others were not measured in them)."""
    return [name for name in MEASURED if name in rows.columns]


def shown_unit(name: str) -> str:
    """A table row's unit as printed: "%" for percent, nothing for the unitless score."""
    unit = UNITS.get(name, "")
    return {"percent": "%", "1": ""}.get(unit, unit)


def label(name: str) -> str:
    """A row or column name with its unit as printed: "CR_AA (%)", "CD (cm)", "CS"."""
    unit = shown_unit(name)
    return f"{name} ({unit})" if unit else name


def units_text(of_steps: bool = False) -> str:
    """Table I's units in words: "collision rates in %, CD in cm, AS in m/s"."""
    shown = in_table(TABLE_I)
    rates = dict.fromkeys(shown_unit(m.name) + (" of steps" if of_steps else "") for m in shown if m.collision)
    return ", ".join([f"collision rates in {' or '.join(rates)}",
                      *(f"{m.name} in {shown_unit(m.name)}" for m in shown if not m.collision)])


def scaled(rows: pd.DataFrame, columns: list[str] | None = None) -> pd.DataFrame:
    """Metric columns of evaluation rows (default: Table I's) in the table's units (rates in percent)."""
    columns = METRIC_COLUMNS if columns is None else columns
    out = rows[columns].astype(float)
    for name in columns:
        if BY_NAME[name].scale != 1.0:
            out[name] *= BY_NAME[name].scale
    return out


def metric(name: str) -> Metric:
    if name not in BY_NAME:
        raise SigmarlError(f"unknown metric {name!r}; choose from {', '.join(BY_NAME)}")
    return BY_NAME[name]
