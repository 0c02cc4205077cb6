"""`build_report`: evaluation rows in, the report's files out, one section after another.

`SECTIONS` is the registry: a new section is its `Section` (`report.sections`) and one line
here, in the order they depend on (a section reads what the ones before it left on the draft).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pandas as pd

from sigmarl.report import sections as sec
from sigmarl.report.cells import model_order, validate_rows
from sigmarl.report.draft import BuildOptions, Draft, Section, check_sections

Report = Draft  # what build_report returns: the Markdown to print, the frames behind it, the files written


def build_report(rows: pd.DataFrame, options: BuildOptions, curves: pd.DataFrame | None = None,
                 sections: list[Section] | None = None) -> Report:
    """Table I and the report's other files in `options.out_dir` from evaluation rows, each
    section (`sections`, default `SECTIONS`) built where its `needs` holds.

    rows: one per (model, obs, seed, scenario, simulation) with CR_AA, CR_AL, CR_total
    (fractions of steps), CD (cm) and AS (m/s); curves: (model, iteration, reward[, seed]).
    Estimates weigh seeds equally and intervals come from a seeded two-level bootstrap (seeds,
    then simulations; `sigmarl.stats.bootstrap`), so the same rows give byte-identical files.
    """
    rows = validate_rows(rows)
    options = replace(options, out_dir=Path(options.out_dir))
    draft = Draft(rows, options, curves if curves is not None and len(curves) else None)
    draft.models = model_order(rows, options.models, options.order)
    options.out_dir.mkdir(parents=True, exist_ok=True)
    for section in SECTIONS if sections is None else sections:
        draft.section = section
        if section.needs is None or section.needs(draft):
            section.build(draft)
    draft.section = None
    return draft


SECTIONS: list[Section] = [
    sec.STUDY,  # `study.md`
    sec.TABLE,  # table.md, table.csv, summary.csv, composite_scores.csv, matrix.md
    sec.STATISTICS,  # improvement, aggregate scores (needs TABLE's cells and composite scores)
    sec.BENCHMARK_TABLE,  # benchmark.md, benchmark.csv (where some rows measured its metrics)
    sec.TRAINING,  # training.csv, training.md
    sec.SEEDS,  # seeds.csv, seeds.md, seed_prediction.csv, slow_seeds.csv
    sec.LATEX,  # table.tex (needs TABLE)
    sec.VERDICTS,  # verdicts.csv, verdicts.md, interactions.csv
    sec.FINDINGS,  # findings.md (needs TABLE and VERDICTS)
    sec.MARL_EVAL,  # marl_eval*.json
    sec.CURVE_VERDICTS,  # curve_verdicts.*, paper_seeds.csv (needs TRAINING)
    sec.REPLICATION,  # replication.csv, replication.md
    sec.PAPER_POLICIES,  # paper_policies.csv, paper_policies.md (the paper's own policies, imported rows)
    sec.FIGURES,  # *.png (needs TABLE)
]
check_sections(SECTIONS)
