"""The evaluation of a driver that needs no training (`driver.kind=rule_based`): the study's
scenarios under its protocol, rows written as a trained seed's are (`evaluation_rows.csv` and
its note, beside the config.yaml it drove with), and one evaluation run in the tracker.

It has no training seeds: it is deterministic, so a sweep runs it once, as the first of the
study's seeds (`sigmarl.sweep.plan`), and its rows name that seed."""

from __future__ import annotations

import pandas as pd

from sigmarl.ablation import obs_strategies
from sigmarl.compose.validate import check_eval
from sigmarl.config import Config, as_dict, to_yaml
from sigmarl.env.paper_rules import rules_label
from sigmarl.errors import SigmarlError
from sigmarl.eval_key import eval_key
from sigmarl.evaluation.protocol import save_rows
from sigmarl.evaluation.rollout import evaluate_policy
from sigmarl.evaluation.rule_based import RuleBasedDriver
from sigmarl.identity import fingerprint
from sigmarl.run import Run, write_atomic
from sigmarl.scenarios import scenario as scenario_of
from sigmarl.tracking import Tracker

CHECKPOINT = "none (rule-based driver)"  # what its rows and its record give for a checkpoint


def driver_rows(cfg: Config, progress: bool = True) -> pd.DataFrame:
    """Per-simulation rows of the rule-based driver on the study's scenarios, in the columns a
    trained seed's rows have."""
    if cfg.driver.kind != "rule_based":
        raise SigmarlError(f"driver.kind={cfg.driver.kind} is trained, not driven by rules")
    driver = RuleBasedDriver(cfg.driver)
    frames = [evaluate_policy(driver, cfg, name, n_sims=cfg.eval.n_sims, steps=cfg.eval.steps, seed=cfg.eval.seed,
                              n_agents=scenario_of(name).n_agents, device=cfg.device, progress=progress)
              for name in check_eval(cfg.eval)]
    rows = pd.concat(frames, ignore_index=True)
    for at, (column, value) in enumerate((("model", cfg.model), ("obs", obs_strategies(cfg.obs)),
                                          ("seed", int(cfg.seed)), ("rules", rules_label(cfg.rules)))):
        rows.insert(at, column, value)
    rows["study"] = cfg.study.name
    rows["fingerprint"] = fingerprint(cfg)
    return rows


def evaluate_driver(cfg: Config, run: Run, tracker: Tracker, progress: bool = False) -> str | None:
    """Evaluate the rule-based driver into `run` (its config.yaml, rows and note) and record it
    in `tracker`; returns the tracker's evaluation run id (None: none)."""
    rows = driver_rows(cfg, progress)
    run.dir.mkdir(parents=True, exist_ok=True)
    write_atomic(run.config_file, to_yaml(cfg))
    save_rows(rows, run.rows_file, {"eval_key": eval_key(cfg.eval), "checkpoint_sha256": CHECKPOINT}, cfg.eval)
    tags = {"model": cfg.model, "obs": obs_strategies(cfg.obs), "study": cfg.study.name,
            "fingerprint": fingerprint(cfg), "seed": str(cfg.seed), "train_run_id": "",
            "checkpoint": CHECKPOINT, "eval_key": eval_key(cfg.eval), "driver": cfg.driver.kind}
    params = {f"eval.{k}": str(v) for k, v in as_dict(cfg.eval).items()}
    params.update({f"driver.{k}": str(v) for k, v in as_dict(cfg.driver).items()})
    params.update({"variant": cfg.model, "overrides": " ".join(cfg.overrides)[:6000],
                   "fingerprint": tags["fingerprint"], "obs": tags["obs"], "seed": tags["seed"]})
    return tracker.log_evaluation(rows, tags, params)
