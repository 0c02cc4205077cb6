"""The comparisons' sections of the report: verdicts, findings, training curves compared, and
whether the paper's claims reproduce."""

from __future__ import annotations

import pandas as pd

from sigmarl.report.compare.curve_verdicts import (
    curve_verdicts_markdown,
    paper_seed_table,
    separation_table,
)
from sigmarl.report.compare.findings import findings_markdown
from sigmarl.report.compare.interactions import interaction_table, interactions_markdown
from sigmarl.report.compare.replication import replication_markdown, replication_table
from sigmarl.report.compare.verdicts import verdict_table, verdicts_markdown
from sigmarl.report.draft import Draft, Section
from sigmarl.report.table.aggregate import trim_collisions
from sigmarl.report.table.paper import paper_curves
from sigmarl.report.table.training import paper_last_rewards


def verdicts_section(d: Draft) -> None:
    """One verdict per comparison and, for a factorial study, its interactions."""
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
    """What the study found, in sentences of its own figures."""
    if d.summary is None or not len(d.summary):
        return
    d.write("findings", "findings.md", findings_markdown(d.summary, d.verdicts, d.models, d.baseline,
                                                        d.design.alpha))


def curve_verdicts_section(d: Draft) -> None:
    """When the compared training curves part, and whether the paper's one seed could be ours."""
    if d.training is None:
        return
    design = d.design
    separation = separation_table(d.curves, design) if design.baseline in d.models else None
    seeds = None
    if d.options.compare_paper:
        seeds = paper_seed_table(d.training, paper_last_rewards(paper_curves()), d.paper_models)
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
    table = replication_table(d.rows, own, "M0", d.design.alpha, d.design)
    d.write("replication", "replication.csv", table)
    d.write("replication_md", "replication.md", replication_markdown(table, d.design.alpha) if len(table) else None)


VERDICTS = Section("verdicts", {
    "verdicts.csv": "each comparison (variant against its baseline, per scenario and metric): the difference "
                    "with the comparison engine's interval and p-values, Welch's p, the verdict and the seeds it needs",
    "verdicts.md": "the same as Markdown, a factorial study's interactions under it",
    "interactions.csv": "a factorial study's interactions (difference of differences)"},
    verdicts_section, when="with a baseline and a variant to compare")

FINDINGS = Section("findings", {
    "findings.md": "the study's figures in sentences: seeds per model, the baseline's worst collision rate and "
                   "speed range, each variant's verdicts (the results pages quote it)"}, findings_section)

CURVE_VERDICTS = Section("curve_verdicts", {
    "curve_verdicts.csv": "each compared variant's reward against its baseline's per window of 25 iterations "
                          "(the comparison engine, Holm-adjusted)",
    "curve_verdicts.md": "the same as Markdown, and where the curves part",
    "paper_seeds.csv": "with `--compare-paper`: whether the paper's one seed could be one of ours"},
    curve_verdicts_section, when="when training curves are read")

REPLICATION = Section("replication", {
    "replication.csv": "per claim of the paper's Table I (each M1..M5 minus M0 CR_total per scenario, each "
                       "scenario's best composite score; Table I's struck-out values listed apart): the paper's "
                       "number, ours with its interval, the paper's percentile and p among our one-seed "
                       "differences, the comparison engine's four one-sided Holm-adjusted p-values, the verdict "
                       "and its explanation (collision rates trimmed as the paper's); in a study that declares "
                       "an interaction on a claim's model (`study=paper_reward`: Mk - M0 under the paper's reward "
                       "against ours), `interaction_*`: its difference of differences, interval, Holm-adjusted p "
                       "and verdict (paper's direction, against it, same, undecided)",
    "replication.md": "the same as Markdown, the interactions in a table of their own"},
    replication_section, when="with `--compare-paper`, over the columns that are the paper's own models, M0 among them")
