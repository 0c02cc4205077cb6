"""The paper's Table I as shipped reference data (CD already in real centimetres)."""

from __future__ import annotations

from importlib import resources

import pandas as pd

PAPER_TABLE = "paper_table_1.csv"
PAPER_CURVES = "paper_training_curves.csv"  # the paper's Fig. 5, one seed per model


def paper_table() -> pd.DataFrame:
    """The paper's numbers: index (scenario, metric), a `unit` column, then M0..M5.

    Collision rates in percent (trimmed as the paper did), CD in cm, AS in m/s, CS unitless.
    """
    source = resources.files("sigmarl").joinpath("data").joinpath(PAPER_TABLE)
    with source.open("r", encoding="utf-8") as f:
        table = pd.read_csv(f, comment="#")
    return table.set_index(["scenario", "metric"])


def paper_values(models: list[str] | None = None) -> pd.DataFrame:
    """Only the numbers, index (scenario, metric), columns `models` (NaN for unknown names)."""
    table = paper_table().drop(columns=["unit", "struck_out"]).astype(float)
    return table if models is None else table.reindex(columns=models)


def struck_out() -> set[tuple[str, str, str]]:
    """(scenario, metric, model) of every value Table I strikes out (the csv's `struck_out`
    column): shown, never a claim."""
    table = paper_table()
    return {(scenario, metric, model) for (scenario, metric), names in table["struck_out"].fillna("").items()
            for model in str(names).split(";") if model}


def paper_curves() -> pd.DataFrame:
    """The paper's training curves (Fig. 5): columns model, iteration, reward."""
    source = resources.files("sigmarl").joinpath("data").joinpath(PAPER_CURVES)
    with source.open("r", encoding="utf-8") as f:
        wide = pd.read_csv(f, comment="#")
    return wide.melt(id_vars="iteration", var_name="model", value_name="reward")[["model", "iteration", "reward"]]
