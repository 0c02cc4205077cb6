"""The paper's Table I as shipped reference data (CD already in real centimetres)."""

from __future__ import annotations

from importlib import resources

import pandas as pd

PAPER_TABLE = "paper_table_1.csv"


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
    table = paper_table().drop(columns="unit").astype(float)
    return table if models is None else table.reindex(columns=models)
