"""A fingerprint recorded in published rows stays what the current code computes: adding a
training setting (at the value earlier runs had) must not change every run's identity."""

from pathlib import Path

import pandas as pd
import pytest

from sigmarl.identity import ADDED_LATER, fingerprint
from sigmarl.readers import read_run_config

ROOT = Path(__file__).resolve().parents[1] / "results"
RECORDED = sorted(p for p in ROOT.glob("*/*/seed*/evaluation_rows.csv")
                  if "fingerprint" in pd.read_csv(p, nrows=0).columns)


@pytest.mark.skipif(not RECORDED, reason="no published rows with a fingerprint")
def test_published_rows_keep_their_fingerprints():
    wrong = []
    for rows in RECORDED:
        recorded = set(pd.read_csv(rows, usecols=["fingerprint"], dtype=str)["fingerprint"])
        now = fingerprint(read_run_config(rows.parent / "config.yaml"))
        if recorded != {now}:
            wrong.append(f"{rows.parent}: rows {sorted(recorded)}, now {now}")
    assert not wrong, "\n".join(wrong[:5])


def test_a_later_setting_counts_away_from_its_old_value():
    cfg = read_run_config(RECORDED[0].parent / "config.yaml")
    from dataclasses import replace
    base = fingerprint(cfg)
    assert ADDED_LATER["network.centralised_critic"] is True
    ippo = replace(cfg, network=replace(cfg.network, centralised_critic=False))
    assert fingerprint(ippo) != base
