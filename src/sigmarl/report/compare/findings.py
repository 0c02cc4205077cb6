"""What a study found, in sentences built from its own numbers (`findings.md`).

A results page quotes this file verbatim between markers (scripts/results_blocks.py), so the
figures of its prose are generated, never typed: the seeds behind each model, the baseline's
worst collision rate and its speed range, and each variant's verdicts per scenario.
"""

from __future__ import annotations

import pandas as pd

from sigmarl.metrics import label

TOTAL = "CR_total"
SPEED = "AS"


def _join(names: list[str]) -> str:
    """"A", "A and B", "A, B and C"."""
    return names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]


def _seeds_sentence(summary: pd.DataFrame, models: list[str]) -> str:
    seeds = summary.groupby("model")["n_seeds"].max()
    counts = [f"{m} {int(seeds[m])}" for m in models if m in seeds.index]
    return f"Seeds per model: {', '.join(counts)}."


def _baseline_sentence(summary: pd.DataFrame, baseline: str, n_scenarios: int) -> str | None:
    mine = summary[summary["model"] == baseline].set_index(["metric", "scenario"])["mean"]
    if TOTAL not in mine.index.get_level_values(0):
        return None
    total = mine[TOTAL]
    text = (f"{baseline}'s total collision rate is at most {total.max():.2f} % on each of the "
            f"{n_scenarios} scenarios (worst: {total.idxmax()}, best: {total.idxmin()} at {total.min():.2f} %)")
    if SPEED in mine.index.get_level_values(0):
        speed = mine[SPEED]
        text += f", at an average speed of {speed.min():.2f}–{speed.max():.2f} m/s"
    return text + "."


def _verdict_sentences(verdicts: pd.DataFrame, baseline: str, n_scenarios: int) -> list[str]:
    """Per variant and metric: the scenarios of each verdict, "on all four" when all agree."""
    out = []
    for (metric, variant), g in verdicts.groupby(["metric", "variant"], sort=False):
        parts = []
        for verdict, scenarios in g.groupby("verdict", sort=False)["scenario"]:
            where = "on every scenario" if len(scenarios) == n_scenarios else "on " + _join(list(scenarios))
            parts.append(f"{verdict} {where}")
        n = g[["n_variant", "n_baseline"]].iloc[0]
        out.append(f"- {variant} against {g['baseline'].iloc[0]} ({label(metric)}, {int(n.n_variant)} "
                   f"against {int(n.n_baseline)} seeds): {'; '.join(parts)}.")
    return out


def findings_markdown(summary: pd.DataFrame, verdicts: pd.DataFrame | None, models: list[str],
                      baseline: str | None, alpha: float = 0.05) -> str:
    """The findings as Markdown: a paragraph of figures, then one line per compared variant."""
    scenarios = list(dict.fromkeys(summary["scenario"]))
    lines = [_seeds_sentence(summary, models)]
    if baseline is not None:
        sentence = _baseline_sentence(summary, baseline, len(scenarios))
        if sentence:
            lines.append(sentence)
    text = " ".join(lines) + "\n"
    if verdicts is not None and len(verdicts):
        tests = ("Verdicts (two-sided permutation tests of the difference of seed means, "
                 f"Holm-adjusted across all {len(verdicts)} comparisons, α = {alpha:g}):")
        text += "\n" + tests + "\n\n" + "\n".join(_verdict_sentences(verdicts, baseline or "", len(scenarios))) + "\n"
    return text
