"""The exports' sections of the report: LaTeX, marl-eval's JSON, the figures."""

from __future__ import annotations

from sigmarl.report.draft import Draft, Section
from sigmarl.report.exports.marl_eval import export_files, interval_data
from sigmarl.report.table.aggregate import scenario_order
from sigmarl.report.table.header import caption
from sigmarl.report.table.paper import paper_curves
from sigmarl.report.table.tables import to_latex


def latex_section(d: Draft) -> None:
    """Table I in LaTeX; its caption says what each column changes, from the study page's header."""
    o = d.options
    if not o.latex:
        return
    text = "Evaluation of the models in the test scenarios (best per row in bold)."
    if o.configs is not None and o.defaults is not None:
        text += " " + caption(o.configs, d.rows, d.models, d.baseline, o.defaults)
    d.write("latex", "table.tex", to_latex(d.table, ci=o.ci, caption=text))


def marl_eval_section(d: Draft) -> None:
    """The rows as marl-eval's JSON, split by seed set so that each file loads whole."""
    chosen = d.rows[d.rows["model"].isin(d.models)]
    for name, data in export_files(chosen, d.models, d.curves).items():
        d.write(name.removesuffix(".json"), name, data)
    d.write("marl_eval_intervals", "marl_eval_intervals.json", interval_data(chosen, d.models))


def figures_section(d: Draft) -> None:
    """The report's figures (matplotlib, imported here only)."""
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
        if d.options.compare_paper:
            from sigmarl.report.exports.paper_band import plot_paper_band

            own = [m for m in models if d.paper_models[m] == m]
            if plot_paper_band(d.curves, paper_curves(), own, d.file("paper_band", "paper_band.png")) is None:
                del d.paths["paper_band"]
    if len(scenarios) > 1 and len(models) > 1:
        plot_heatmap(d.summary, models, scenarios, d.file("heatmap", "heatmap.png"))
    plot_performance_profiles(chosen, models, scenarios, d.file("performance_profiles", "performance_profiles.png"))


LATEX = Section("latex", {
    "table.tex": "Table I in booktabs; its caption says each column's label and what it changes against the "
                 "baseline, the shared settings and the budget"}, latex_section, when="with `--latex`")

MARL_EVAL = Section("marl_eval", {
    "marl_eval.json": "the rows in marl-eval 0.0.4's format, the seeds every model has",
    "marl_eval_<models>.json": "one per group of models with a larger seed set, e.g. `marl_eval_M0_M4.json`",
    "marl_eval_intervals.json": "every seed, the real n and Student t, and which file holds which seeds"},
    marl_eval_section)

FIGURES = Section("figures", {
    "distributions.png": "box plots of CR_total, CD and AS over the simulations, a row per scenario",
    "performance_profiles.png": "per model, the share of simulations with CR_total above each level, a panel per scenario and "
                                "one over all, with bootstrap bands",
    "heatmap.png": "CR_total's estimates, models by scenarios, with intervals (several of each)",
    "training_curves.png": "mean episode reward per iteration, a line per model (the paper's Fig. 5 beside it "
                           "with `--compare-paper`)",
    "training_band.png": "mean reward per iteration over seeds, with its 95% band over resampled seeds",
    "paper_band.png": "with `--compare-paper`: the paper's training curve of each of its models against our seeds' "
                      "range and median, on the definition our runs logged (batch-cut, or the complete-episode "
                      "estimate where every seed has it), the paper's evaluated policy's iteration marked"}, figures_section, when="unless `--no-figures`")
