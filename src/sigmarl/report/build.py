"""`build_report`: evaluation rows in, table files, composite scores and figures out.

The report is a list of sections (`SECTIONS`), each a function of one `Draft`: the rows, the
options and what the earlier sections computed. A section computes its part, writes its
files through `Draft.write` and leaves what later sections or the caller need on the draft.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import pandas as pd

from sigmarl.report.compare.curve_verdicts import (
    curve_verdicts_markdown,
    paper_model_of,
    paper_seed_table,
    separation_table,
)
from sigmarl.report.compare.findings import findings_markdown
from sigmarl.report.compare.interactions import interaction_table, interactions_markdown
from sigmarl.report.compare.replication import replication_markdown, replication_table
from sigmarl.report.compare.verdicts import verdict_table, verdicts_markdown
from sigmarl.report.draft import BuildOptions, Draft, Section, check_sections
from sigmarl.report.exports.marl_eval import export_files, interval_data
from sigmarl.report.seeds.sections import SEEDS
from sigmarl.report.seeds.training import paper_last_rewards, training_markdown, training_summary
from sigmarl.report.table.aggregate import (
    cells,
    model_order,
    scenario_order,
    summarise,
    trim_collisions,
    validate_rows,
)
from sigmarl.report.table.composite import composite_scores
from sigmarl.report.table.header import caption, reward_differs, study_markdown
from sigmarl.report.table.notes import table_notes
from sigmarl.report.table.paper import paper_curves, paper_values
from sigmarl.report.table.scores import (
    aggregate_scores,
    composite_intervals,
    improvement,
    improvement_overall,
)
from sigmarl.report.table.tables import (
    ResultTable,
    build_table,
    matrix_markdown,
    statistics_markdown,
    to_csv_frame,
    to_latex,
    to_markdown,
)

# in table.md, between what the columns are and the table itself
TABLE_HEADING = "## Table"


@dataclass
class Report:
    """What `build_report` made: the Markdown to print, the frames behind it, the files."""

    markdown: str
    table: ResultTable
    summary: pd.DataFrame  # one row per (scenario, model, metric), see `aggregate`
    composite: pd.DataFrame  # scenario, model, CS, note, ci_low, ci_high
    improvement: pd.DataFrame  # see `scores.improvement`
    aggregates: pd.DataFrame  # see `scores.aggregate_scores`
    statistics: str  # Markdown of the two frames above
    training: pd.DataFrame | None = None  # see `training.training_summary` (curves given)
    paths: dict[str, Path] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    verdicts: pd.DataFrame | None = None  # see `verdicts.verdict_table` (a baseline and a model given)
    verdicts_markdown: str = ""


def build_report(rows: pd.DataFrame, options: BuildOptions, curves: pd.DataFrame | None = None) -> Report:
    """Aggregate evaluation rows into the paper's Table I and the report's other files in
    `options.out_dir`, one section after another (`SECTIONS`).

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
    for section in SECTIONS:
        draft.section = section
        section.build(draft)
    draft.section = None
    return Report(draft.markdown, draft.table, draft.summary, draft.composite, draft.improvement,
                  draft.aggregates, draft.statistics, draft.training, draft.paths, draft.notes,
                  draft.verdicts, draft.verdicts_markdown)


def table_section(d: Draft) -> None:
    """Table I (table.md, table.csv), its cells (summary.csv) and composite scores with their
    intervals (composite_scores.csv); the matrix view of the same table (matrix.md)."""
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
    """Probability of improvement and aggregate scores over scenarios: statistics.md,
    improvement.csv, improvement_overall.csv and aggregate_scores.csv (`sigmarl.report.table.scores`);
    none for a one-column report, which has nothing to compare."""
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


def training_section(d: Draft) -> None:
    """The training curves' summary (training.csv, training.md), curves given."""
    if d.curves is None:
        return
    d.training = training_summary(d.curves, d.models)
    last = paper_last_rewards(paper_curves()) if d.options.compare_paper else None
    d.write("training", "training.csv", d.training)
    text = training_markdown(d.training, last)
    configs = [d.options.configs[m] for m in d.models if m in (d.options.configs or {})]
    if differ := reward_differs(configs):  # sums of different reward functions
        text = (f"Not comparable across columns: they train on different rewards ({', '.join(differ)}); "
                "each column's rewards compare only with its own seeds.\n\n") + text
    d.write("training_md", "training.md", text)


def study_section(d: Draft) -> None:
    """What the report compares (the study page, `report.table.header`), the columns' configs given."""
    o = d.options
    if o.configs is None or o.defaults is None:
        return
    d.write("study", "study.md", study_markdown(o.configs, d.rows, d.models, d.baseline, o.defaults, o.commit))


def latex_section(d: Draft) -> None:
    """table.tex; its caption says what each column changes, from the study page's header."""
    o = d.options
    if not o.latex:
        return
    text = "Evaluation of the models in the test scenarios (best per row in bold)."
    if o.configs is not None and o.defaults is not None:
        text += " " + caption(o.configs, d.rows, d.models, d.baseline, o.defaults)
    d.write("latex", "table.tex", to_latex(d.table, ci=o.ci, caption=text))


def verdicts_section(d: Draft) -> None:
    """One verdict per comparison (verdicts.md, verdicts.csv) and, for a factorial study, its
    interactions (interactions.csv, under the verdicts in verdicts.md)."""
    design = d.design
    if design.baseline not in d.models or not design.compared:
        return
    measured = trim_collisions(d.rows) if d.options.trim else d.rows
    d.verdicts = verdict_table(measured, design)
    d.verdicts_markdown = verdicts_markdown(d.verdicts, design)
    d.write("verdicts", "verdicts.csv", d.verdicts)
    interactions = interaction_table(measured, design) if design.interactions else None
    if interactions is not None and len(interactions):  # a factorial study's question
        d.verdicts_markdown += "\n" + interactions_markdown(interactions, design)
        d.write("interactions", "interactions.csv", interactions)
    d.write("verdicts_md", "verdicts.md", d.verdicts_markdown)


def findings_section(d: Draft) -> None:
    """What the study found, in sentences of its own figures (findings.md; `report.compare.findings`)."""
    if d.summary is None or not len(d.summary):
        return
    d.write("findings", "findings.md", findings_markdown(d.summary, d.verdicts, d.models, d.baseline,
                                                        d.design.alpha))


def marl_eval_section(d: Draft) -> None:
    """The rows as marl-eval's JSON, split by seed set so each file loads whole (marl_eval.json:
    the seeds common to all models), and its intervals with every seed and the real number of
    seeds (marl_eval_intervals.json; `sigmarl.report.exports.marl_eval`)."""
    chosen = d.rows[d.rows["model"].isin(d.models)]
    for name, data in export_files(chosen, d.models, d.curves).items():
        d.write(name.removesuffix(".json"), name, data)
    d.write("marl_eval_intervals", "marl_eval_intervals.json", interval_data(chosen, d.models))


def curve_verdicts_section(d: Draft) -> None:
    """When the compared training curves part, and (compare_paper) whether the paper's one
    seed could be one of ours: curve_verdicts.md, curve_verdicts.csv and paper_seeds.csv."""
    if d.training is None:
        return
    design = d.design
    separation = separation_table(d.curves, design) if design.baseline in d.models else None
    seeds = None
    if d.options.compare_paper:
        obs = d.rows.drop_duplicates("model").set_index("model")["obs"].astype(str)
        seeds = paper_seed_table(d.training, paper_last_rewards(paper_curves()),
                                 {m: paper_model_of(obs.get(m, "")) for m in d.models})
    text = curve_verdicts_markdown(*(x if x is not None else pd.DataFrame() for x in (separation, seeds)), design)
    if not text:
        return
    d.write("curve_verdicts_md", "curve_verdicts.md", text)
    d.write("curve_verdicts", "curve_verdicts.csv", separation)
    d.write("paper_seeds", "paper_seeds.csv", seeds)


def replication_section(d: Draft) -> None:
    """(compare_paper) Does each claim of the paper's Table I reproduce: replication.csv and
    replication.md (`report.compare.replication`), over the columns that are the paper's own models
    (label and observation strategies both, so no other design is read as the paper's)."""
    if not d.options.compare_paper or "M0" not in d.models:
        return
    obs = d.rows.drop_duplicates("model").set_index("model")["obs"].astype(str)
    own = [m for m in d.models if paper_model_of(obs.get(m, "")) == m]
    if "M0" not in own or len(own) < 2:
        return
    table = replication_table(d.rows, own, "M0", d.design.alpha)
    d.write("replication", "replication.csv", table)
    d.write("replication_md", "replication.md", replication_markdown(table, d.design.alpha) if len(table) else None)


def figures_section(d: Draft) -> None:
    """distributions.png, performance_profiles.png, heatmap.png (several scenarios and models),
    and training_curves.png and training_band.png (curves given)."""
    if not d.options.figures:
        return
    # matplotlib is imported only when drawing: table-only reports stay quick to start
    from sigmarl.report.exports.figures import (
        plot_distributions,
        plot_heatmap,
        plot_performance_profiles,
        plot_training_band,
        plot_training_curves,
    )

    models, scenarios = d.models, scenario_order(d.rows)
    chosen = d.rows[d.rows["model"].isin(models)]
    plot_distributions(chosen, models, scenarios, d.file("distributions", "distributions.png"))
    if d.curves is not None:
        plot_training_curves(d.curves, d.file("training_curves", "training_curves.png"), models,
                             paper=paper_curves() if d.options.compare_paper else None)
        plot_training_band(d.curves, d.file("training_band", "training_band.png"), models)
    if len(scenarios) > 1 and len(models) > 1:
        plot_heatmap(d.summary, models, scenarios, d.file("heatmap", "heatmap.png"))
    plot_performance_profiles(chosen, models, scenarios, d.file("performance_profiles", "performance_profiles.png"))


STUDY = Section("study", {
    "study.md": "what the report compares: per column its label, fingerprint, seeds and the training settings "
                "it changes against the baseline; the settings every column shares where they are not the "
                "defaults, a sweep's command line included; the training and evaluation budget; the commit "
                "the report was built at"}, study_section, when="the columns' training configs known")
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
    "statistics.md": "the three files above as Markdown"}, statistics_section, when="two columns or more")
TRAINING = Section("training", {
    "training.csv": "per seed: iterations, compute time, last and best reward",
    "training.md": "the same per model (the paper's Fig. 5 beside it with `--compare-paper`); where the columns "
                   "train on different rewards it opens by saying their rewards are not comparable"},
    training_section, when="training curves (`metrics.csv`) read")
LATEX = Section("latex", {
    "table.tex": "Table I in booktabs; its caption says each column's label and what it changes against the "
                 "baseline, the shared settings and the budget"}, latex_section, when="`--latex`")
VERDICTS = Section("verdicts", {
    "verdicts.csv": "each comparison (variant against its baseline, per scenario and metric): the difference "
                    "with its interval, permutation and Welch p-values, the verdict and the seeds it needs",
    "verdicts.md": "the same as Markdown, a factorial study's interactions under it",
    "interactions.csv": "a factorial study's interactions (difference of differences)"},
    verdicts_section, when="a baseline and a variant to compare")
FINDINGS = Section("findings", {
    "findings.md": "the study's figures in sentences: seeds per model, the baseline's worst collision rate and "
                   "speed range, each variant's verdicts (the results pages quote it)"}, findings_section)
MARL_EVAL = Section("marl_eval", {
    "marl_eval.json": "the rows in marl-eval 0.0.4's format, the seeds every model has",
    "marl_eval_<models>.json": "one per group of models with a larger seed set, e.g. `marl_eval_M0_M4.json`",
    "marl_eval_intervals.json": "every seed, the real n and Student t, and which file holds which seeds"},
    marl_eval_section)
CURVE_VERDICTS = Section("curve_verdicts", {
    "curve_verdicts.csv": "each compared variant's reward against its baseline's per window of 25 iterations "
                          "(Welch, Holm-adjusted)",
    "curve_verdicts.md": "the same as Markdown, and where the curves part",
    "paper_seeds.csv": "with `--compare-paper`: whether the paper's one seed could be one of ours"},
    curve_verdicts_section, when="training curves read")
REPLICATION = Section("replication", {
    "replication.csv": "per claim of the paper's Table I (each M1..M5 minus M0 CR_total per scenario, each "
                       "scenario's best composite score): the paper's number, ours with its interval, the "
                       "paper's percentile among our one-seed differences, four one-sided Holm-adjusted "
                       "permutation p-values and the verdict (collision rates trimmed as the paper's)",
    "replication.md": "the same as Markdown"},
    replication_section, when="`--compare-paper`, over the columns that are the paper's own models, M0 among them")
FIGURES = Section("figures", {
    "distributions.png": "box plots of CR_total, CD and AS over the simulations, a row per scenario",
    "performance_profiles.png": "per model, the share of simulations with CR_total above each level, a panel per scenario and "
                                "one over all, with bootstrap bands",
    "heatmap.png": "CR_total's estimates, models by scenarios, with intervals (several of each)",
    "training_curves.png": "mean episode reward per iteration, a line per model (the paper's Fig. 5 beside it "
                           "with `--compare-paper`)",
    "training_band.png": "mean reward per iteration over seeds, with its 95% band over resampled seeds"}, figures_section, when="not `--no-figures`")

SECTIONS: list[Section] = [
    STUDY, TABLE, STATISTICS, TRAINING, SEEDS, LATEX, VERDICTS, FINDINGS, MARL_EVAL, CURVE_VERDICTS, REPLICATION,
    FIGURES,
]
check_sections(SECTIONS)
