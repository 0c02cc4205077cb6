"""The marl-eval export of the published study loads whole in marl-eval's own loader (id-marl-eval
0.0.4, installed with --no-deps since it pins pandas 1.4.4), and its matrices are the seed means."""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest

from sigmarl.report.marl_eval import export_files, marl_eval_data, seed_groups
from sigmarl.results.folders import read_results

processing = pytest.importorskip("marl_eval.utils.data_processing_utils")
ROOT = Path(__file__).resolve().parents[1] / "results" / "paper-budget"
MODELS = ["M0", "M1", "M2", "M3", "M4", "M5"]


def _matrices(data: dict) -> dict:
    processed = processing.data_process_pipeline(raw_data=copy.deepcopy(data), metrics_to_normalize=[])
    matrices, _ = processing.create_matrices_for_rliable(
        data_dictionary=processed, environment_name="sigmarl", metrics_to_normalize=[])
    return matrices


@pytest.fixture(scope="module")
def rows():
    return read_results(ROOT).rows


def test_one_file_with_unequal_seed_counts_does_not_load(rows) -> None:
    """Why the export is split: marl-eval takes every algorithm's run names from the first one,
    so a model with fewer seeds after it fails, and one before it drops the others' seeds."""
    rows = rows[(rows["model"] != "M1") | (rows["seed"] < 5)]  # M1 with fewer seeds than M0
    n_m1 = rows.loc[rows["model"] == "M1", "seed"].nunique()
    with pytest.raises(KeyError, match=f"run_{n_m1}"):
        _matrices(marl_eval_data(rows, ["M0", "M1"]))
    dropped = _matrices(marl_eval_data(rows, ["M1", "M0"]))["mean_cr_total"]
    assert dropped["m0"].shape[0] == n_m1


def test_each_file_loads_whole_and_holds_the_seed_means(rows) -> None:
    groups = seed_groups(rows, MODELS)
    # Expected from the committed seed counts: every model at the fewest seeds, then one file for
    # each larger count holding the models trained to exactly that many.
    counts = {m: rows.loc[rows["model"] == m, "seed"].nunique() for m in MODELS}
    fewest = min(counts.values())
    expected = {"marl_eval.json": (MODELS, fewest)}
    for n in sorted(set(counts.values()) - {fewest}):
        at_n = [m for m in MODELS if counts[m] == n]
        expected[f"marl_eval_{'_'.join(at_n)}.json"] = (at_n, n)
    assert {name: (models, len(seeds)) for name, (models, seeds) in groups.items()} == expected
    for name, data in export_files(rows, MODELS).items():
        models, seeds = groups[name]
        tasks = list(data["sigmarl"])
        cr = _matrices(data)["mean_cr_total"]
        assert sorted(cr) == sorted(m.lower() for m in models)
        for model in models:
            mine = rows[(rows["model"] == model) & rows["seed"].isin(seeds)]
            means = mine.groupby(["seed", "scenario"])["CR_total"].mean().unstack()[tasks]
            np.testing.assert_allclose(cr[model.lower()], means.to_numpy(), rtol=1e-12, err_msg=name)
