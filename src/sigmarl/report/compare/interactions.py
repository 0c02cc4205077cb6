"""Interactions of a factorial study: does a comparison change from one level of a factor to another?

A study whose variants have their own baselines (`study.baselines`) may set two comparisons
against each other (`study.interactions`: name -> [x, y]): x against its baseline and y
against its own, e.g. M4-paper against M0-paper and M4 against M0, to ask whether the paper's
rules change what leaving out the boundary distances does. The interaction is the difference
of the two differences, (x - bx) - (y - by), over the seed means of four independent groups.
Its standard error is the root of the sum of the two comparisons' squared standard errors,
and its degrees of freedom are Satterthwaite's over the four groups, which equal
se^4 / (se_x^4 / df_x + se_y^4 / df_y) for the two comparisons' Welch degrees of freedom.

Verdicts as for comparisons, over their own Holm family (every interaction, scenario and
metric): **differs** where the adjusted p of a zero interaction is <= alpha; **same within
+-margin** (the metric's equivalence margin) by two one-sided tests; otherwise undecided.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from sigmarl.metrics import shown_unit
from sigmarl.report.compare.verdicts import Design, comparisons, margin_unit
from sigmarl.report.format import p_text, signed
from sigmarl.stats.intervals import t_critical
from sigmarl.stats.tests import contrast, holm

COLUMNS = [
    "scenario", "metric", "interaction", "x", "x_baseline", "y", "y_baseline", "x_difference",
    "y_difference", "difference", "ci_low", "ci_high", "margin", "p_difference", "p_difference_holm",
    "p_equivalence", "p_equivalence_holm", "verdict",
]  # fmt: skip


def interaction_table(rows: pd.DataFrame, design: Design) -> pd.DataFrame:
    """One row per (scenario, metric, interaction) the rows can make, in that order."""
    tests = {(c.scenario, c.metric, c.variant): c.test for c in comparisons(rows, design)}
    records = []
    for (scenario, metric, variant), tx in tests.items():
        for name, (x, y) in design.interactions.items():
            if variant != x or (scenario, metric, y) not in tests:
                continue
            margin = design.margins[metric]
            t = contrast(tx, tests[(scenario, metric, y)], margin)
            se_ok = math.isfinite(t.df)
            half = t_critical(t.df, 1 - design.alpha) * t.se if se_ok else math.nan
            records.append({
                "scenario": scenario, "metric": metric, "interaction": name,
                "x": x, "x_baseline": design.baseline_of(x), "y": y, "y_baseline": design.baseline_of(y),
                "x_difference": t.variant_mean, "y_difference": t.baseline_mean, "difference": t.difference,
                "ci_low": t.difference - half, "ci_high": t.difference + half, "margin": margin,
                "p_difference": t.p_difference, "p_equivalence": t.p_equivalence,
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
        "difference of differences: the first minus the second, with Welch-Satterthwaite's t-interval over "
        "the seed means of the four groups. differs: a zero interaction rejected at Holm's level; same: two "
        "one-sided tests within the metric's margin; otherwise undecided.",
    ]
    return "\n".join(lines) + "\n"
