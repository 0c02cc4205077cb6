"""`build_report`: evaluation rows in, the report's files out, one section after another.

`SECTIONS` is the registry: each `Section` (`report.draft`) lives beside what it draws
(`table/`, `seeds/`, `compare/`, `exports/`), and a new one is its module and one line here.
A section reads what the ones before it left on the draft, so the order is the order they
depend on: the table before the statistics and the findings, the verdicts before the
findings, the training summary before the curve verdicts.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pandas as pd

from sigmarl.report.draft import BuildOptions, Draft, Section, check_sections
from sigmarl.report.sections.benchmark import BENCHMARK_TABLE
from sigmarl.report.sections.compare import CURVE_VERDICTS, FINDINGS, REPLICATION, VERDICTS
from sigmarl.report.sections.exports import FIGURES, LATEX, MARL_EVAL
from sigmarl.report.sections.paper_policies import PAPER_POLICIES
from sigmarl.report.sections.seeds import SEEDS, TRAINING
from sigmarl.report.sections.table import STATISTICS, STUDY, TABLE
from sigmarl.report.table.aggregate import model_order, validate_rows

# What build_report returns: the draft its sections finished (the Markdown to print, the frames
# behind it, the files written).
Report = Draft


def build_report(rows: pd.DataFrame, options: BuildOptions, curves: pd.DataFrame | None = None,
                 sections: list[Section] | None = None) -> Report:
    """Aggregate evaluation rows into the paper's Table I and the report's other files in
    `options.out_dir`, one section after another (`sections`, default `SECTIONS`).

    rows: one per (model, obs, seed, scenario, simulation) with CR_AA, CR_AL, CR_total
    (fractions of steps), CD (cm) and AS (m/s); curves: (model, iteration, reward[, seed]) for
    the training summary, the curve verdicts and the training figures.

    Estimates weigh seeds equally and intervals come from a two-level bootstrap (seeds, then
    simulations; `sigmarl.stats.bootstrap`), so the same rows give byte-identical files.
    """
    rows = validate_rows(rows)
    options = replace(options, out_dir=Path(options.out_dir))
    draft = Draft(rows, options, curves if curves is not None and len(curves) else None)
    draft.models = model_order(rows, options.models, options.order)
    options.out_dir.mkdir(parents=True, exist_ok=True)
    for section in SECTIONS if sections is None else sections:
        draft.section = section
        section.build(draft)
    draft.section = None
    return draft


SECTIONS: list[Section] = [
    STUDY,  # `study.md`
    TABLE,  # table.md, table.csv, summary.csv, composite_scores.csv, matrix.md
    STATISTICS,  # improvement, aggregate scores (needs TABLE's cells and composite scores)
    BENCHMARK_TABLE,  # benchmark.md, benchmark.csv (where some rows measured its metrics)
    TRAINING,  # training.csv, training.md
    SEEDS,  # seeds.csv, seeds.md, seed_prediction.csv, slow_seeds.csv
    LATEX,  # table.tex (needs TABLE)
    VERDICTS,  # verdicts.csv, verdicts.md, interactions.csv
    FINDINGS,  # findings.md (needs TABLE and VERDICTS)
    MARL_EVAL,  # marl_eval*.json
    CURVE_VERDICTS,  # curve_verdicts.*, paper_seeds.csv (needs TRAINING)
    REPLICATION,  # replication.csv, replication.md
    PAPER_POLICIES,  # paper_policies.csv, paper_policies.md (the paper's own policies, imported rows)
    FIGURES,  # *.png (needs TABLE)
]
check_sections(SECTIONS)
