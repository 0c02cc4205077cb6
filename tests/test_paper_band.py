"""The paper's training curves against our seeds' band (`paper_band.png`): each panel on the
definition every seed of the model logged, a figure only where a model has both curves."""

from __future__ import annotations

import numpy as np
import pandas as pd
from PIL import Image

from sigmarl.report.figures import definition, plot_paper_band
from sigmarl.report.tables import paper_curves


def _curves(model: str, seeds: int, complete: list[bool]) -> pd.DataFrame:
    it = np.arange(1, 251)
    return pd.DataFrame([{"model": model, "seed": s, "iteration": i, "reward": 0.02 * i + s,
                          "reward_complete": 0.02 * i + s + 0.5 if complete[s] else np.nan}
                         for s in range(seeds) for i in it])


def test_the_estimate_only_where_every_seed_logged_it():
    assert definition(_curves("M0", 3, [True, True, True])) == ("reward_complete", "complete-episode estimate")
    assert definition(_curves("M0", 3, [True, False, True])) == ("reward", "batch-cut")
    assert definition(_curves("M0", 2, [False, False]).drop(columns="reward_complete"))[1] == "batch-cut"


def test_a_panel_per_model_with_both_curves(tmp_path):
    curves = pd.concat([_curves("M0", 3, [False] * 3), _curves("M5", 2, [True, True]), _curves("W64", 2, [False] * 2)])
    path = plot_paper_band(curves, paper_curves(), ["M0", "M5", "W64"], tmp_path / "band.png")
    assert path == tmp_path / "band.png" and Image.open(path).size[0] > 600
    assert plot_paper_band(curves, paper_curves(), ["W64"], tmp_path / "none.png") is None
    assert not (tmp_path / "none.png").exists()
    # the paper's evaluated policies: the best iteration of its curve (FORMAT.md of its checkpoints)
    paper = paper_curves().set_index("iteration").groupby("model")["reward"].idxmax().to_dict()
    assert paper == {"M0": 190, "M1": 76, "M2": 182, "M3": 212, "M4": 217, "M5": 247}
