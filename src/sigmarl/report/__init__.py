"""The study's report: evaluation rows in, Table I, comparisons, seeds, figures and exports out.

Grouped by what a reader sees (`table`, `compare`, `seeds`, `exports`, over the `inputs` it is
built from); `build.SECTIONS` lists the sections that write the files (`draft.Section`).
Figures live in `sigmarl.report.exports.figures` (imported on use: matplotlib is slow to load).
"""

from sigmarl.report.build import BuildOptions, Report, build_report
from sigmarl.report.table.aggregate import aggregate, trim_collisions
from sigmarl.report.table.composite import CompositeScore, composite_score, composite_scores
from sigmarl.report.table.paper import paper_table, paper_values
from sigmarl.report.table.tables import (
    ResultTable,
    best_mask,
    build_table,
    to_csv_frame,
    to_latex,
    to_markdown,
)

__all__ = [
    "BuildOptions",
    "CompositeScore",
    "Report",
    "ResultTable",
    "aggregate",
    "best_mask",
    "build_report",
    "build_table",
    "composite_score",
    "composite_scores",
    "paper_table",
    "paper_values",
    "to_csv_frame",
    "to_latex",
    "to_markdown",
    "trim_collisions",
]
