"""One model identity: the label, run folder, tags and evaluation rows all follow the five
observation flags (once, `obs=full obs.ego_view=false` was M1 in training but M0 elsewhere)."""

from __future__ import annotations

import itertools

import pytest

from sigmarl.ablation import MODELS, OBS_FLAGS, model_label, obs_strategies
from sigmarl.compose import compose_config

# Table I's definition: M0 uses all five strategies, Mk leaves out the k-th of E, V, DA, DB, DC.
PAPER = {"M0": "E,V,DA,DB,DC", "M1": "V,DA,DB,DC", "M2": "E,DA,DB,DC", "M3": "E,V,DB,DC",
         "M4": "E,V,DA,DC", "M5": "E,V,DA,DB"}


@pytest.mark.parametrize("model, preset", sorted(MODELS.items()))
def test_each_preset_is_its_paper_model(model: str, preset: str) -> None:
    cfg = compose_config([f"obs={preset}"])
    assert cfg.model == model == model_label(cfg.obs)
    assert obs_strategies(cfg.obs) == PAPER[model]
    assert cfg.run_dir == f"runs/sigmarl-ablation/{model}/seed0"


def test_flags_decide_not_the_preset_name() -> None:
    # The preset says "full", the flags say M1: the label, folder and tags are M1's.
    cfg = compose_config(["obs=full", "obs.ego_view=false", "seed=2"])
    assert cfg.obs.preset == "full"
    assert cfg.model == "M1" and cfg.run_dir == "runs/sigmarl-ablation/M1/seed2"


def test_every_combination_has_a_distinct_label() -> None:
    labels = {}
    for values in itertools.product([True, False], repeat=len(OBS_FLAGS)):
        obs = dict(zip(OBS_FLAGS, values, strict=True))
        labels[model_label(obs)] = values
    assert len(labels) == 2 ** len(OBS_FLAGS)  # no two combinations share a label or folder
    customs = [label for label in labels if label.startswith("custom-")]
    assert len(customs) == 32 - 6 and all(len(label) == len("custom-") + 6 for label in customs)


def test_a_custom_combination_never_takes_a_paper_models_folder() -> None:
    cfg = compose_config(["obs=no_vertices", "obs.ego_view=false"])
    assert cfg.model.startswith("custom-") and cfg.model not in MODELS
    assert cfg.run_dir == f"runs/sigmarl-ablation/{cfg.model}/seed0"


def test_runs_root_moves_every_run_folder() -> None:
    cfg = compose_config(["runs_root=results/paper-budget", "obs=no_distance_to_agents", "seed=1"])
    assert cfg.run_dir == "results/paper-budget/M3/seed1"


@pytest.mark.slow
def test_training_evaluation_and_tags_agree_on_the_label(tmp_path) -> None:
    # `obs=full obs.ego_view=false` is M1 everywhere: run folder, MLflow tags, evaluation rows.
    from mlflow.tracking import MlflowClient

    from sigmarl.evaluation.protocol import evaluate_and_log
    from sigmarl.training import train

    uri = f"sqlite:///{tmp_path}/mlflow.db"
    cfg = compose_config(["ppo=smoke", "ppo.iterations=1", "obs=full", "obs.ego_view=false",
                          f"runs_root={tmp_path}/runs", f"tracking.tracking_uri={uri}",
                          "eval.n_sims=1", "eval.steps=5", "eval.scenarios=[Intersection]"])
    result = train(cfg)
    assert (tmp_path / "runs" / "M1" / "seed0" / "best.pt").is_file()
    rows, eval_run = evaluate_and_log(tmp_path / "runs" / "M1" / "seed0" / "best.pt", cfg,
                                      result.run_id, progress=False)
    assert set(rows["model"]) == {"M1"} and set(rows["obs"]) == {PAPER["M1"]}
    client = MlflowClient(tracking_uri=uri)
    for run_id in (result.run_id, eval_run):
        tags = client.get_run(run_id).data.tags
        assert tags["model"] == "M1" and tags["obs"] == PAPER["M1"]


def test_a_checkpoint_from_an_older_sigmarl_resumes() -> None:
    # A run started before a knob existed (or while one that is gone still did) must resume:
    # only settings that differ from what that run did count.
    from sigmarl.config import as_dict
    from sigmarl.training.loop import config_changes

    cfg = compose_config(["ppo=smoke"])
    saved = as_dict(cfg)  # what a checkpoint holds
    saved["env"]["mode"] = "train"  # a knob since removed
    del saved["ppo"]["entropy_coef"]  # a knob added since, at its default
    assert config_changes(saved, cfg) == []
    changed = compose_config(["ppo=smoke", "ppo.entropy_coef=0.01", "ppo.lr=0.001", "threads=2"])
    assert config_changes(saved, changed) == ["ppo.entropy_coef", "ppo.lr"]  # threads may change
