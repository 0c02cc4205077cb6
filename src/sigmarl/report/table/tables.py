"""The paper's Table I layout: row groups per scenario, one column per model.

A `ResultTable` holds the numbers; `to_markdown`, `to_latex` and `to_csv_frame` render
it. The best value per row is bold: lowest for collision rates and CD, highest for AS
and the composite score. Values are compared as printed, so models that tie on screen
are all bold, and a row where every model ties has no best.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import pandas as pd

from sigmarl.metrics import LOWER_IS_BETTER, METRIC_COLUMNS, TABLE_DIGITS, UNITS, label

ROW_METRICS = [*METRIC_COLUMNS, "CS"]
DIGITS = TABLE_DIGITS
# how the baseline collides and drives, under each matrix
BASELINE_PARTS = ("CR_AA", "CR_AL", "CD", "AS")
MISSING = "–"


@dataclass
class ResultTable:
    """Estimates (and interval bounds, optional paper numbers) indexed by (scenario, metric)."""

    values: pd.DataFrame
    ci_low: pd.DataFrame
    ci_high: pd.DataFrame
    paper: pd.DataFrame | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def models(self) -> list[str]:
        return list(self.values.columns)

    @property
    def scenarios(self) -> list[str]:
        return list(dict.fromkeys(self.values.index.get_level_values("scenario")))


def build_table(
    summary: pd.DataFrame,
    composite: pd.DataFrame,
    models: list[str],
    paper: pd.DataFrame | None = None,
    notes: list[str] | None = None,
) -> ResultTable:
    """Arrange an `aggregate` summary and `composite_scores` into the paper's layout.

    `composite` may carry ci_low/ci_high columns (`scores.composite_intervals`).
    """
    scenarios = list(dict.fromkeys(summary["scenario"]))
    index = pd.MultiIndex.from_product([scenarios, ROW_METRICS], names=["scenario", "metric"])
    cs = composite.assign(metric="CS", mean=composite["CS"])
    for bound in ("ci_low", "ci_high"):
        if bound not in cs.columns:
            cs[bound] = math.nan
    long = pd.concat([summary, cs], ignore_index=True)

    def wide(column: str) -> pd.DataFrame:
        w = long.pivot_table(
            index=["scenario", "metric"], columns="model", values=column, dropna=False
        )
        w = w.reindex(index=index, columns=models).astype(float)
        w.columns.name = None
        return w

    if paper is not None:
        # Only scenarios the paper measured: a procedural map has no paper numbers, even
        # where its name resembles one of Table I's.
        measured = set(paper.index.get_level_values("scenario"))
        rows = index[index.get_level_values("scenario").isin(measured)]
        paper = paper.reindex(index=rows, columns=models).astype(float)
    return ResultTable(wide("mean"), wide("ci_low"), wide("ci_high"), paper, list(notes or []))


def best_mask(values: pd.DataFrame, digits: int = DIGITS) -> pd.DataFrame:
    """True where a cell holds its row's best value as printed with `digits` decimals."""
    shown = values.round(digits)
    mask = pd.DataFrame(False, index=values.index, columns=values.columns)
    for key, row in shown.iterrows():
        finite = row.dropna()
        if finite.empty or (finite.nunique() == 1 and len(finite) == len(row)):
            continue  # nothing to compare, or every model ties
        best = finite.min() if key[-1] in LOWER_IS_BETTER else finite.max()
        mask.loc[key] = row == best
    return mask


def _number(x: float, digits: int) -> str:
    if x is None or not math.isfinite(x):
        return MISSING
    s = f"{x:.{digits}f}"
    return "0." + "0" * digits if s == "-0." + "0" * digits else s  # no "-0.00"


def _cells(
    table: ResultTable, *, ci: bool, digits: int, bold: tuple[str, str]
) -> pd.DataFrame:
    """Cell strings: value, optional [low, high] interval, bold when best, optional (paper)."""
    mask = best_mask(table.values, digits)
    cells = pd.DataFrame("", index=table.values.index, columns=table.values.columns)
    for key in table.values.index:
        for model in table.models:
            v = table.values.at[key, model]
            text = _number(v, digits)
            lo, hi = table.ci_low.at[key, model], table.ci_high.at[key, model]
            if ci and math.isfinite(lo) and math.isfinite(hi):
                text += f" [{_number(lo, digits)}, {_number(hi, digits)}]"
            if mask.at[key, model]:
                text = f"{bold[0]}{text}{bold[1]}"
            if table.paper is not None and key in table.paper.index:
                text += f" ({_number(table.paper.at[key, model], digits)})"
            cells.at[key, model] = text
    return cells


def row_label(metric: str) -> str:
    """Row name with its unit as printed: "CR_AA (%)", "CD (cm)", "CS"."""
    return label(metric)


def to_markdown(table: ResultTable, *, ci: bool = False, digits: int = DIGITS) -> str:
    """A GitHub-flavoured Markdown table, scenario named on its group's first row."""
    cells = _cells(table, ci=ci, digits=digits, bold=("**", "**"))
    lines = [
        "| Scenario | Metric | " + " | ".join(table.models) + " |",
        "|---|---|" + "---:|" * len(table.models),
    ]
    for scenario, metric in cells.index:
        first = metric == ROW_METRICS[0]
        row = [scenario if first else "", row_label(metric), *cells.loc[(scenario, metric)]]
        lines.append("| " + " | ".join(row) + " |")
    if table.notes:
        lines += ["", *table.notes]
    return "\n".join(lines) + "\n"


_LATEX_SPECIAL = {
    "\\": r"\textbackslash{}", "&": r"\&", "%": r"\%", "$": r"\$", "#": r"\#",
    "_": r"\_", "{": r"\{", "}": r"\}", "~": r"\textasciitilde{}", "^": r"\textasciicircum{}",
}  # fmt: skip


def latex_escape(text: str) -> str:
    return "".join(_LATEX_SPECIAL.get(ch, ch) for ch in str(text))


def to_latex(
    table: ResultTable,
    *,
    ci: bool = False,
    digits: int = DIGITS,
    caption: str = "Evaluation of the models in the test scenarios (best per row in bold).",
    label: str = "tab:sigmarl-results",
) -> str:
    """A booktabs `table` float: one header line per scenario, `\\midrule` between groups.

    Needs only `\\usepackage{booktabs}`; numbers use a real minus sign.
    """
    cells = _cells(table, ci=ci, digits=digits, bold=(r"\textbf{", "}"))
    cells = cells.map(lambda s: s.replace("-", "$-$").replace(MISSING, "--"))
    n = len(table.models)
    out = [
        "% requires \\usepackage{booktabs}",
        "\\begin{table}[t]",
        "\\centering",
        f"\\caption{{{latex_escape(caption)}}}",
        f"\\label{{{label}}}",
        "\\begin{tabular}{l" + "r" * n + "}",
        "\\toprule",
        "Metric & " + " & ".join(latex_escape(m) for m in table.models) + " \\\\",
    ]
    for scenario in table.scenarios:
        out += [
            "\\midrule",
            f"\\multicolumn{{{n + 1}}}{{l}}{{\\textit{{{latex_escape(scenario)}}}}} \\\\",
        ]
        for metric in ROW_METRICS:
            row = [latex_escape(row_label(metric)), *cells.loc[(scenario, metric)]]
            out.append(" & ".join(row) + " \\\\")
    out += ["\\bottomrule", "\\end{tabular}"]
    out += [f"\\par\\smallskip\\footnotesize {latex_escape(note)}" for note in table.notes]
    out.append("\\end{table}")
    return "\n".join(out) + "\n"


def to_csv_frame(table: ResultTable) -> pd.DataFrame:
    """Plain numbers in the layout of the paper's reference CSV, plus a `source` column.

    Columns: scenario, metric, unit, source ("ours", or "paper" when compared), models.
    """
    parts = []
    sources = [("ours", table.values)] + (
        [("paper", table.paper)] if table.paper is not None else []
    )
    for source, values in sources:
        part = values.reset_index()
        part.insert(2, "unit", part["metric"].map(UNITS))
        part.insert(3, "source", source)
        parts.append(part)
    frame = pd.concat(parts, ignore_index=True)
    order = {key: i for i, key in enumerate(table.values.index)}
    frame["_row"] = [order[(s, m)] for s, m in zip(frame["scenario"], frame["metric"], strict=True)]
    return (
        frame.sort_values(["_row", "source"], kind="stable")
        .drop(columns="_row")
        .reset_index(drop=True)
    )


def _interval(value: float, lo: float, hi: float, digits: int) -> str:
    text = _number(value, digits)
    if math.isfinite(lo) and math.isfinite(hi):
        text += f" [{_number(lo, digits)}, {_number(hi, digits)}]"
    return text


def statistics_markdown(
    improvement: pd.DataFrame, aggregates: pd.DataFrame, *, trim: bool = False, digits: int = DIGITS
) -> str:
    """Markdown of `scores.improvement` (scenarios x models) and `scores.aggregate_scores`."""
    lines: list[str] = []
    if len(improvement):
        reference = improvement["reference"].iloc[0]
        others = list(dict.fromkeys(improvement["model"]))
        cells = improvement.set_index(["scenario", "model"])
        lines += [
            f"Probability that {reference} has a lower CR_total than each model "
            "[95% bootstrap interval]" + (" (collision rates trimmed)" if trim else "") + ":",
            "",
            "| Scenario | " + " | ".join(f"{reference} vs {m}" for m in others) + " |",
            "|---|" + "---:|" * len(others),
        ]
        for scenario in dict.fromkeys(improvement["scenario"]):
            row = []
            for m in others:
                if (scenario, m) in cells.index:
                    c = cells.loc[(scenario, m)]
                    row.append(_interval(c["probability"], c["ci_low"], c["ci_high"], digits))
                else:
                    row.append(MISSING)
            lines.append(f"| {scenario} | " + " | ".join(row) + " |")
        lines += [
            "",
            "A simulation of a random seed of each model is compared; ties count half; "
            "0.5 means no difference, 1 that the reference always had fewer collisions. "
            "Per scenario, the interval resamples each model's seeds and simulations; the mean "
            "over scenarios resamples whole seeds (all scenarios of a seed together) with the "
            "percentile level widened for the number of seeds.",
            "",
        ]
    if len(aggregates):
        stats = list(dict.fromkeys(aggregates["statistic"]))
        cells = aggregates.set_index(["model", "statistic"])
        lines += [
            "Composite score aggregated over scenarios [95% interval, whole seeds resampled]:",
            "",
            "| Model | " + " | ".join(stats) + " | scenarios | runs |",
            "|---|" + "---:|" * (len(stats) + 2),
        ]
        for model in dict.fromkeys(aggregates["model"]):
            row = [_interval(cells.at[(model, s), "value"], cells.at[(model, s), "ci_low"],
                             cells.at[(model, s), "ci_high"], digits) for s in stats]
            first = cells.loc[(model, stats[0])]
            lines.append(f"| {model} | " + " | ".join(row) + f" | {int(first['n_scenarios'])} | {int(first['n_runs'])} |")
        lines += [
            "",
            "Per-seed composite scores with each scenario's normalisers fixed (their mean over "
            "seeds is the table's CS); mean: over scenarios; IQM: interquartile mean of all "
            "(scenario, seed) scores.",
        ]
    return "\n".join(lines) + "\n" if lines else ""


def matrix_markdown(table: ResultTable, baseline: str | None = None, metric: str = "CR_total",
                    digits: int = DIGITS) -> str:
    """A study over many scenarios at a glance: `metric` for every model (columns) on every
    scenario (rows), with intervals, best per row in bold; then the baseline's collision rates
    split into agent-agent and agent-lane, with its deviation and speed, to say how a scenario
    breaks it."""
    values = table.values.xs(metric, level="metric")
    lo, hi = (t.xs(metric, level="metric") for t in (table.ci_low, table.ci_high))
    best = best_mask(table.values).xs(metric, level="metric")
    lines = [f"{label(metric)}, mean over seeds [95% interval over seeds and simulations]; best per "
             "scenario in bold:", "", "| Scenario | " + " | ".join(table.models) + " |",
             "|---|" + "---:|" * len(table.models)]
    for scenario in table.scenarios:
        cells = []
        for m in table.models:
            text = _interval(values.loc[scenario, m], lo.loc[scenario, m], hi.loc[scenario, m], digits)
            cells.append(f"**{text}**" if best.loc[scenario, m] else text)
        lines.append(f"| {scenario} | " + " | ".join(cells) + " |")
    if baseline in table.models:
        lines += ["", f"{baseline}: how it collides, how it drives:", "",
                  "| Scenario | " + " | ".join(label(k) for k in BASELINE_PARTS) + " |", "|---|---:|---:|---:|---:|"]
        for scenario in table.scenarios:
            cells = [_interval(table.values.loc[(scenario, k), baseline], table.ci_low.loc[(scenario, k), baseline],
                               table.ci_high.loc[(scenario, k), baseline], digits)
                     for k in BASELINE_PARTS]
            lines.append(f"| {scenario} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"
