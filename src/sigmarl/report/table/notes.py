"""The lines under the results table that say what its numbers are: seeds and simulations per
cell, trimming, missing rows, and what the paper's numbers in parentheses can be compared with."""

from __future__ import annotations

import pandas as pd

from sigmarl.ablation import MODELS
from sigmarl.metrics import units_text


def table_notes(
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
    by_note: dict[str, list[str]] = {}  # a note once, naming its scenarios unless it holds for all
    groups = list(composite.groupby("scenario", sort=False))
    for scenario, g in groups:
        absent = [m for m in models if m not in set(g["model"])]
        if absent:  # the scores then compare fewer models than the table's columns
            by_note.setdefault(f"no evaluation rows for {', '.join(absent)}", []).append(scenario)
        for note in dict.fromkeys(g["note"]):
            if note:
                by_note.setdefault(note, []).append(scenario)
    for note, where in by_note.items():
        everywhere = len(where) == len(groups) > 1
        notes.append(f"{'All scenarios' if everywhere else ', '.join(where)}: {note}.")
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
