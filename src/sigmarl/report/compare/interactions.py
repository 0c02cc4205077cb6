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

import numpy as np
import pandas as pd

from sigmarl.metrics import shown_unit
from sigmarl.report.compare.verdicts import Design, margin_unit, seed_values
from sigmarl.report.format import p_text, signed
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
