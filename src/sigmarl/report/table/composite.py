"""The paper's composite score (eq. 2), per scenario over the models compared.

CS_m = -CR_total,m / mean_j CR_total,j - CD_m / mean_j CD_j + AS_m / mean_j AS_j.
Each metric is divided by its mean over the compared models, so units cancel (percent or
fraction, cm or paper units give the same score) but the score depends on which models
are in the table. When a mean is zero the score has no meaning; we say so instead of
dividing by zero.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import pandas as pd

from sigmarl.metrics import BY_NAME, COMPOSITE


@dataclass(frozen=True)
class CompositeScore:
    """Scores indexed by model (NaN where undefined) and a note explaining any gap."""

    scores: pd.Series
    note: str | None = None

    @property
    def defined(self) -> bool:
        return bool(self.scores.notna().any())


def composite_score(
    cr_total: Mapping[str, float] | pd.Series,
    cd: Mapping[str, float] | pd.Series,
    avg_speed: Mapping[str, float] | pd.Series,
) -> CompositeScore:
    """Composite scores of the models in one scenario from their mean CR_total, CD and AS."""
    return composite_of({"CR_total": cr_total, "CD": cd, "AS": avg_speed})


def composite_of(means: Mapping[str, Mapping[str, float] | pd.Series]) -> CompositeScore:
    """Composite scores of the models in one scenario from their means of each composite
    metric (`sigmarl.metrics.COMPOSITE`: metric -> sign), given as metric -> {model: mean}."""
    frame = pd.DataFrame({name: pd.Series(means[name], dtype=float) for name in COMPOSITE})
    frame.index.name = "model"
    complete = frame.dropna()
    nan_scores = pd.Series(math.nan, index=frame.index, name="CS")
    notes = []
    if len(complete) < len(frame):
        left_out = ", ".join(map(str, frame.index.difference(complete.index, sort=False)))
        notes.append(f"no complete metrics for {left_out}: left out of the composite score")
    if complete.empty:
        return CompositeScore(nan_scores, "composite score undefined: no model has all metrics")
    if len(complete) == 1:  # each metric over its mean across one model is 1: the score says nothing
        return CompositeScore(nan_scores, "; ".join(["one model: nothing to compare, so no composite score, probability of improvement or verdict",
                                                    *notes]))
    mean = complete.mean()
    for name in COMPOSITE:
        if not mean[name] > 0:
            why = BY_NAME[name].zero_mean_note or f"composite score undefined: mean {name} is 0"
            return CompositeScore(nan_scores, "; ".join([why, *notes]))
    scores = None
    for name, sign in COMPOSITE.items():  # sign x (value / mean), summed in the metrics' order
        term = complete[name] / mean[name]
        scores = (-term if sign < 0 else term) if scores is None else \
            (scores - term if sign < 0 else scores + term)
    return CompositeScore(scores.reindex(frame.index).rename("CS"), "; ".join(notes) or None)


def composite_scores(summary: pd.DataFrame) -> pd.DataFrame:
    """Per scenario of an `aggregate` summary: columns scenario, model, CS, note."""
    parts = []
    for scenario, g in summary.groupby("scenario", sort=False):
        means = g.pivot(index="model", columns="metric", values="mean")
        means = means.reindex(list(dict.fromkeys(g["model"])))
        result = composite_of({name: means[name] for name in COMPOSITE})
        parts.append(
            pd.DataFrame(
                {
                    "scenario": scenario,
                    "model": result.scores.index,
                    "CS": result.scores.to_numpy(),
                    "note": result.note or "",
                }
            )
        )
    return (
        pd.concat(parts, ignore_index=True)
        if parts
        else pd.DataFrame(columns=["scenario", "model", "CS", "note"])
    )
