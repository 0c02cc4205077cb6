"""A factorial study's interactions (difference of differences) against hand-worked numbers,
and the study declaration that asks for them."""

from __future__ import annotations

import math

import pandas as pd
import pytest
from scipy import stats

from sigmarl.compose import compose_config
from sigmarl.errors import SigmarlError
from sigmarl.report.compare.verdicts import Design, interaction_table, interactions_markdown
from sigmarl.stats.engine import Null, interaction

# seed means in %: one simulation per seed, so a seed's mean is its value
SEEDS = {"M0-paper": [1.0, 2.0, 3.0], "M4-paper": [3.0, 4.0, 5.0], "M0": [1.5, 2.5, 2.0], "M4": [2.0, 2.5, 3.0]}


def _rows(seeds: dict[str, list[float]]) -> pd.DataFrame:
    return pd.DataFrame([{"model": m, "scenario": "A", "seed": s, "simulation": 0, "CR_total": v / 100,
                          "CD": 1.0, "AS": 0.7} for m, vs in seeds.items() for s, v in enumerate(vs)])


DESIGN = Design(variants=list(SEEDS), baseline="M0-paper", baselines={"M4": "M0"},
                interactions={"M4": ("M4-paper", "M4")}, margins={"CR_total": 0.1})


def test_difference_of_differences_by_hand():
    # (4 - 2) - (2.5 - 2) = 1.5; group variances 1, 1, 0.25, 0.25 over n = 3 seeds:
    # se^2 = 1/3 + 1/3 + 1/12 + 1/12 = 5/6, t = 1.64: decided by the comparison engine
    (r,) = interaction_table(_rows(SEEDS), DESIGN).to_dict("records")
    assert (r["x_difference"], r["y_difference"], r["difference"]) == pytest.approx((2.0, 0.5, 1.5))
    assert r["seeds"] == "3/3/3/3"  # x / its baseline / y / its baseline
    nulls = {"zero": Null(0.0), "above": Null(-0.1, "greater"), "below": Null(0.1, "less")}
    direct = interaction(*(SEEDS[m] for m in ("M4-paper", "M0-paper", "M4", "M0")), nulls)
    assert direct.se == pytest.approx(math.sqrt(5 / 6))
    assert (r["ci_low"], r["ci_high"]) == (direct.ci_low, direct.ci_high) and r["ci_low"] < 1.5 < r["ci_high"]
    assert r["p_difference"] == direct.p["zero"]
    assert r["p_same_holm"] == max(direct.p["above"], direct.p["below"])  # a family of one: Holm's p is the raw one
    # at least the t distribution's p on Satterthwaite's 100/17 degrees of freedom (0.15): three seeds cannot tell
    assert r["p_difference"] > 2 * stats.t.sf(1.5 / math.sqrt(5 / 6), 100 / 17) - 0.02
    assert r["verdict"] == "undecided"
    text = interactions_markdown(interaction_table(_rows(SEEDS), DESIGN), DESIGN)
    assert "| M4-paper − M0-paper: +2.000 | M4 − M0: +0.500 |" in text


def test_a_clear_interaction_differs_and_a_null_one_is_the_same():
    big = {**SEEDS, "M4-paper": [9.0, 9.1, 9.2], "M0-paper": [1.0, 1.1, 1.2]}  # +8 against +0.5
    assert interaction_table(_rows(big), DESIGN)["verdict"].tolist() == ["differs"]
    flat = {m: [2.0, 2.01, 2.02] for m in SEEDS}  # no difference anywhere, little noise
    table = interaction_table(_rows(flat), DESIGN)
    assert table["verdict"].tolist() == ["same"]
    text = interactions_markdown(table, DESIGN)
    assert "| A | CR_total (%) | M4 | M4-paper − M0-paper: +0.000 | M4 − M0: +0.000 |" in text
    assert "same within ±0.1 pp" in text


def test_paper_rules_declares_its_question():
    study = compose_config(["study=paper_rules"]).study
    assert dict(study.interactions) == {"M4": ["M4-paper", "M4"], "M1": ["M1-paper", "M1"],
                                        "M5": ["M5-paper", "M5"], "M2": ["M2-paper", "M2"]}
    for model in ("M4", "M1", "M5", "M2"):
        assert study.baselines[model] == "M0" and study.baselines[f"{model}-paper"] == "M0-paper"


@pytest.mark.parametrize("value, says", [
    ("[M4-paper]", "must be two variants"),
    ("[M4-paper,M9]", "M9 not among the study's variants"),
    ("[M4-paper,M1-paper]", "must be four different variants"),
])
def test_a_bad_interaction_is_refused_at_composition(value, says):
    with pytest.raises(SigmarlError, match="study.interactions.M4") as e:
        compose_config(["study=paper_rules", f"study.interactions.M4={value}"])
    assert says in str(e.value)


def test_the_report_writes_the_interactions_beside_the_verdicts(tmp_path):
    from sigmarl.metrics import METRIC_COLUMNS
    from sigmarl.report.build import BuildOptions, build_report

    rows = _rows(SEEDS)
    for column in METRIC_COLUMNS:  # the report's other tables need every metric column
        if column not in rows:
            rows[column] = 0.0
    rows["CR_AA"], rows["CR_AL"] = rows["CR_total"], 0.0
    report = build_report(rows, BuildOptions(out_dir=tmp_path, models=list(SEEDS), figures=False,
                                             order=list(SEEDS), baseline="M0-paper", design=DESIGN))
    saved = pd.read_csv(report.paths["interactions"])
    assert saved["difference"].tolist() == pytest.approx([1.5])
    text = (tmp_path / "verdicts.md").read_text()
    assert text.startswith("Verdicts against each model's baseline") and "\nInteractions: " in text


@pytest.mark.parametrize("override, says", [
    ("study.baselines.M4=M9", "study.baselines.M4: 'M9' is not one of the study's variants"),
    ("+study.baselines.M9=M0", "study.baselines: 'M9' is not one of the study's variants"),
    ("study.baselines.M4=M4", "a variant cannot be its own baseline"),
])
def test_a_bad_baseline_is_refused_at_composition(override, says):
    with pytest.raises(SigmarlError) as e:
        compose_config(["study=paper_rules", override])
    assert says in str(e.value)
