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

# Metric -> why the score is undefined when that metric's mean over the models is zero.
_ZERO_MEAN_NOTES = {
    "CR_total": "composite score undefined: no model collided (mean CR_total is 0)",
    "CD": "composite score undefined: mean center-line deviation CD is 0",
    "AS": "composite score undefined: no model moved (mean AS is 0)",
}


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
    frame = pd.DataFrame(
        {
            "CR_total": pd.Series(cr_total, dtype=float),
            "CD": pd.Series(cd, dtype=float),
            "AS": pd.Series(avg_speed, dtype=float),
        }
    )
    frame.index.name = "model"
    complete = frame.dropna()
    nan_scores = pd.Series(math.nan, index=frame.index, name="CS")
    notes = []
    if len(complete) < len(frame):
        left_out = ", ".join(map(str, frame.index.difference(complete.index, sort=False)))
        notes.append(f"no complete metrics for {left_out}: left out of the composite score")
    if complete.empty:
        return CompositeScore(nan_scores, "composite score undefined: no model has all metrics")
    means = complete.mean()
    for metric, why in _ZERO_MEAN_NOTES.items():
        if not means[metric] > 0:
            return CompositeScore(nan_scores, "; ".join([why, *notes]))
    scores = (
        -complete["CR_total"] / means["CR_total"]
        - complete["CD"] / means["CD"]
        + complete["AS"] / means["AS"]
    )
    if len(complete) == 1:
        notes.append("with a single model the composite score is always -1")
    return CompositeScore(scores.reindex(frame.index).rename("CS"), "; ".join(notes) or None)


def composite_scores(summary: pd.DataFrame) -> pd.DataFrame:
    """Per scenario of an `aggregate` summary: columns scenario, model, CS, note."""
    parts = []
    for scenario, g in summary.groupby("scenario", sort=False):
        means = g.pivot(index="model", columns="metric", values="mean")
        means = means.reindex(list(dict.fromkeys(g["model"])))
        result = composite_score(means["CR_total"], means["CD"], means["AS"])
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
