"""Interactions of a factorial study: does a comparison change from one level of a factor to another?

A study whose variants have their own baselines (`study.baselines`) may set two comparisons
against each other (`study.interactions`: name -> [x, y]): x against its baseline and y
against its own, e.g. M4-paper against M0-paper and M4 against M0, to ask whether the paper's
rules change what leaving out the boundary distances does. The interaction is the difference
of the two differences, (x - bx) - (y - by), over the seed means of four independent groups,
decided by the comparison engine (`sigmarl.stats.engine.interaction`: each group resampled from
its own seeds under the null), with its bootstrap-t interval.

Verdicts as for comparisons, over their own Holm family (every interaction, scenario and
metric): **differs** where the adjusted p of a zero interaction is <= alpha; **same within
+-margin** (the metric's equivalence margin) by two one-sided tests; otherwise undecided.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd

from sigmarl.metrics import shown_unit
from sigmarl.report.compare.verdicts import Design, margin_unit, seed_values
from sigmarl.report.tables import p_text, signed
from sigmarl.stats.engine import Null, holm, interaction

COLUMNS = [
    "scenario", "metric", "interaction", "x", "x_baseline", "y", "y_baseline", "x_difference",
    "y_difference", "difference", "ci_low", "ci_high", "margin", "p_difference", "p_difference_holm",
    "p_equivalence", "p_equivalence_holm", "verdict",
]  # fmt: skip


def interaction_table(rows: pd.DataFrame, design: Design) -> pd.DataFrame:
    """One row per (scenario, metric, interaction) the rows can make, in that order."""
    scenarios = list(design.scenarios) if design.scenarios is not None else list(dict.fromkeys(rows["scenario"]))
    records = []
    for metric in design.metrics:
        values = seed_values(rows, metric)
        margin = design.margins[metric]
        for scenario in scenarios:
            for name, (x, y) in design.interactions.items():
                labels = (x, design.baseline_of(x), y, design.baseline_of(y))
                groups = [values.get((m, scenario)) for m in labels]
                if any(not g for g in groups):
                    continue
                r = interaction(*([g.mean() for g in gs] for gs in groups),
                                {"zero": Null(0.0), "above": Null(-margin, "greater"), "below": Null(margin, "less")},
                                1 - design.alpha)
                means = [float(np.mean([g.mean() for g in gs])) for gs in groups]
                records.append({
                    "scenario": scenario, "metric": metric, "interaction": name, "x": x, "x_baseline": labels[1],
                    "y": y, "y_baseline": labels[3], "x_difference": means[0] - means[1],
                    "y_difference": means[2] - means[3], "difference": r.estimate, "ci_low": r.ci_low,
                    "ci_high": r.ci_high, "margin": margin, "p_difference": r.p["zero"],
                    "p_equivalence": max(r.p["above"], r.p["below"]),
                })
    frame = pd.DataFrame(records, columns=COLUMNS)
    if len(frame):
        frame["p_difference_holm"] = holm(frame["p_difference"].to_numpy())
        frame["p_equivalence_holm"] = holm(frame["p_equivalence"].to_numpy())
        frame["verdict"] = [
            "differs" if pd_ <= design.alpha else "same" if pe <= design.alpha else "undecided"
            for pd_, pe in zip(np.nan_to_num(frame["p_difference_holm"], nan=1.0),
                               np.nan_to_num(frame["p_equivalence_holm"], nan=1.0), strict=True)
        ]
    return frame


def interactions_markdown(table: pd.DataFrame, design: Design) -> str:
    lines = [
        f"Interactions: does a comparison change between the two levels? (difference of differences; "
        f"{len(table)} tests, Holm-corrected; α = {design.alpha:g}):",
        "",
        "| Scenario | Metric | Interaction | first difference | second difference | difference of differences "
        "[95% CI] | p (Holm) | p same (Holm) | verdict |",
        "|---|---|---|---|---|---|---:|---:|---|",
    ]
    for _, r in table.iterrows():
        unit = shown_unit(r["metric"])
        verdict = f"same within ±{r['margin']:g} {margin_unit(r['metric'])}" if r["verdict"] == "same" \
            else str(r["verdict"])
        lines.append(
            f"| {r['scenario']} | {r['metric']} ({unit}) | {r['interaction']} | {r['x']} − {r['x_baseline']}: "
            f"{signed(r['x_difference'])} | {r['y']} − {r['y_baseline']}: {signed(r['y_difference'])} | "
            f"{signed(r['difference'])} [{signed(r['ci_low'])}, {signed(r['ci_high'])}] | "
            f"{p_text(r['p_difference'])} ({p_text(r['p_difference_holm'])}) | {p_text(r['p_equivalence'])} "
            f"({p_text(r['p_equivalence_holm'])}) | {verdict} |"
        )
    lines += [
        "",
        "difference of differences: the first minus the second, over the seed means of the four groups, with "
        "the comparison engine's bootstrap-t interval (each group resampled from its own seeds; "
        "docs/concepts.md). differs: a zero interaction rejected at Holm's level; same: two one-sided tests "
        "within the metric's margin; otherwise undecided (always with one seed in a group).",
    ]
    return "\n".join(lines) + "\n"


# A claim of the replication table (Mk - M0) beside the study's interaction on it: Mk - M0 under
# another condition (x against its own baseline) against ours (y = Mk against M0), CR_total.
CLAIM_COLUMNS = ["interaction", "interaction_seeds", "interaction_difference", "interaction_ci_low",
                 "interaction_ci_high", "p_interaction", "interaction_verdict"]
PAPERS_WAY, AGAINST = "paper's direction", "against the paper's direction"


def claim_interactions(trimmed: pd.DataFrame, design: Design, claims: pd.DataFrame, baseline: str) -> pd.DataFrame:
    """`CLAIM_COLUMNS` per row of `claims` (the replication table's), from the design's
    interactions whose y is the claim's model compared with `baseline`, on CR_total per scenario
    (the engine's test over their own Holm family). The verdict: **paper's direction** where a zero
    interaction is rejected and it moves Mk - M0 the way the paper's difference lies, **against
    the paper's direction** where it is rejected the other way, **same** within the margin, else
    **undecided** (always with one seed in a group). Empty where the claim has no interaction."""
    chosen = {name: (x, y) for name, (x, y) in design.interactions.items() if design.baseline_of(y) == baseline}
    out = pd.DataFrame(index=claims.index, columns=CLAIM_COLUMNS)
    if not chosen:
        return out
    table = interaction_table(trimmed, replace(design, interactions=chosen, metrics=("CR_total",), scenarios=None))
    by_claim = {(r["scenario"], r["y"]): r for _, r in table.iterrows()}
    groups = trimmed.groupby("model")["seed"].nunique()
    for i, claim in claims.iterrows():
        r = by_claim.get((claim["scenario"], claim["model"]))
        if r is None or claim["claim"] != "difference":
            continue
        seeds = "/".join(str(int(groups.get(m, 0))) for m in (r["x"], r["x_baseline"], r["y"], r["y_baseline"]))
        way = r["difference"] * claim["paper"] > 0
        verdict = (PAPERS_WAY if way else AGAINST) if r["verdict"] == "differs" else r["verdict"]
        out.loc[i] = [r["x"], seeds, r["difference"], r["ci_low"], r["ci_high"], r["p_difference_holm"], verdict]
    return out


def claim_interactions_lines(table: pd.DataFrame) -> list[str]:
    """The claims that have an interaction, as a Markdown table (none: no lines)."""
    rows = table[table["interaction_verdict"].notna() & (table["interaction_verdict"] != "")]
    if not len(rows):
        return []
    lines = ["", "Does the other condition explain a claim? Its Mk − M0 against ours (x: the condition's column; "
             f"difference of differences, CR_total in pp, the comparison engine, {len(rows)} tests Holm-corrected):",
             "", "| Scenario | Model | x | seeds x / its M0 / Mk / M0 | paper | difference of differences [95% CI] "
             "| p (Holm) | verdict |", "|---|---|---|---|---:|---|---:|---|"]
    for _, r in rows.iterrows():
        lines.append(f"| {r['scenario']} | {r['model']} | {r['interaction']} | {r['interaction_seeds']} | "
                     f"{signed(r['paper'], 2)} | {signed(r['interaction_difference'], 2)} "
                     f"[{signed(r['interaction_ci_low'], 2)}, {signed(r['interaction_ci_high'], 2)}] | "
                     f"{p_text(r['p_interaction'])} | {r['interaction_verdict']} |")
    lines += ["", "paper's direction: a zero interaction rejected at Holm's level, the condition moving Mk − M0 the "
              "way the paper's difference lies (then a claim that does not reproduce is explained by it, "
              "paper_policies.md); against the paper's direction: rejected the other way; same: within the margin by "
              "two one-sided tests; else undecided (always with one seed in a group)."]
    return lines
