"""The comparison engine's level at nominal 5 %, from the committed results of
`scripts/engine_level.py` (2,000 datasets a cell: a 6 % rate lies 2 binomial standard errors
above 5 %), checked cheaply here; one cell is simulated again at fewer datasets to show the file
is the script's.

A cell fails above 6 %. Cells known to fail are listed with their rates, and docs/concepts.md
states them; a new cell above 6 %, or a listed one that comes back under it, fails this test."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

ROOT = Path(__file__).resolve().parents[1]
LEVEL = pd.read_csv(ROOT / "tests" / "data" / "engine_level.csv")
LIMIT = 0.06
ENGINE_TESTS = ("difference", "smaller")
TODAY = "smaller, today's permutation test"


def _over(shapes: tuple[str, ...], tests: tuple[str, ...]) -> set[tuple[str, str, str]]:
    cells = LEVEL[LEVEL["shape"].isin(shapes) & LEVEL["test"].isin(tests)]
    return {(r.design, r.shape, r.test) for r in cells.itertuples() if r.rate > LIMIT}


def test_the_file_covers_every_design_and_shape():
    sys.path.insert(0, str(ROOT / "scripts"))
    import engine_level

    assert set(LEVEL["design"]) == set(engine_level.DESIGNS) and set(LEVEL["shape"]) == set(engine_level.SHAPES)
    assert (LEVEL["datasets"] == engine_level.N_DATASETS).all()


def test_the_engine_holds_the_level_under_lognormal_seeds_unequal_variances_and_in_the_interaction():
    assert _over(("lognormal", "variances 1:9"), ENGINE_TESTS) == set()
    interaction = LEVEL[LEVEL["design"].str.startswith("interaction")]
    assert (interaction["rate"] <= LIMIT).all()


def test_a_slow_seed_carrying_the_mean_breaks_every_test_as_the_docs_say():
    # M4's committed On-Ramp seeds: one of 14 carries most of the mean; a sample that misses it looks
    # smaller. The engine does better than today's test there, and the docs give the engine's worst rate.
    committed = LEVEL[LEVEL["shape"].str.startswith("committed")]
    engine = committed[committed["test"] == "smaller"].set_index(["design", "shape"])["rate"]
    today = committed[committed["test"] == TODAY].set_index(["design", "shape"])["rate"]
    assert (engine <= today + 0.01).all()
    docs = (ROOT / "docs" / "concepts.md").read_text(encoding="utf-8")
    assert f"{engine.max():.2f}" in docs


def test_todays_smaller_test_fails_the_level():
    # unequal variances at unequal counts, and every committed shape
    assert _over(("variances 1:9",), (TODAY,)) == {("6 v 14", "variances 1:9", TODAY)}
    assert _over(("committed scaled",), (TODAY,))
    assert LEVEL.loc[(LEVEL["shape"] == "committed scaled") & (LEVEL["test"] == TODAY), "rate"].min() > 0.3


def test_one_cell_again_at_fewer_datasets():
    sys.path.insert(0, str(ROOT / "scripts"))
    import engine_level

    n = 300
    old = engine_level.N_DATASETS
    engine_level.N_DATASETS = n
    try:
        m0, m4 = engine_level.committed()
        rate = engine_level.engine_rates("5 v 5", "variances 1:9", m0, m4, np.random.default_rng(7))["smaller"]
    finally:
        engine_level.N_DATASETS = old
    stored = float(LEVEL.query("design == '5 v 5' and shape == 'variances 1:9' and test == 'smaller'")["rate"].iloc[0])
    assert rate == pytest.approx(stored, abs=4 * math.sqrt(stored * (1 - stored) / n))
