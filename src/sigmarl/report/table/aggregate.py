"""Per-simulation evaluation rows -> per (scenario, model, metric) estimates with 95% intervals.

A cell's estimate is the mean over seeds of each seed's mean over simulations; its interval
is a two-level bootstrap over seeds and their simulations (`sigmarl.stats.bootstrap`), so
it reflects the seed-to-seed variation that pooled simulations would hide.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np
import pandas as pd

from sigmarl.ablation import MODELS
from sigmarl.errors import SigmarlError
from sigmarl.metrics import COLLISION_COLUMNS, METRIC_COLUMNS, UNITS, scaled
from sigmarl.scenarios import scenario_names
from sigmarl.stats import bootstrap as bs
from sigmarl.stats.intervals import mean_ci

SUMMARY_COLUMNS = [
    "scenario", "model", "metric", "unit", "mean", "ci_low", "ci_high", "std", "n", "n_seeds", "seed_std",
    "trimmed",
]  # fmt: skip


def validate_rows(rows: pd.DataFrame | None) -> pd.DataFrame:
    """The rows with the columns the report needs; a clear error for empty or malformed input."""
    if rows is None or len(rows) == 0:
        raise SigmarlError(
            "no finished evaluation runs to report on (evaluate some models first, "
            "e.g. with `sigmarl sweep` or `sigmarl evaluate`)"
        )
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
        for i, k in enumerate(known):
            if label == k or label.startswith(k + "_"):
                return i
        return len(known)

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
    absent = [m for m in models if m not in present]
    if absent:
        raise SigmarlError(
            f"no evaluation rows for model(s) {', '.join(absent)}; "
            f"models with rows: {', '.join(_known_first(present, list(MODELS)))}"
        )
    if len(set(models)) != len(models):
        raise SigmarlError(f"model list names a model twice: {', '.join(models)}")
    return models


def scenario_order(rows: pd.DataFrame) -> list[str]:
    """The rows' scenarios: Table I's four in the paper's order, then the others by name."""
    return _known_first(list(dict.fromkeys(rows["scenario"])), scenario_names())


def trim_collisions(rows: pd.DataFrame) -> pd.DataFrame:
    """Blank the collision rates of each evaluation's best and worst simulation.

    As in the paper, per (scenario, model, seed) the simulation with the lowest and the one
    with the highest CR_total are dropped from all three collision-rate columns (the same
    two simulations, so that CR_total stays CR_AA + CR_AL); ties go to the lower
    simulation index. CD and AS keep every simulation. Evaluations of fewer than three
    simulations are left whole, since trimming would leave nothing to average.
    """
    rows = rows.copy()
    drop: list = []
    for _, g in rows.groupby(["scenario", "model", "seed"], sort=False):
        g = g.dropna(subset=["CR_total"])
        if len(g) < 3:
            continue
        ranked = g.sort_values(["CR_total", "simulation"], kind="stable").index
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


def seed_groups(rows: pd.DataFrame) -> tuple[list, list[np.ndarray]]:
    """The seeds of one cell's rows (ascending) and their [n_sims, K] metric arrays."""
    ordered = rows.sort_values(["seed", "simulation"], kind="stable")
    values = scaled(ordered).to_numpy()
    seeds = list(dict.fromkeys(ordered["seed"]))
    keys = ordered["seed"].to_numpy()
    return seeds, [values[keys == s] for s in seeds]


def cells(
    rows: pd.DataFrame,
    models: list[str] | None = None,
    *,
    trim: bool = False,
    n_boot: int = bs.N_BOOT,
) -> list[Cell]:
    """Every (scenario, model) with rows, scenarios and models in report order."""
    rows = validate_rows(rows)
    models = model_order(rows, models)
    rows = rows[rows["model"].isin(models)]
    if trim:
        rows = trim_collisions(rows)
    out = []
    for scenario in scenario_order(rows):
        for model in models:
            g = rows[(rows["scenario"] == scenario) & (rows["model"] == model)]
            if g.empty:
                continue
            seeds, groups = seed_groups(g)
            reps = bs.replicate_means(groups, n_boot, bs.rng_for("cell", scenario, model, trim))
            out.append(Cell(scenario, model, seeds, groups, bs.point_estimate(groups), reps))
    return out


def summarise(cell_list: list[Cell], *, trim: bool = False, level: float = bs.LEVEL) -> pd.DataFrame:
    """One row per (scenario, model, metric) of `cells`: estimate, interval, spread, counts."""
    records = []
    for c in cell_list:
        lo, hi = bs.percentile_interval(bs.mean_over_seeds(c.replicates), level)
        per_seed = c.seed_means()
        for k, metric in enumerate(METRIC_COLUMNS):
            _, _, std, n = mean_ci(np.concatenate([g[:, k] for g in c.groups]), level)
            seed_means = per_seed[:, k][np.isfinite(per_seed[:, k])]
            records.append(
                {
                    "scenario": c.scenario,
                    "model": c.model,
                    "metric": metric,
                    "unit": UNITS[metric],
                    "mean": float(c.point[k]),
                    "ci_low": float(lo[k]),
                    "ci_high": float(hi[k]),
                    "std": std,
                    "n": n,
                    "n_seeds": len(seed_means),
                    "seed_std": float(seed_means.std(ddof=1)) if len(seed_means) > 1 else math.nan,
                    "trimmed": bool(trim and metric in COLLISION_COLUMNS),
                }
            )
    return pd.DataFrame(records, columns=SUMMARY_COLUMNS)


def aggregate(
    rows: pd.DataFrame,
    models: list[str] | None = None,
    *,
    trim: bool = False,
    level: float = bs.LEVEL,
    n_boot: int = bs.N_BOOT,
) -> pd.DataFrame:
    """One row per (scenario, model, metric): estimate, `level` interval, std, n, seed spread.

    Collision rates come in as fractions of steps and go out in percent. `mean` is the mean
    over seeds of the seeds' means over simulations; `ci_low`/`ci_high` the two-level
    bootstrap percentile interval; `std` and `n` are over the pooled simulations; `seed_std`
    is the sample standard deviation of the per-seed means (NaN with one seed).
    """
    return summarise(cells(rows, models, trim=trim, n_boot=n_boot), trim=trim, level=level)
