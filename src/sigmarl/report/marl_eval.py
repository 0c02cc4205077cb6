"""The evaluation as marl-eval's raw-data JSON (Gorsane et al. 2022), and its intervals with
the real number of runs.

marl-eval reads environment -> task -> algorithm -> run -> step -> metrics, each metric a list
over evaluation episodes: here "sigmarl" -> scenario -> model -> "run_<seed>" -> "step_0" (its
step_count the training iterations where known) and "absolute_metrics", the per-simulation values
in the rows' units. Its loader takes every algorithm's run names from the first one, so a file
whose models have different seeds does not load (KeyError 'run_3'): `export_files` writes the
seeds every model has to `marl_eval.json` and each group of models with a larger seed set to
`marl_eval_<models>.json`. Its interval helper assumes n = 10 runs and z = 1.96; the sidecar
`marl_eval_intervals.json` gives the real n (seeds) and z = t_(0.975, n - 1).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from sigmarl.metrics import METRIC_COLUMNS, ROW_UNITS
from sigmarl.stats.bootstrap import t_critical

ENVIRONMENT = "sigmarl"
LEVEL = 0.95


def _clean(values: np.ndarray) -> list[float | None]:
    return [float(v) if math.isfinite(v) else None for v in values]


def _tasks(rows: pd.DataFrame, models: list[str]):
    """(scenario, model, its rows) for each model with rows, scenarios in the rows' order."""
    for scenario in dict.fromkeys(rows["scenario"]):
        sc = rows[rows["scenario"] == scenario]
        for model in models:
            if len(mine := sc[sc["model"] == model]):
                yield str(scenario), model, mine


def marl_eval_data(rows: pd.DataFrame, models: list[str], curves: pd.DataFrame | None = None) -> dict:
    """The nested dict marl-eval reads (JSON-serialisable)."""
    iterations = {}
    if curves is not None and len(curves) and "seed" in curves.columns:
        iterations = curves.groupby(["model", "seed"])["iteration"].max().to_dict()
    metrics = [m for m in METRIC_COLUMNS if m in rows.columns]
    tasks: dict = {}
    for scenario, model, mine in _tasks(rows, models):
        for seed, g in mine.sort_values(["seed", "simulation"], kind="stable").groupby("seed", sort=True):
            values = {m: _clean(g[m].to_numpy(float)) for m in metrics}
            step = {"step_count": int(iterations.get((model, seed), 0)), **values}
            run = {"step_0": step, "absolute_metrics": dict(values)}
            tasks.setdefault(scenario, {}).setdefault(model, {})[f"run_{int(seed)}"] = run
    return {ENVIRONMENT: tasks}


def seed_groups(rows: pd.DataFrame, models: list[str]) -> dict[str, tuple[list[str], list[int]]]:
    """File name -> (models, seeds) of the split export: the seeds every model has, then one
    file per group of models with the same, larger seed set (models in the study's order)."""
    seeds = {m: tuple(sorted(int(s) for s in rows.loc[rows["model"] == m, "seed"].unique())) for m in models}
    seeds = {m: s for m, s in seeds.items() if s}
    if not seeds:
        return {}
    common = sorted(set.intersection(*(set(s) for s in seeds.values())))
    files = {"marl_eval.json": (list(seeds), common)} if common else {}
    by_set: dict[tuple[int, ...], list[str]] = {}
    for m, s in seeds.items():
        by_set.setdefault(s, []).append(m)
    for s, group in by_set.items():
        if list(s) != common:
            files["marl_eval_" + "_".join(group) + ".json"] = (group, list(s))
    return files


def export_files(rows: pd.DataFrame, models: list[str], curves: pd.DataFrame | None = None) -> dict[str, dict]:
    """File name -> marl-eval JSON, each with equal run names for all its algorithms."""
    out = {}
    for name, (group, seeds) in seed_groups(rows, models).items():
        mine = rows[rows["model"].isin(group) & rows["seed"].isin(seeds)]
        out[name] = marl_eval_data(mine, group, curves)
    return out


def interval_data(rows: pd.DataFrame, models: list[str]) -> dict:
    """Per task, algorithm and metric: mean over seeds, n seeds, z = t quantile, half-width."""
    out: dict = {"environment": ENVIRONMENT, "level": LEVEL, "units": ROW_UNITS,
                 "note": "mean over seeds of each seed's mean over its simulations; half_width = "
                         "z * sd(seed means) / sqrt(n), z the Student t quantile with n - 1 degrees "
                         "of freedom (marl-eval's own helper assumes n = 10 and z = 1.96)",
                 "files": {name: {"models": group, "seeds": seeds}
                           for name, (group, seeds) in seed_groups(rows, models).items()},
                 "tasks": {}}
    metrics = [m for m in METRIC_COLUMNS if m in rows.columns]
    for scenario, model, mine in _tasks(rows, models):
        means = mine.groupby("seed")[metrics].mean()
        entry = {}
        for m in metrics:
            v = means[m].to_numpy(float)
            v = v[np.isfinite(v)]
            n = len(v)
            z = t_critical(n - 1, LEVEL) if n > 1 else None
            entry[m] = {"mean": float(v.mean()) if n else None, "n": n, "z": z,
                        "half_width": z * float(v.std(ddof=1)) / math.sqrt(n) if z else None}
        out["tasks"].setdefault(scenario, {})[model] = entry
    return out
