"""The CPM Lab benchmark's table: its metrics (`sigmarl.metrics.in_table(BENCHMARK)`) per
scenario and column, each a mean over seeds of the seed's mean over simulations (seeds weigh
equally, as in Table I; a simulation where a metric is undefined is left out of its mean)."""

from __future__ import annotations

import pandas as pd

from sigmarl.metrics import BENCHMARK, MIN_DISTANCE_M, NOT_MEASURED, in_table
from sigmarl.report.draft import Draft, Section


def benchmark_estimates(rows: pd.DataFrame, models: list[str]) -> pd.DataFrame:
    """scenario, model and each benchmark metric in the table's units (NaN: none measured)."""
    shown = in_table(BENCHMARK)
    rows = rows.assign(**{m.name: pd.to_numeric(rows[m.name], errors="coerce") * m.scale if m.name in rows
                          else float("nan") for m in shown})
    names = [m.name for m in shown]
    per_seed = rows.groupby(["scenario", "model", "seed"], sort=False)[names].mean()
    means = per_seed.groupby(level=["scenario", "model"], sort=False).mean()
    index = pd.MultiIndex.from_product([list(dict.fromkeys(rows["scenario"])), models], names=["scenario", "model"])
    return means.reindex(index).reset_index()


def benchmark_markdown(estimates: pd.DataFrame) -> str:
    shown = in_table(BENCHMARK)
    lines = ["# CPM Lab benchmark", "", "| Scenario | Model | " + " | ".join(m.heading for m in shown) + " |",
             "|---|---|" + "---:|" * len(shown)]
    for r in estimates.itertuples(index=False):
        cells = " | ".join(m.cell(getattr(r, m.name)) for m in shown)
        lines.append(f"| {r.scenario} | {r.model} | {cells} |")
    lines += ["", *(f"- {m.name}: {m.meaning}." for m in shown),
              f"- {NOT_MEASURED}: not measured in these rows (evaluated before the metric was declared; "
              "`sigmarl evaluate RUN --add-metrics` adds it), or undefined in every simulation (TS: no try "
              f"ended; per 100 m: its agents drove under {MIN_DISTANCE_M:g} m in all)."]
    return "\n".join(lines) + "\n"


def benchmark_section(d: Draft) -> None:
    names = [m.name for m in in_table(BENCHMARK)]
    if not any(n in d.rows.columns and d.rows[n].notna().any() for n in names):
        return  # no row measured them: the report of rows from before them is what it was
    estimates = benchmark_estimates(d.rows, d.models)
    d.write("benchmark_md", "benchmark.md", benchmark_markdown(estimates))
    d.write("benchmark_csv", "benchmark.csv", estimates)


BENCHMARK_TABLE = Section("benchmark", {
    "benchmark.md": "the CPM Lab benchmark's metrics per scenario and column (task success, collision events "
                    "and lane violation per 100 m driven), `–` where not measured, with their definitions",
    "benchmark.csv": "the same, in the table's units"}, benchmark_section,
    when="when some rows measured them (`sigmarl evaluate --add-metrics` adds them to older rows)")
