"""Per-simulation evaluation rows -> Table I's cells (per scenario, model and metric: the mean
over seeds of each seed's mean, with a two-level bootstrap interval over seeds and their
simulations, so seed-to-seed variation shows) and the paper's composite score per scenario.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import pandas as pd

from sigmarl.ablation import MODELS
from sigmarl.errors import SigmarlError
from sigmarl.metrics import (
    BY_NAME,
    COLLISION_COLUMNS,
    COMPOSITE,
    CS,
    HEADLINE,
    METRIC_COLUMNS,
    UNITS,
    scaled,
)
from sigmarl.scenarios import scenario_names
from sigmarl.stats import bootstrap as bs
from sigmarl.stats.bootstrap import mean_ci

SUMMARY_COLUMNS = ["scenario", "model", "metric", "unit", "mean", "ci_low", "ci_high", "std", "n", "n_seeds",
                   "seed_std", "trimmed"]


def validate_rows(rows: pd.DataFrame | None) -> pd.DataFrame:
    """The rows with the columns the report needs; a clear error for empty or malformed input."""
    if rows is None or len(rows) == 0:
        raise SigmarlError("no finished evaluation runs to report on (evaluate some models first, "
                           "e.g. with `sigmarl sweep` or `sigmarl evaluate`)")
    missing = [c for c in ("model", "scenario", *METRIC_COLUMNS) if c not in rows.columns]
    if missing:
        raise SigmarlError(f"evaluation rows lack the column(s) {', '.join(missing)}")
    rows = rows.reset_index(drop=True)  # trimming addresses rows by label
    if "seed" not in rows.columns:
        rows["seed"] = 0
    if "simulation" not in rows.columns:
        rows["simulation"] = rows.groupby(["scenario", "model", "seed"]).cumcount()
    rows["model"] = rows["model"].astype(str)
    rows["scenario"] = rows["scenario"].astype(str)
    for c in METRIC_COLUMNS:
        rows[c] = pd.to_numeric(rows[c], errors="coerce")
    return rows


def _known_first(present: list[str], known: list[str]) -> list[str]:
    """The study's own names in the study's order, then any others in order of appearance."""
    return [k for k in known if k in present] + [p for p in present if p not in known]


def label_order(present: list[str], known: list[str] | None = None) -> list[str]:
    """The study's labels in its declared order (default: the paper's M0..M5), each followed by
    the labels derived from it by a sweep over another key (`M0_hidden-64-64`, in natural order:
    8 before 16), then any others, also in natural order."""
    known = list(MODELS) if known is None else list(known)

    def base(label: str) -> int:
        return next((i for i, k in enumerate(known) if label == k or label.startswith(k + "_")), len(known))

    def natural(label: str) -> list:
        return [(0, int(t), "") if t.isdigit() else (1, 0, t) for t in re.split(r"(\d+)", label)]

    return sorted(present, key=lambda label: (base(label), label not in known,
                                              natural(label) if label not in known else []))


def model_order(rows: pd.DataFrame, models: list[str] | None = None,
                known: list[str] | None = None) -> list[str]:
    """`models` as given (checked against the rows), or every model in the rows in the study's
    order (`label_order`)."""
    present = list(dict.fromkeys(rows["model"]))
    if models is None:
        return label_order(present, known)
    models = [str(m) for m in models]
    if absent := [m for m in models if m not in present]:
        raise SigmarlError(f"no evaluation rows for model(s) {', '.join(absent)}; "
                           f"models with rows: {', '.join(_known_first(present, list(MODELS)))}")
    if len(set(models)) != len(models):
        raise SigmarlError(f"model list names a model twice: {', '.join(models)}")
    return models


def scenario_order(rows: pd.DataFrame) -> list[str]:
    """The rows' scenarios: Table I's four in the paper's order, then the others by name."""
    return _known_first(list(dict.fromkeys(rows["scenario"])), scenario_names())


def trim_collisions(rows: pd.DataFrame) -> pd.DataFrame:
    """Blank the collision rates of each evaluation's best and worst simulation.

    As in the paper, per (scenario, model, seed) the simulation with the lowest and the one
    with the highest headline rate (`metrics.HEADLINE`, CR_total) are dropped from all the
    collision-rate columns (the same two simulations, so that CR_total stays CR_AA + CR_AL);
    ties go to the lower simulation index. CD and AS keep every simulation. Evaluations of
    fewer than three simulations are left whole, since trimming would leave nothing to average.
    """
    rows = rows.copy()
    drop: list = []
    for _, g in rows.groupby(["scenario", "model", "seed"], sort=False):
        g = g.dropna(subset=[HEADLINE])
        if len(g) >= 3:
            ranked = g.sort_values([HEADLINE, "simulation"], kind="stable").index
            drop += [ranked[0], ranked[-1]]
    rows.loc[drop, list(COLLISION_COLUMNS)] = math.nan
    return rows


@dataclass
class Cell:
    """One (scenario, model): its rows per seed in report units, estimates and replicates.

    groups: per seed (ascending), an [n_sims, len(METRIC_COLUMNS)] array (collision rates in
    percent; NaN where trimmed); point: [K] estimates; replicates: [B, S, K] bootstrap
    replicates of the seeds' means (S seed slots drawn per replicate).
    """

    scenario: str
    model: str
    seeds: list
    groups: list[np.ndarray]
    point: np.ndarray
    replicates: np.ndarray

    def seed_means(self) -> np.ndarray:
        return bs.seed_means(self.groups)


def cells(rows: pd.DataFrame, models: list[str] | None = None, *, trim: bool = False,
          n_boot: int = bs.N_BOOT) -> list[Cell]:
    """Every (scenario, model) with rows, scenarios and models in report order."""
    rows = validate_rows(rows)
    models = model_order(rows, models)
    rows = rows[rows["model"].isin(models)]
    rows = trim_collisions(rows) if trim else rows
    out = []
    for scenario in scenario_order(rows):
        for model in models:
            g = rows[(rows["scenario"] == scenario) & (rows["model"] == model)]
            if g.empty:
                continue
            g = g.sort_values(["seed", "simulation"], kind="stable")
            values, seeds = scaled(g).to_numpy(), list(dict.fromkeys(g["seed"]))
            groups = [values[g["seed"].to_numpy() == s] for s in seeds]  # [n_sims, K] per seed
            reps = bs.replicate_means(groups, n_boot, bs.rng_for("cell", scenario, model, trim))
            out.append(Cell(scenario, model, seeds, groups, bs.point_estimate(groups), reps))
    return out


def summarise(cell_list: list[Cell], *, trim: bool = False) -> pd.DataFrame:
    """One row per (scenario, model, metric) of `cells`: estimate, interval, spread, counts."""
    records = []
    for c in cell_list:
        lo, hi = bs.percentile_interval(bs.mean_over_seeds(c.replicates), bs.LEVEL)
        per_seed = c.seed_means()
        for k, metric in enumerate(METRIC_COLUMNS):
            _, _, std, n = mean_ci(np.concatenate([g[:, k] for g in c.groups]), bs.LEVEL)
            seed_means = per_seed[:, k][np.isfinite(per_seed[:, k])]
            records.append({
                "scenario": c.scenario, "model": c.model, "metric": metric, "unit": UNITS[metric],
                "mean": float(c.point[k]), "ci_low": float(lo[k]), "ci_high": float(hi[k]), "std": std, "n": n,
                "n_seeds": len(seed_means), "seed_std": float(seed_means.std(ddof=1)) if len(seed_means) > 1 else math.nan,
                "trimmed": bool(trim and metric in COLLISION_COLUMNS)})
    return pd.DataFrame(records, columns=SUMMARY_COLUMNS)


def aggregate(rows: pd.DataFrame, models: list[str] | None = None, *, trim: bool = False) -> pd.DataFrame:
    """One row per (scenario, model, metric), collision rates in percent: `mean` over seeds of
    the seeds' means, `ci_low`/`ci_high` the two-level bootstrap percentile interval, `std` and
    `n` over the pooled simulations, `seed_std` over the per-seed means (NaN with one seed)."""
    return summarise(cells(rows, models, trim=trim), trim=trim)


@dataclass(frozen=True)
class CompositeScore:
    """Scores indexed by model (NaN where undefined) and a note explaining any gap."""

    scores: pd.Series
    note: str | None = None

    @property
    def defined(self) -> bool:
        return bool(self.scores.notna().any())


def composite_of(means: Mapping[str, Mapping[str, float] | pd.Series]) -> CompositeScore:
    """Composite scores (the paper's eq. 2) of the models in one scenario from their means of
    each composite metric (`metrics.COMPOSITE`: metric -> sign), given as metric -> {model: mean}:
    the sum of each metric over its mean across the models, with its sign. Units cancel, but the
    score depends on which models are in the table; a zero mean leaves it undefined, said in
    the note instead of dividing by zero."""
    frame = pd.DataFrame({name: pd.Series(means[name], dtype=float) for name in COMPOSITE})
    frame.index.name = "model"
    complete = frame.dropna()
    nan_scores = pd.Series(math.nan, index=frame.index, name=CS)
    notes = []
    if len(complete) < len(frame):
        left_out = ", ".join(map(str, frame.index.difference(complete.index, sort=False)))
        notes.append(f"no complete metrics for {left_out}: left out of the composite score")
    if complete.empty:
        return CompositeScore(nan_scores, "composite score undefined: no model has all metrics")
    if len(complete) == 1:  # each metric over its mean across one model is 1: the score says nothing
        return CompositeScore(nan_scores, "; ".join(["one model: nothing to compare, so no composite score, "
                                                     "probability of improvement or verdict", *notes]))
    mean = complete.mean()
    for name in COMPOSITE:
        if not mean[name] > 0:
            why = BY_NAME[name].zero_mean_note or f"composite score undefined: mean {name} is 0"
            return CompositeScore(nan_scores, "; ".join([why, *notes]))
    scores = sum(sign * complete[name] / mean[name] for name, sign in COMPOSITE.items())  # in the metrics' order
    return CompositeScore(scores.reindex(frame.index).rename(CS), "; ".join(notes) or None)


def composite_scores(summary: pd.DataFrame) -> pd.DataFrame:
    """Per scenario of an `aggregate` summary: columns scenario, model, CS, note."""
    parts = []
    for scenario, g in summary.groupby("scenario", sort=False):
        means = g.pivot(index="model", columns="metric", values="mean").reindex(list(dict.fromkeys(g["model"])))
        result = composite_of({name: means[name] for name in COMPOSITE})
        parts.append(pd.DataFrame({"scenario": scenario, "model": result.scores.index,
                                   CS: result.scores.to_numpy(), "note": result.note or ""}))
    return pd.concat(parts, ignore_index=True) if parts else pd.DataFrame(columns=["scenario", "model", CS, "note"])
