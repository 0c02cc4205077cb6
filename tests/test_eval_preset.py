"""`eval=smoke` shrinks any study's evaluation, and nothing else."""

from __future__ import annotations

import pytest

from sigmarl.compose import compose_config
from sigmarl.evaluation.target import check_evaluate_overrides
from sigmarl.identity import fingerprint


@pytest.mark.parametrize("study", ["paper", "quick", "generalisation"])
def test_smoke_evaluation_of_any_study(study):
    full, smoke = compose_config([f"study={study}"]), compose_config([f"study={study}", "eval=smoke"])
    assert (smoke.eval.n_sims, smoke.eval.steps) == (2, 100)
    assert smoke.eval.scenarios == full.eval.scenarios and smoke.eval.seed == full.eval.seed
    assert fingerprint(smoke) == fingerprint(full)  # the models trained are the study's own


def test_the_study_keeps_its_evaluation_without_it():
    assert (compose_config([]).eval.n_sims, compose_config([]).eval.steps) == (32, 1200)
    assert (compose_config(["study=quick"]).eval.n_sims, compose_config(["study=quick"]).eval.steps) == (4, 150)


def test_evaluate_takes_it():
    check_evaluate_overrides(["eval=smoke"])  # raises on an override evaluate would drop
