"""The paper's Table I layout and how the report writes its numbers.

A `ResultTable` holds the numbers (row groups per scenario, one column per model);
`to_markdown`, `to_latex` and `to_csv_frame` render it, `table_notes` says what its numbers
are. The best value per row is bold: lowest where a metric is lower-is-better
(`metrics.LOWER_IS_BETTER`), highest otherwise and for the composite score. Values are compared
as printed, so models that tie on screen are all bold, and a row where every model ties has no
best. The paper's own Table I and Fig. 5 ship as reference data (CD already in real centimetres).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from importlib import resources

import pandas as pd

from sigmarl.ablation import MODELS
from sigmarl.metrics import (
    BENCHMARK,
    COLLISION_COLUMNS,
    CS,
    HEADLINE,
    LOWER_IS_BETTER,
    METRIC_COLUMNS,
    MIN_DISTANCE_M,
    NOT_MEASURED,
    TABLE_DIGITS,
    UNITS,
    in_table,
    units_text,
)
from sigmarl.metrics import label as metric_label

ROW_METRICS = [*METRIC_COLUMNS, CS]
DIGITS = TABLE_DIGITS
MISSING = "–"
PAPER_TABLE = "paper_table_1.csv"
PAPER_CURVES = "paper_training_curves.csv"  # the paper's Fig. 5, one seed per model


def p_text(p: float) -> str:
    """A p-value to three decimals, "<0.001" below that, "–" where there is none."""
    if not math.isfinite(p):
        return MISSING
    return "<0.001" if p < 0.001 else f"{p:.3f}"


def signed(x: float, digits: int = 3) -> str:
    """x with its sign, to `digits` decimals ("–" where it is not finite)."""
    return f"{x:+.{digits}f}" if pd.notna(x) and math.isfinite(x) else MISSING


def seeds_text(n) -> str:
    """A seed count, "–" where there is none."""
    return MISSING if pd.isna(n) else str(int(n))


def interval_signed(x: float, lo: float, hi: float, digits: int = 3) -> str:
    """"+x [+lo, +hi]", each signed (`signed`)."""
    return f"{signed(x, digits)} [{signed(lo, digits)}, {signed(hi, digits)}]"


def markdown_row(cells) -> str:
    return "| " + " | ".join(map(str, cells)) + " |"


def markdown_table(frame: pd.DataFrame, columns: dict[str, str | Callable[[dict], str]], align: str = "") -> list[str]:
    """`frame` as the lines of a Markdown table: per `columns` item its heading and the frame's
    column shown as it is, or a function of the row (a dict) that writes the cell; `align`, one
    letter a column, "r" right-aligned (the rest left)."""
    rule = "".join("---:|" if a == "r" else "---|" for a in align.ljust(len(columns), "l"))
    cells = [[f(r) if callable(f) else r[f] for f in columns.values()] for r in frame.to_dict("records")]
    return [markdown_row(columns), "|" + rule, *map(markdown_row, cells)]


def _data(name: str) -> pd.DataFrame:
    with resources.files("sigmarl").joinpath("data").joinpath(name).open("r", encoding="utf-8") as f:
        return pd.read_csv(f, comment="#")


def paper_table() -> pd.DataFrame:
    """The paper's numbers: index (scenario, metric), a `unit` column, then M0..M5.

    Collision rates in percent (trimmed as the paper did), CD in cm, AS in m/s, CS unitless.
    """
    return _data(PAPER_TABLE).set_index(["scenario", "metric"])


def paper_values(models: list[str] | None = None) -> pd.DataFrame:
    """Only the numbers, index (scenario, metric), columns `models` (NaN for unknown names)."""
    table = paper_table().drop(columns=["unit", "struck_out"]).astype(float)
    return table if models is None else table.reindex(columns=models)


def struck_out() -> set[tuple[str, str, str]]:
    """(scenario, metric, model) of every value Table I strikes out (the csv's `struck_out`
    column): shown, never a claim."""
    return {(scenario, metric, model) for (scenario, metric), names in paper_table()["struck_out"].fillna("").items()
            for model in str(names).split(";") if model}


def paper_curves() -> pd.DataFrame:
    """The paper's training curves (Fig. 5): columns model, iteration, reward."""
    wide = _data(PAPER_CURVES)
    return wide.melt(id_vars="iteration", var_name="model", value_name="reward")[["model", "iteration", "reward"]]


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


def build_table(summary: pd.DataFrame, composite: pd.DataFrame, models: list[str],
                paper: pd.DataFrame | None = None, notes: list[str] | None = None) -> ResultTable:
    """Arrange an `aggregate` summary and `composite_scores` into the paper's layout.

    `composite` may carry ci_low/ci_high columns (`scores.composite_intervals`).
    """
    scenarios = list(dict.fromkeys(summary["scenario"]))
    index = pd.MultiIndex.from_product([scenarios, ROW_METRICS], names=["scenario", "metric"])
    cs = composite.assign(metric=CS, mean=composite[CS])
    for bound in ("ci_low", "ci_high"):
        if bound not in cs.columns:
            cs[bound] = math.nan
    long = pd.concat([summary, cs], ignore_index=True)

    def wide(column: str) -> pd.DataFrame:
        w = long.pivot_table(index=["scenario", "metric"], columns="model", values=column, dropna=False)
        w = w.reindex(index=index, columns=models).astype(float)
        w.columns.name = None
        return w

    if paper is not None:
        # Only scenarios the paper measured: a procedural map has no paper numbers, even
        # where its name resembles one of Table I's.
        measured = set(paper.index.get_level_values("scenario"))
        paper = paper.reindex(index=index[index.get_level_values("scenario").isin(measured)],
                              columns=models).astype(float)
    return ResultTable(wide("mean"), wide("ci_low"), wide("ci_high"), paper, list(notes or []))


def best_mask(values: pd.DataFrame, digits: int = DIGITS) -> pd.DataFrame:
    """True where a cell holds its row's best value as printed with `digits` decimals."""
    mask = pd.DataFrame(False, index=values.index, columns=values.columns)
    for key, row in values.round(digits).iterrows():
        finite = row.dropna()
        if finite.empty or (finite.nunique() == 1 and len(finite) == len(row)):
            continue  # nothing to compare, or every model ties
        mask.loc[key] = row == (finite.min() if key[-1] in LOWER_IS_BETTER else finite.max())
    return mask


def _number(x: float, digits: int) -> str:
    if x is None or not math.isfinite(x):
        return MISSING
    s = f"{x:.{digits}f}"
    return "0." + "0" * digits if s == "-0." + "0" * digits else s  # no "-0.00"


def interval_text(value: float, lo: float, hi: float, digits: int = DIGITS) -> str:
    """"value [lo, hi]", or the value alone where the interval is not finite."""
    text = _number(value, digits)
    if math.isfinite(lo) and math.isfinite(hi):
        text += f" [{_number(lo, digits)}, {_number(hi, digits)}]"
    return text


def _cells(table: ResultTable, *, ci: bool, digits: int, bold: tuple[str, str]) -> pd.DataFrame:
    """Cell strings: value, optional [low, high] interval, bold when best, optional (paper)."""
    mask = best_mask(table.values, digits)
    cells = pd.DataFrame("", index=table.values.index, columns=table.values.columns)
    for key in table.values.index:
        for model in table.models:
            v, lo, hi = (t.at[key, model] for t in (table.values, table.ci_low, table.ci_high))
            text = interval_text(v, lo, hi, digits) if ci else _number(v, digits)
            if mask.at[key, model]:
                text = f"{bold[0]}{text}{bold[1]}"
            if table.paper is not None and key in table.paper.index:
                text += f" ({_number(table.paper.at[key, model], digits)})"
            cells.at[key, model] = text
    return cells


def to_markdown(table: ResultTable, *, ci: bool = False, digits: int = DIGITS) -> str:
    """A GitHub-flavoured Markdown table, scenario named on its group's first row."""
    cells = _cells(table, ci=ci, digits=digits, bold=("**", "**"))
    lines = ["| Scenario | Metric | " + " | ".join(table.models) + " |", "|---|---|" + "---:|" * len(table.models)]
    for scenario, metric in cells.index:
        row = [scenario if metric == ROW_METRICS[0] else "", metric_label(metric), *cells.loc[(scenario, metric)]]
        lines.append("| " + " | ".join(row) + " |")
    if table.notes:
        lines += ["", *table.notes]
    return "\n".join(lines) + "\n"


_LATEX_SPECIAL = {"\\": r"\textbackslash{}", "&": r"\&", "%": r"\%", "$": r"\$", "#": r"\#", "_": r"\_",
                  "{": r"\{", "}": r"\}", "~": r"\textasciitilde{}", "^": r"\textasciicircum{}"}


def latex_escape(text: str) -> str:
    return "".join(_LATEX_SPECIAL.get(ch, ch) for ch in str(text))


def to_latex(table: ResultTable, *, ci: bool = False, digits: int = DIGITS,
             caption: str = "Evaluation of the models in the test scenarios (best per row in bold).",
             label: str = "tab:sigmarl-results") -> str:
    """A booktabs `table` float: one header line per scenario, `\\midrule` between groups.

    Needs only `\\usepackage{booktabs}`; numbers use a real minus sign.
    """
    cells = _cells(table, ci=ci, digits=digits, bold=(r"\textbf{", "}"))
    cells = cells.map(lambda s: s.replace("-", "$-$").replace(MISSING, "--"))
    n = len(table.models)
    out = ["% requires \\usepackage{booktabs}", "\\begin{table}[t]", "\\centering",
           f"\\caption{{{latex_escape(caption)}}}", f"\\label{{{label}}}", "\\begin{tabular}{l" + "r" * n + "}",
           "\\toprule", "Metric & " + " & ".join(latex_escape(m) for m in table.models) + " \\\\"]
    for scenario in table.scenarios:
        out += ["\\midrule", f"\\multicolumn{{{n + 1}}}{{l}}{{\\textit{{{latex_escape(scenario)}}}}} \\\\"]
        out += [" & ".join([latex_escape(metric_label(metric)), *cells.loc[(scenario, metric)]]) + " \\\\"
                for metric in ROW_METRICS]
    out += ["\\bottomrule", "\\end{tabular}"]
    out += [f"\\par\\smallskip\\footnotesize {latex_escape(note)}" for note in table.notes]
    out.append("\\end{table}")
    return "\n".join(out) + "\n"


def to_csv_frame(table: ResultTable) -> pd.DataFrame:
    """Plain numbers in the layout of the paper's reference CSV, plus a `source` column.

    Columns: scenario, metric, unit, source ("ours", or "paper" when compared), models.
    """
    parts = []
    for source, values in [("ours", table.values)] + ([("paper", table.paper)] if table.paper is not None else []):
        part = values.reset_index()
        part.insert(2, "unit", part["metric"].map(UNITS))
        part.insert(3, "source", source)
        parts.append(part)
    frame = pd.concat(parts, ignore_index=True)
    order = {key: i for i, key in enumerate(table.values.index)}
    frame["_row"] = [order[(s, m)] for s, m in zip(frame["scenario"], frame["metric"], strict=True)]
    return frame.sort_values(["_row", "source"], kind="stable").drop(columns="_row").reset_index(drop=True)


def matrix_markdown(table: ResultTable, baseline: str | None = None, metric: str = HEADLINE,
                    digits: int = DIGITS) -> str:
    """A study over many scenarios at a glance: `metric` for every model (columns) on every
    scenario (rows), with intervals, best per row in bold; then the baseline's other metrics
    (the collision rates split into their kinds, its deviation and speed), to say how a
    scenario breaks it."""
    values, lo, hi = (t.xs(metric, level="metric") for t in (table.values, table.ci_low, table.ci_high))
    best = best_mask(table.values).xs(metric, level="metric")
    lines = [f"{metric_label(metric)}, mean over seeds [95% interval over seeds and simulations]; best per "
             "scenario in bold:", "", "| Scenario | " + " | ".join(table.models) + " |",
             "|---|" + "---:|" * len(table.models)]
    for scenario in table.scenarios:
        cells = [interval_text(values.loc[scenario, m], lo.loc[scenario, m], hi.loc[scenario, m], digits)
                 for m in table.models]
        cells = [f"**{text}**" if best.loc[scenario, m] else text for m, text in zip(table.models, cells, strict=True)]
        lines.append(f"| {scenario} | " + " | ".join(cells) + " |")
    if baseline in table.models:
        parts = [m for m in METRIC_COLUMNS if m != metric]
        lines += ["", f"{baseline}: how it collides, how it drives:", "",
                  "| Scenario | " + " | ".join(metric_label(k) for k in parts) + " |", "|---|" + "---:|" * len(parts)]
        for scenario in table.scenarios:
            cells = [interval_text(*(t.loc[(scenario, k), baseline] for t in (table.values, table.ci_low,
                                                                              table.ci_high)), digits) for k in parts]
            lines.append(f"| {scenario} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def table_notes(summary: pd.DataFrame, composite: pd.DataFrame, models: list[str], *, trim: bool,
                compare_paper: bool, ci: bool, paper_scenarios: set[str] = frozenset()) -> list[str]:
    """The lines under the table that say what its numbers are: seeds and simulations per cell,
    trimming, missing rows, and what the paper's numbers in parentheses can be compared with."""
    whole = summary[summary["metric"] == next(m for m in METRIC_COLUMNS if m not in COLLISION_COLUMNS)]
    sims, seeds = _span(whole["n"]), _span(whole["n_seeds"])  # of a metric never trimmed
    notes = [(f"Mean over {seeds} seeds of each seed's mean over its simulations ({sims} simulations per cell)"
              if whole["n_seeds"].max() > 1 else f"Mean over {sims} simulations per cell")
             + (" [95% bootstrap interval over seeds and simulations]" if ci else "")
             + f"; {units_text(of_steps=True)}; best per row in bold."]
    if trim:
        notes.append("Collision rates without each evaluation's best and worst simulation.")
    by_note: dict[str, list[str]] = {}  # a note once, naming its scenarios unless it holds for all
    groups = list(composite.groupby("scenario", sort=False))
    for scenario, g in groups:
        if absent := [m for m in models if m not in set(g["model"])]:  # the scores then compare fewer models
            by_note.setdefault(f"no evaluation rows for {', '.join(absent)}", []).append(scenario)
        for note in dict.fromkeys(g["note"]):
            if note:
                by_note.setdefault(note, []).append(scenario)
    for note, where in by_note.items():
        notes.append(f"{'All scenarios' if len(where) == len(groups) > 1 else ', '.join(where)}: {note}.")
    if compare_paper:
        notes.append("In parentheses: the paper's Table I (CD converted to real cm).")
        if others := [s for s in dict.fromkeys(summary["scenario"]) if s not in paper_scenarios]:
            notes.append(f"{', '.join(others)}: not in the paper's Table I, no paper numbers.")
        if not trim:
            notes.append("The paper dropped the best and worst simulation from its collision rates; "
                         "ours are not trimmed (use trim for a like-for-like comparison).")
        if models != list(MODELS):
            notes.append(f"The paper's composite scores compare M0..M5; ours compare {', '.join(models)}, "
                         f"so the two {CS} rows are not comparable.")
    return notes


def _span(counts: pd.Series) -> str:
    return f"{counts.min()}" if counts.min() == counts.max() else f"{counts.min()}–{counts.max()}"


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
    """The CPM Lab benchmark's table: its metrics (`metrics.in_table(BENCHMARK)`) per scenario and
    column, each a mean over seeds of the seed's mean over simulations (seeds weigh equally, as in
    Table I; a simulation where a metric is undefined is left out of its mean)."""
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
