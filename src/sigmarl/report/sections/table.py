"""Table I's sections of the report: what the columns are, the table in its formats, and the
statistics over scenarios."""

from __future__ import annotations

import pandas as pd

from sigmarl.report.draft import Draft, Section
from sigmarl.report.table.aggregate import cells, summarise
from sigmarl.report.table.composite import composite_scores
from sigmarl.report.table.header import study_markdown
from sigmarl.report.table.notes import table_notes
from sigmarl.report.table.paper import paper_values
from sigmarl.report.table.provenance import provenance_markdown
from sigmarl.report.table.scores import (
    aggregate_scores,
    composite_intervals,
    improvement,
    improvement_overall,
)
from sigmarl.report.table.tables import (
    build_table,
    matrix_markdown,
    statistics_markdown,
    to_csv_frame,
    to_markdown,
)

# in table.md, between what the columns are and the table itself
TABLE_HEADING = "## Table"


def study_section(d: Draft) -> None:
    """What the report compares (the study page)."""
    o = d.options
    if o.configs is None or o.defaults is None:
        return
    text = study_markdown(o.configs, d.rows, d.models, d.baseline, o.defaults, o.commit)
    if o.provenance is not None:  # "study.md" only: table.md's header stays what the rows alone give
        text += "\n" + "\n".join(provenance_markdown(o.provenance, d.models)) + "\n"
    d.write("study", "study.md", text)


def table_section(d: Draft) -> None:
    """Table I, its cells and composite scores with their intervals, and its matrix view."""
    o = d.options
    d.cells = cells(d.rows, d.models, trim=o.trim)
    d.summary = summarise(d.cells, trim=o.trim)
    composite = composite_scores(d.summary)
    intervals = composite_intervals(d.cells, composite)
    d.composite = composite.merge(intervals.drop(columns="CS"), on=["scenario", "model"], how="left")
    paper = paper_values(d.models) if o.compare_paper else None
    measured = set(paper.index.get_level_values("scenario")) if paper is not None else set()
    d.notes = table_notes(d.summary, d.composite, d.models, trim=o.trim, compare_paper=o.compare_paper, ci=o.ci,
                     paper_scenarios=measured) + list(o.extra_notes)
    d.table = build_table(d.summary, d.composite, d.models, paper, d.notes)
    d.markdown = to_markdown(d.table, ci=o.ci)
    if o.configs is not None and o.defaults is not None:  # the study page's header: what the columns are
        d.markdown = study_markdown(o.configs, d.rows, d.models, d.baseline, o.defaults, o.commit,
                                    title="What this table compares", with_commit=False) \
            + f"\n{TABLE_HEADING}\n\n" + d.markdown
    d.write("markdown", "table.md", d.markdown)
    d.write("csv", "table.csv", to_csv_frame(d.table))
    d.write("summary", "summary.csv", d.summary)
    d.write("composite", "composite_scores.csv", d.composite)
    d.write("matrix", "matrix.md", matrix_markdown(d.table, d.baseline or ("M0" if "M0" in d.models else None)))


def statistics_section(d: Draft) -> None:
    """Probability of improvement and aggregate scores over scenarios (a one-column report has
    nothing to compare)."""
    if len(d.models) < 2:
        return
    d.improvement = improvement(d.rows, d.models, trim=d.options.trim, reference=d.baseline)
    overall = improvement_overall(d.rows, d.models, trim=d.options.trim, reference=d.baseline)
    d.aggregates = aggregate_scores(d.cells, d.composite, d.models)
    both = pd.concat([d.improvement, overall], ignore_index=True) if len(overall) else d.improvement
    d.statistics = statistics_markdown(both, d.aggregates, trim=d.options.trim)
    d.write("improvement", "improvement.csv", d.improvement)
    d.write("improvement_overall", "improvement_overall.csv", overall)
    d.write("aggregates", "aggregate_scores.csv", d.aggregates)
    d.write("statistics", "statistics.md", d.statistics)


STUDY = Section("study", {
    "study.md": "what the report compares: per column its label, fingerprint, seeds and the training settings "
                "it changes against the baseline; the settings every column shares where they are not the "
                "defaults, a sweep's command line included; the training and evaluation budget; the commit "
                "the report was built at; what each column's runs were trained on (Python and library versions, "
                "CPU and GPU, threads, sigmarl commit and whether its tree was dirty, from each run folder's "
                "`provenance.json`; \"not recorded\" for runs from before it), with the columns whose library "
                "versions or hardware differ"}, study_section, when="when the columns' training configs are known (by `sigmarl report`, always)")

TABLE = Section("table", {
    "table.md": "the same header as `study.md`, less the commit, then Table I: each metric per scenario and "
                "model, the best per row in bold, the composite score, its notes",
    "table.csv": "Table I's cells (`source`: ours, or the paper's with `--compare-paper`)",
    "summary.csv": "per scenario, model and metric: estimate, 95% interval, spread, simulations and seeds",
    "composite_scores.csv": "the composite score per scenario and model, with its 95% interval",
    "matrix.md": "every metric of every model on every scenario, with intervals"}, table_section)

STATISTICS = Section("statistics", {
    "improvement.csv": "per scenario, the probability that the baseline has a lower CR_total than each other "
                       "column, with its interval",
    "improvement_overall.csv": "the same averaged over scenarios, whole seeds resampled",
    "aggregate_scores.csv": "each model's composite score over scenarios: mean and IQM, with intervals",
    "statistics.md": "the three files above as Markdown"}, statistics_section, when="with two columns or more")
