"""`build_report`: evaluation rows in, table files, composite scores and figures out."""

from __future__ import annotations

import json
from dataclasses import dataclass, field, replace
from pathlib import Path

import pandas as pd

from sigmarl.ablation import MODELS
from sigmarl.metrics import units_text
from sigmarl.report.aggregate import (
    cells,
    model_order,
    scenario_order,
    summarise,
    trim_collisions,
    validate_rows,
)
from sigmarl.report.composite import composite_scores
from sigmarl.report.curve_verdicts import (
    curve_verdicts_markdown,
    paper_model_of,
    paper_seed_table,
    separation_table,
)
from sigmarl.report.interactions import interaction_table, interactions_markdown
from sigmarl.report.marl_eval import interval_data, marl_eval_data
from sigmarl.report.paper import paper_curves, paper_values
from sigmarl.report.scores import aggregate_scores, composite_intervals, improvement
from sigmarl.report.seeds import seed_table, seeds_markdown
from sigmarl.report.tables import (
    ResultTable,
    build_table,
    matrix_markdown,
    statistics_markdown,
    to_csv_frame,
    to_latex,
    to_markdown,
)
from sigmarl.report.training import paper_last_rewards, training_markdown, training_summary
from sigmarl.report.verdicts import Design, verdict_table, verdicts_markdown

# Fixed formatting of every CSV's floats: the same rows give byte-identical files.
FLOAT_FORMAT = "%.10g"


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


def _notes(
    summary: pd.DataFrame,
    composite: pd.DataFrame,
    models: list[str],
    *,
    trim: bool,
    compare_paper: bool,
    ci: bool,
    paper_scenarios: set[str] = frozenset(),
) -> list[str]:
    """The lines under the table that say what the numbers are."""
    n = summary["n"][summary["metric"] == "AS"]
    n_seeds = summary["n_seeds"][summary["metric"] == "AS"]
    sims = _span(n)
    seeds = _span(n_seeds)
    notes = [
        (f"Mean over {seeds} seeds of each seed's mean over its simulations ({sims} simulations per cell)"
         if n_seeds.max() > 1 else f"Mean over {sims} simulations per cell")
        + (" [95% bootstrap interval over seeds and simulations]" if ci else "")
        + f"; {units_text(of_steps=True)}; best per row in bold."
    ]
    if trim:
        notes.append("Collision rates without each evaluation's best and worst simulation.")
    for scenario, g in composite.groupby("scenario", sort=False):
        absent = [m for m in models if m not in set(g["model"])]
        if absent:  # the scores then compare fewer models than the table's columns
            notes.append(f"{scenario}: no evaluation rows for {', '.join(absent)}.")
        for note in dict.fromkeys(g["note"]):
            if note:
                notes.append(f"{scenario}: {note}.")
    if compare_paper:
        notes.append("In parentheses: the paper's Table I (CD converted to real cm).")
        others = [s for s in dict.fromkeys(summary["scenario"]) if s not in paper_scenarios]
        if others:
            notes.append(f"{', '.join(others)}: not in the paper's Table I, no paper numbers.")
        if not trim:
            notes.append(
                "The paper dropped the best and worst simulation from its collision rates; "
                "ours are not trimmed (use trim for a like-for-like comparison)."
            )
        if models != list(MODELS):
            notes.append(
                "The paper's composite scores compare M0..M5; ours compare "
                f"{', '.join(models)}, so the two CS rows are not comparable."
            )
    return notes


def _span(counts: pd.Series) -> str:
    return f"{counts.min()}" if counts.min() == counts.max() else f"{counts.min()}–{counts.max()}"


def build_report(
    rows: pd.DataFrame,
    models: list[str] | None = None,
    *,
    out_dir: Path,
    trim: bool = False,
    compare_paper: bool = False,
    latex: bool = False,
    curves: pd.DataFrame | None = None,
    ci: bool = False,
    figures: bool = True,
    extra_notes: list[str] | None = None,
    order: list[str] | None = None,
    baseline: str | None = None,
    design: Design | None = None,
) -> Report:
    """Aggregate evaluation rows into the paper's Table I and write it to `out_dir`.

    rows: one per (model, obs, seed, scenario, simulation) with CR_AA, CR_AL, CR_total
    (fractions of steps), CD (cm) and AS (m/s); models: the columns, in order (default:
    every model in the rows); trim: drop each evaluation's best and worst simulation from
    the collision rates; compare_paper: show the paper's numbers in parentheses; ci: show
    95% bootstrap intervals; curves: (model, iteration, reward[, seed]) for the training plot;
    order: the study's labels in declared order (the default columns); baseline: what every
    other column is compared with (default M0, or the first column).

    Estimates weigh seeds equally and intervals come from a two-level bootstrap (seeds, then
    simulations; `sigmarl.report.bootstrap`), so the same rows give byte-identical files.

    Writes table.md, table.csv, summary.csv, composite_scores.csv (with CS intervals),
    improvement.csv and aggregate_scores.csv with statistics.md (`sigmarl.report.scores`),
    table.tex (latex), training.csv and training.md (curves given; `sigmarl.report.training`),
    seeds.csv and seeds.md (each model-seed's rates and rewards; `sigmarl.report.seeds`),
    distributions.png and training_curves.png (figures; curves given).

    Also (`design`: the verdicts' study parameters; default: the models against M0, or the
    first model, on CR_total): verdicts.md and verdicts.csv (`sigmarl.report.verdicts`),
    marl_eval.json and marl_eval_intervals.json (`sigmarl.report.marl_eval`), and with figures
    performance_profiles.png and training_band.png (curves given).
    """
    rows = validate_rows(rows)
    models = model_order(rows, models, order)
    cell_list = cells(rows, models, trim=trim)
    summary = summarise(cell_list, trim=trim)
    composite = composite_scores(summary)
    intervals = composite_intervals(cell_list, composite)
    composite = composite.merge(intervals.drop(columns="CS"), on=["scenario", "model"], how="left")
    paper = paper_values(models) if compare_paper else None
    measured = set(paper.index.get_level_values("scenario")) if paper is not None else set()
    notes = _notes(summary, composite, models, trim=trim, compare_paper=compare_paper, ci=ci,
                   paper_scenarios=measured)
    notes += list(extra_notes or [])
    table = build_table(summary, composite, models, paper, notes)
    markdown = to_markdown(table, ci=ci)
    better = improvement(rows, models, trim=trim, reference=baseline if baseline in models else None)
    aggregates = aggregate_scores(cell_list, composite, models)
    statistics = statistics_markdown(better, aggregates, trim=trim)

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = {
        "markdown": out_dir / "table.md",
        "csv": out_dir / "table.csv",
        "summary": out_dir / "summary.csv",
        "composite": out_dir / "composite_scores.csv",
        "improvement": out_dir / "improvement.csv",
        "aggregates": out_dir / "aggregate_scores.csv",
        "statistics": out_dir / "statistics.md",
    }
    paths["markdown"].write_text(markdown, encoding="utf-8")
    paths["matrix"] = out_dir / "matrix.md"
    paths["matrix"].write_text(matrix_markdown(table, baseline if baseline in models else ("M0" if "M0" in models else None)), encoding="utf-8")
    paths["statistics"].write_text(statistics, encoding="utf-8")
    for key, frame in [("csv", to_csv_frame(table)), ("summary", summary), ("composite", composite),
                       ("improvement", better), ("aggregates", aggregates)]:
        frame.to_csv(paths[key], index=False, float_format=FLOAT_FORMAT, lineterminator="\n")
    training = None
    if curves is not None and len(curves):
        training = training_summary(curves, models)
        last = paper_last_rewards(paper_curves()) if compare_paper else None
        paths["training"] = out_dir / "training.csv"
        paths["training_md"] = out_dir / "training.md"
        training.to_csv(paths["training"], index=False, float_format=FLOAT_FORMAT, lineterminator="\n")
        paths["training_md"].write_text(training_markdown(training, last), encoding="utf-8")
    seeds = seed_table(rows, curves, models)
    paths["seeds"], paths["seeds_md"] = out_dir / "seeds.csv", out_dir / "seeds.md"
    seeds.to_csv(paths["seeds"], index=False, float_format=FLOAT_FORMAT, lineterminator="\n")
    paths["seeds_md"].write_text(seeds_markdown(seeds, scenario_order(rows)), encoding="utf-8")
    if latex:
        paths["latex"] = out_dir / "table.tex"
        paths["latex"].write_text(to_latex(table, ci=ci), encoding="utf-8")
    verdicts, verdicts_md = _write_extras(rows, models, curves, out_dir, paths, trim=trim, design=design)
    if training is not None:
        _write_curve_verdicts(rows, models, curves, training, out_dir, paths, design=design,
                              paper_last=last if compare_paper else None)
    if figures:
        # matplotlib is imported only when drawing: table-only reports stay quick to start
        from sigmarl.report.figures import (
            plot_distributions,
            plot_heatmap,
            plot_performance_profiles,
            plot_training_band,
            plot_training_curves,
        )

        scenarios = scenario_order(rows)
        paths["distributions"] = plot_distributions(
            rows[rows["model"].isin(models)], models, scenarios, out_dir / "distributions.png"
        )
        if curves is not None and len(curves):
            paths["training_curves"] = plot_training_curves(
                curves, out_dir / "training_curves.png", models,
                paper=paper_curves() if compare_paper else None,
            )
            paths["training_band"] = plot_training_band(curves, out_dir / "training_band.png", models)
        if len(scenarios) > 1 and len(models) > 1:
            paths["heatmap"] = plot_heatmap(summary, models, scenarios, out_dir / "heatmap.png")
        paths["performance_profiles"] = plot_performance_profiles(
            rows[rows["model"].isin(models)], models, scenarios, out_dir / "performance_profiles.png"
        )
    return Report(markdown, table, summary, composite, better, aggregates, statistics, training, paths, notes,
                  verdicts, verdicts_md)


def _write_curve_verdicts(rows: pd.DataFrame, models: list[str], curves: pd.DataFrame, training: pd.DataFrame,
                          out_dir: Path, paths: dict[str, Path], *, design: Design | None,
                          paper_last: dict[str, float] | None) -> None:
    """When the compared training curves part, and (`paper_last` given) whether the paper's one
    seed could be one of ours: curve_verdicts.md, curve_verdicts.csv and paper_seeds.csv."""
    design = _design(design, models)
    separation = separation_table(curves, design) if design.baseline in models else None
    seeds = None
    if paper_last is not None:
        obs = rows.drop_duplicates("model").set_index("model")["obs"].astype(str)
        seeds = paper_seed_table(training, paper_last, {m: paper_model_of(obs.get(m, "")) for m in models})
    text = curve_verdicts_markdown(*(x if x is not None else pd.DataFrame() for x in (separation, seeds)), design)
    if not text:
        return
    paths["curve_verdicts_md"] = out_dir / "curve_verdicts.md"
    paths["curve_verdicts_md"].write_text(text, encoding="utf-8")
    for key, frame in [("curve_verdicts", separation), ("paper_seeds", seeds)]:
        if frame is not None and len(frame):
            paths[key] = out_dir / f"{key}.csv"
            frame.to_csv(paths[key], index=False, float_format=FLOAT_FORMAT, lineterminator="\n")


def _design(design: Design | None, models: list[str]) -> Design:
    """The study's verdict design over the report's columns (default: against M0, or the first)."""
    return replace(design, variants=list(models)) if design is not None else \
        Design(variants=models, baseline="M0" if "M0" in models else models[0])


def _write_extras(rows: pd.DataFrame, models: list[str], curves: pd.DataFrame | None, out_dir: Path,
                  paths: dict[str, Path], *, trim: bool, design: Design | None
                  ) -> tuple[pd.DataFrame | None, str]:
    """The verdict table (and a factorial study's interactions), and the marl-eval export, beside
    the report's other files."""
    design = _design(design, models)
    verdicts, text = None, ""
    if design.baseline in models and design.compared:
        measured = trim_collisions(rows) if trim else rows
        verdicts = verdict_table(measured, design)
        text = verdicts_markdown(verdicts, design)
        paths["verdicts"] = out_dir / "verdicts.csv"
        verdicts.to_csv(paths["verdicts"], index=False, float_format=FLOAT_FORMAT, lineterminator="\n")
        interactions = interaction_table(measured, design) if design.interactions else None
        if interactions is not None and len(interactions):  # a factorial study's question
            text += "\n" + interactions_markdown(interactions, design)
            paths["interactions"] = out_dir / "interactions.csv"
            interactions.to_csv(paths["interactions"], index=False, float_format=FLOAT_FORMAT, lineterminator="\n")
        paths["verdicts_md"] = out_dir / "verdicts.md"
        paths["verdicts_md"].write_text(text, encoding="utf-8")
    chosen = rows[rows["model"].isin(models)]
    for key, name, data in [("marl_eval", "marl_eval.json", marl_eval_data(chosen, models, curves)),
                            ("marl_eval_intervals", "marl_eval_intervals.json", interval_data(chosen, models))]:
        paths[key] = out_dir / name
        paths[key].write_text(json.dumps(data, indent=1, allow_nan=False) + "\n", encoding="utf-8")
    return verdicts, text
