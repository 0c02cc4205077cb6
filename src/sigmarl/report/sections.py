"""The report's sections (`draft.Section`), in the groups a reader sees: Table I (what the columns
are, the table, the statistics over scenarios), the seeds (the training curves' summary, each
model-seed's figures, where a next seed will land), the exports (LaTeX, marl-eval's JSON, the
figures) and the comparisons (verdicts, findings, curves compared, whether the paper's claims
reproduce, the paper's own policies beside our seeds). `build.SECTIONS` lists them in order.
"""

from __future__ import annotations

from dataclasses import asdict

import pandas as pd

from sigmarl.metrics import BENCHMARK, CS, HEADLINE, in_table
from sigmarl.report import scores, tables
from sigmarl.report import seeds as per_seed
from sigmarl.report.cells import cells, composite_scores, scenario_order, summarise, trim_collisions
from sigmarl.report.compare import verdicts
from sigmarl.report.compare.curves import (
    curve_verdicts_markdown,
    paper_seed_table,
    separation_table,
)
from sigmarl.report.compare.paper_policies import explain, policy_markdown, policy_table
from sigmarl.report.compare.replication import (
    COLUMNS,
    PAPERS_WAY,
    replication_markdown,
    replication_table,
)
from sigmarl.report.draft import Draft, Section
from sigmarl.report.marl_eval import export_files, interval_data
from sigmarl.report.study import caption, provenance_markdown, reward_differs, study_markdown
from sigmarl.report.training import paper_last_rewards, training_markdown, training_summary

# in table.md, between what the columns are and the table itself
TABLE_HEADING = "## Table"


def _configured(d: Draft) -> bool:
    """Whether the columns' training configs are known (the command reads them; a bare
    `build_report` has none)."""
    return d.options.configs is not None and d.options.defaults is not None


def study_section(d: Draft) -> None:
    """What the report compares (the study page)."""
    o = d.options
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
    intervals = scores.composite_intervals(d.cells, composite)
    d.composite = composite.merge(intervals.drop(columns=CS), on=["scenario", "model"], how="left")
    paper = tables.paper_values(d.models) if o.compare_paper else None
    measured = set(paper.index.get_level_values("scenario")) if paper is not None else set()
    d.notes = tables.table_notes(d.summary, d.composite, d.models, trim=o.trim, compare_paper=o.compare_paper, ci=o.ci,
                                 paper_scenarios=measured) + list(o.extra_notes)
    d.table = tables.build_table(d.summary, d.composite, d.models, paper, d.notes)
    d.markdown = tables.to_markdown(d.table, ci=o.ci)
    if _configured(d):  # the study page's header: what the columns are
        d.markdown = study_markdown(o.configs, d.rows, d.models, d.baseline, o.defaults, o.commit,
                                    title="What this table compares", with_commit=False) \
            + f"\n{TABLE_HEADING}\n\n" + d.markdown
    d.write("markdown", "table.md", d.markdown)
    d.write("csv", "table.csv", tables.to_csv_frame(d.table))
    d.write("summary", "summary.csv", d.summary)
    d.write("composite", "composite_scores.csv", d.composite)
    d.write("matrix", "matrix.md", tables.matrix_markdown(d.table, d.baseline or ("M0" if "M0" in d.models else None)))


def statistics_section(d: Draft) -> None:
    """Probability of improvement and aggregate scores over scenarios."""
    d.improvement = scores.improvement(d.rows, d.models, trim=d.options.trim, reference=d.baseline)
    overall = scores.improvement_overall(d.rows, d.models, trim=d.options.trim, reference=d.baseline)
    d.aggregates = scores.aggregate_scores(d.cells, d.composite, d.models)
    both = pd.concat([d.improvement, overall], ignore_index=True) if len(overall) else d.improvement
    d.statistics = scores.statistics_markdown(both, d.aggregates, trim=d.options.trim)
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
                "versions or hardware differ"}, study_section,
    when="when the columns' training configs are known (by `sigmarl report`, always)", needs=_configured)

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
    "statistics.md": "the three files above as Markdown"}, statistics_section,
    when="with two columns or more", needs=lambda d: len(d.models) > 1)  # one column: nothing to compare


def _benchmark_measured(d: Draft) -> bool:
    """Whether some row measured the benchmark's metrics (rows from before them did not)."""
    return any(m.name in d.rows.columns and d.rows[m.name].notna().any() for m in in_table(BENCHMARK))


def benchmark_section(d: Draft) -> None:
    estimates = tables.benchmark_estimates(d.rows, d.models)
    d.write("benchmark_md", "benchmark.md", tables.benchmark_markdown(estimates))
    d.write("benchmark_csv", "benchmark.csv", estimates)


BENCHMARK_TABLE = Section("benchmark", {
    "benchmark.md": "the CPM Lab benchmark's metrics per scenario and column (task success, collision events "
                    "and lane violation per 100 m driven), `–` where not measured, with their definitions",
    "benchmark.csv": "the same, in the table's units"}, benchmark_section,
    when="when some rows measured them (`sigmarl evaluate --add-metrics` adds them to older rows)",
    needs=_benchmark_measured)


def training_section(d: Draft) -> None:
    """The training curves' summary."""
    d.training = training_summary(d.curves, d.models)
    last = paper_last_rewards(tables.paper_curves()) if d.options.compare_paper else None
    d.write("training", "training.csv", d.training)
    text = training_markdown(d.training, last)
    configs = [d.options.configs[m] for m in d.models if m in (d.options.configs or {})]
    if differ := reward_differs(configs):  # sums of different reward functions
        text = (f"Not comparable across columns: they train on different rewards ({', '.join(differ)}); "
                "each column's rewards compare only with its own seeds.\n\n") + text
    d.write("training_md", "training.md", text)


TRAINING = Section("training", {
    "training.csv": "per seed: iterations, compute time, last and best reward",
    "training.md": "the same per model (the paper's Fig. 5 beside it with `--compare-paper`); where the columns "
                   "train on different rewards it opens by saying their rewards are not comparable"},
    training_section, when="when training curves (`metrics.csv`) are read", needs=lambda d: d.curves is not None)


def seeds_section(d: Draft) -> None:
    """Each model-seed's rates, deviation, speed and rewards, and where a next seed will land."""
    seeds = per_seed.seed_table(d.rows, d.curves, d.models)
    scenarios = scenario_order(d.rows)
    prediction = per_seed.prediction_table(seeds, scenarios)
    design = d.design
    slow = per_seed.slow_seed_table(seeds, {v: design.baseline_of(v) for v in design.compared}, design.slow_seed)
    d.write("seeds", "seeds.csv", seeds)
    d.write("seed_prediction", "seed_prediction.csv", prediction)
    d.write("slow_seeds", "slow_seeds.csv", slow)
    spread = per_seed.next_seed_markdown(prediction, slow, scenarios)
    d.write("seeds_md", "seeds.md", per_seed.seeds_markdown(seeds, scenarios) + ("\n" + spread if spread else ""))


SEEDS = Section("seeds", {
    "seeds.csv": "each evaluated model-seed's collision rates per scenario, its worst one, center-line "
                 "deviation, speed range and reward over three windows of training",
    "seeds.md": "the same as Markdown; per model with 5 seeds or more, Spearman's correlation of a seed's "
                "reward with its collisions, and where a next seed will land",
    "seed_prediction.csv": "per model and scenario: the next seed's 95% prediction interval of CR_total and "
                           "the seeds' range",
    "slow_seeds.csv": "with `study.slow_seed`: each variant's slow seeds against its baseline's, Fisher's "
                      "exact p"}, seeds_section)


def latex_section(d: Draft) -> None:
    """Table I in LaTeX; its caption says what each column changes, from the study page's header."""
    o = d.options
    text = "Evaluation of the models in the test scenarios (best per row in bold)."
    if _configured(d):
        text += " " + caption(o.configs, d.rows, d.models, d.baseline, o.defaults)
    d.write("latex", "table.tex", tables.to_latex(d.table, ci=o.ci, caption=text))


def marl_eval_section(d: Draft) -> None:
    """The rows as marl-eval's JSON, split by seed set so that each file loads whole."""
    chosen = d.rows[d.rows["model"].isin(d.models)]
    for name, data in export_files(chosen, d.models, d.curves).items():
        d.write(name.removesuffix(".json"), name, data)
    d.write("marl_eval_intervals", "marl_eval_intervals.json", interval_data(chosen, d.models))


def figures_section(d: Draft) -> None:
    """The report's figures (matplotlib is slow to load: imported here, table-only reports skip it)."""
    from sigmarl.report import figures as fig

    models, scenarios = d.models, scenario_order(d.rows)
    chosen = d.rows[d.rows["model"].isin(models)]
    paper = tables.paper_curves() if d.options.compare_paper else None
    fig.plot_distributions(chosen, models, scenarios, d.file("distributions", "distributions.png"))
    if d.curves is not None:
        fig.plot_training_curves(d.curves, d.file("training_curves", "training_curves.png"), models, paper)
        fig.plot_training_band(d.curves, d.file("training_band", "training_band.png"), models)
        own = [m for m in models if d.paper_models[m] == m]
        if paper is not None and fig.plot_paper_band(d.curves, paper, own, d.file("paper_band", "paper_band.png")) \
                is None:
            del d.paths["paper_band"]
    if len(scenarios) > 1 and len(models) > 1:
        fig.plot_heatmap(d.summary, models, scenarios, d.file("heatmap", "heatmap.png"))
    fig.plot_performance_profiles(chosen, models, scenarios, d.file("performance_profiles", "performance_profiles.png"))


LATEX = Section("latex", {
    "table.tex": "Table I in booktabs; its caption says each column's label and what it changes against the "
                 "baseline, the shared settings and the budget"}, latex_section,
    when="with `--latex`", needs=lambda d: d.options.latex)

MARL_EVAL = Section("marl_eval", {
    "marl_eval.json": "the rows in marl-eval 0.0.4's format, the seeds every model has",
    "marl_eval_<models>.json": "one per group of models with a larger seed set, e.g. `marl_eval_M0_M4.json`",
    "marl_eval_intervals.json": "every seed, the real n and Student t, and which file holds which seeds"},
    marl_eval_section)

FIGURES = Section("figures", {
    "distributions.png": "box plots of CR_total, CD and AS over the simulations, a row per scenario",
    "performance_profiles.png": "per model, the share of simulations with CR_total above each level, a panel per scenario and "
                                "one over all, with bootstrap bands",
    "heatmap.png": f"{HEADLINE}'s estimates, models by scenarios, with intervals (several of each)",
    "training_curves.png": "mean episode reward per iteration, a line per model (the paper's Fig. 5 beside it "
                           "with `--compare-paper`)",
    "training_band.png": "mean reward per iteration over seeds, with its 95% band over resampled seeds",
    "paper_band.png": "with `--compare-paper`: the paper's training curve of each of its models against our seeds' "
                      "range and median, on the definition our runs logged (batch-cut, or the complete-episode "
                      "estimate where every seed has it), the paper's evaluated policy's iteration marked"},
    figures_section, when="unless `--no-figures`", needs=lambda d: d.options.figures)


def verdicts_section(d: Draft) -> None:
    """One verdict per comparison and, for a factorial study, its interactions."""
    design = d.design
    measured = trim_collisions(d.rows) if d.options.trim else d.rows
    d.verdicts = verdicts.verdict_table(measured, design)
    d.verdicts_markdown = verdicts.verdicts_markdown(d.verdicts, design)
    d.write("verdicts", "verdicts.csv", d.verdicts)
    interactions = verdicts.interaction_table(measured, design) if design.interactions else None
    if interactions is not None and len(interactions):  # a factorial study's question
        d.verdicts_markdown += "\n" + verdicts.interactions_markdown(interactions, design)
        d.write("interactions", "interactions.csv", interactions)
    d.write("verdicts_md", "verdicts.md", d.verdicts_markdown)


def findings_section(d: Draft) -> None:
    """What the study found, in sentences of its own figures."""
    d.write("findings", "findings.md", verdicts.findings_markdown(d.summary, d.verdicts, d.models, d.baseline,
                                                                  d.design.alpha))


def curve_verdicts_section(d: Draft) -> None:
    """When the compared training curves part, and whether the paper's one seed could be ours."""
    design = d.design
    separation = separation_table(d.curves, design) if design.baseline in d.models else None
    seeds = None
    if d.options.compare_paper:
        seeds = paper_seed_table(d.training, paper_last_rewards(tables.paper_curves()), d.paper_models)
    text = curve_verdicts_markdown(*(x if x is not None else pd.DataFrame() for x in (separation, seeds)), design)
    if not text:
        return
    d.write("curve_verdicts_md", "curve_verdicts.md", text)
    d.write("curve_verdicts", "curve_verdicts.csv", separation)
    d.write("paper_seeds", "paper_seeds.csv", seeds)


def replication_section(d: Draft) -> None:
    """Does each claim of the paper's Table I reproduce, over the columns that are the paper's own
    models (label and observation strategies both, so no other design is read as the paper's)."""
    if not d.options.compare_paper or "M0" not in d.models:
        return
    paper = d.paper_models
    own = [m for m in d.models if paper[m] == m]
    if "M0" not in own or len(own) < 2:
        return
    found = replication_table(d.rows, own, "M0", d.design.alpha, d.design)
    d.write("replication", "replication.csv", found.differences[COLUMNS])
    d.write("replication_rankings", "replication_rankings.csv", found.rankings)
    d.write("replication_interactions", "replication_interactions.csv", found.interactions)
    any_claim = len(found.differences) or len(found.rankings)
    d.write("replication_md", "replication.md", replication_markdown(found, d.design.alpha) if any_claim else None)


VERDICTS = Section("verdicts", {
    "verdicts.csv": "each comparison (variant against its baseline, per scenario and metric): the difference "
                    "with the comparison engine's interval and p-values, the verdict and the seeds it needs",
    "verdicts.md": "the same as Markdown, a factorial study's interactions under it",
    "interactions.csv": "a factorial study's interactions (difference of differences)"},
    verdicts_section, when="with a baseline and a variant to compare",
    needs=lambda d: d.design.baseline in d.models and bool(d.design.compared))

FINDINGS = Section("findings", {
    "findings.md": "the study's figures in sentences: seeds per model, the baseline's worst collision rate and "
                   "speed range, each variant's verdicts (the results pages quote it)"}, findings_section,
    needs=lambda d: d.summary is not None and len(d.summary) > 0)

CURVE_VERDICTS = Section("curve_verdicts", {
    "curve_verdicts.csv": "each compared variant's reward against its baseline's per window of 25 iterations "
                          "(the comparison engine, Holm-adjusted)",
    "curve_verdicts.md": "the same as Markdown, and where the curves part",
    "paper_seeds.csv": "with `--compare-paper`: whether the paper's one seed could be one of ours"},
    curve_verdicts_section, when="when training curves are read", needs=lambda d: d.training is not None)

REPLICATION = Section("replication", {
    "replication.csv": "per claim of Table I (M1..M5 minus M0, CR_total trimmed as the paper's, per scenario; "
                       "struck-out values listed apart): the paper's number, ours with its interval, the paper's "
                       "percentile and Holm-adjusted p among our one-seed differences, `p_verdict` (the Holm-adjusted "
                       "p of the one-sided test the verdict rests on), the verdict, its explanation, seeds needed",
    "replication_rankings.csv": "per scenario: the paper's best-scored model, the share of whole-seed replicates "
                                "in which it ranks first here, the model most often first, the verdict",
    "replication_interactions.csv": "per claim with a study's interaction on it (`study=paper_reward`): the other "
                                    "condition's column, the four groups' seeds, the difference of differences, its "
                                    "interval, Holm-adjusted p and verdict (paper's direction, against it, same, undecided)",
    "replication.md": "the three files above as Markdown, with all four one-sided p-values of each claim"},
    replication_section, when="with `--compare-paper`, over the columns that are the paper's own models, M0 among them")

def paper_policies_section(d: Draft) -> None:
    """The paper's policy per model: its CR_total in our evaluator under either rules, its rank
    among our seeds, its Mk - M0 beside Table I's; over the columns that are the paper's models."""
    imported = d.options.imported
    if not d.options.compare_paper or imported is None or not len(imported):
        return
    paper = d.paper_models
    own = [m for m in d.models if paper[m] == m]
    table = policy_table(d.rows[d.rows["model"].isin(own)], imported, own)
    if "replication" in d.paths and len(table):  # each unreproduced claim's explanation
        interactions = d.paths.get("replication_interactions")
        reward = reward_explains(pd.read_csv(interactions), d.options.configs or {}) if interactions else {}
        table["explanation"] = explain(table, pd.read_csv(d.paths["replication"]), reward)
    d.write("paper_policies", "paper_policies.csv", table)
    d.write("paper_policies_md", "paper_policies.md", policy_markdown(table) if len(table) else None)


def reward_explains(interactions: pd.DataFrame, configs: dict) -> dict[tuple[str, str], bool]:
    """(scenario, model) -> True where the claim's interaction (`replication_interactions.csv`) is
    decided in the paper's direction and its condition is the paper's reward: the condition's
    column was trained with `rules.reward_normaliser_one` on, the claim's model with it off, every
    other rule alike."""
    out = {}
    for _, r in interactions[interactions["verdict"] == PAPERS_WAY].iterrows():
        x, y = configs.get(str(r["condition"])), configs.get(str(r["model"]))
        if x is not None and y is not None:
            a, b = asdict(x.rules), asdict(y.rules)
            if {k for k in a if a[k] != b[k]} == {"reward_normaliser_one"} and a["reward_normaliser_one"]:
                out[(str(r["scenario"]), str(r["model"]))] = True
    return out


PAPER_POLICIES = Section("paper_policies", {
    "paper_policies.csv": "per claim of `replication.csv` and M0 (each Mk - M0 is a row's minus M0's): CR_total, "
                          "trimmed as the paper's, of Table I, of our seeds (`n_seeds`) and of the paper's own policy "
                          "in our evaluator under the paper's rules and under ours (adapted); how many of our seed "
                          "means lie below it under either; `explanation`, each unreproduced claim's: the paper's "
                          "reward (its `replication_interactions.csv` row decided in the paper's direction), the "
                          "paper's own run, seed luck or unexplained",
    "paper_policies.md": "the same as Markdown, with each Mk - M0 and the policy's rank among our seeds"},
    paper_policies_section,
    when="with `--compare-paper` and the paper's policies' rows (results/paper-policies/ beside the --from folder)")

