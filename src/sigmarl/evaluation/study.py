"""Evaluate a trained model (checkpoint file, run folder or MLflow run id) on the study's scenarios."""

from __future__ import annotations

import tempfile
from pathlib import Path

import pandas as pd
from omegaconf import DictConfig, OmegaConf

from sigmarl.errors import SigmarlError
from sigmarl.evaluation import records
from sigmarl.evaluation.rollout import evaluate_policy
from sigmarl.study import SCENARIOS, check_eval, model_label, obs_strategies


def checkpoint_name(which: str) -> str:
    from sigmarl.training import checkpoint as ckpt

    if which not in ("best", "final"):
        raise SigmarlError(f"eval.checkpoint must be 'best' or 'final', got {which!r}")
    return ckpt.BEST_FILE if which == "best" else ckpt.FINAL_FILE


def resolve_checkpoint(target: str, cfg: DictConfig, download_dir: Path | None = None) -> Path:
    """A checkpoint file from a path, a training run folder, or an MLflow training run id."""
    name = checkpoint_name(cfg.eval.checkpoint)
    path = Path(target)
    if path.is_file():
        return path
    if path.is_dir():
        if (path / name).is_file():
            return path / name
        raise SigmarlError(f"{path} holds no {name} (has the training finished? see eval.checkpoint)")
    if "/" in target or target.endswith(".pt"):
        raise SigmarlError(f"checkpoint not found: {target}")
    # An MLflow run id: use the run's folder if it is on this machine, else its artifact.
    client = records.client_for(cfg)
    try:
        run = client.get_run(target)
    except Exception as e:
        raise SigmarlError(f"{target!r} is neither a checkpoint file, a run folder nor an MLflow run id") from e
    local = Path(run.data.params.get("run_dir", "")) / name
    if local.is_file():
        return local
    try:
        out = download_dir or Path(tempfile.mkdtemp(prefix="sigmarl-ckpt-"))
        return Path(client.download_artifacts(target, name, str(out)))
    except Exception as e:
        raise SigmarlError(f"MLflow run {target} has no {name} artifact") from e


def evaluate_checkpoint(path: Path, eval_cfg: DictConfig, scenarios: list[str] | None = None,
                        device: str = "cpu", progress: bool = True) -> tuple[pd.DataFrame, dict]:
    """Per-simulation rows of a trained policy on each scenario, and the checkpoint's state."""
    from sigmarl.training.loop import load_policy

    scenarios = check_eval(eval_cfg, scenarios or None)
    frames = []
    state = None
    for scenario in scenarios:
        n_agents = SCENARIOS[scenario][1]
        actor, state = load_policy(path, n_agents=n_agents, device=device)
        train_cfg = OmegaConf.create(state["config"])
        rows = evaluate_policy(actor, train_cfg, scenario, n_sims=eval_cfg.n_sims, steps=eval_cfg.steps,
                               seed=eval_cfg.seed, n_agents=n_agents, device=device, progress=progress)
        frames.append(rows)
    train_cfg = OmegaConf.create(state["config"])
    rows = pd.concat(frames, ignore_index=True)
    rows.insert(0, "model", model_label(train_cfg.obs))
    rows.insert(1, "obs", obs_strategies(train_cfg.obs))
    rows.insert(2, "seed", int(train_cfg.seed))
    return rows, state


def evaluate_and_log(path: Path, cfg: DictConfig, train_run_id: str | None, scenarios=None,
                     progress: bool = True) -> tuple[pd.DataFrame, str | None]:
    """Evaluate a checkpoint and record it in MLflow (unless tracking is off)."""
    rows, state = evaluate_checkpoint(path, cfg.eval, scenarios, device=cfg.device, progress=progress)
    if not cfg.tracking.enabled:
        return rows, None
    client = records.client_for(cfg)
    exp_id = records.experiment_id(client, cfg.tracking.experiment, create=True)
    train_cfg = OmegaConf.create(state["config"])
    tags = {
        "model": str(rows["model"].iloc[0]),
        "obs": obs_strategies(train_cfg.obs),
        "seed": str(train_cfg.seed),
        "train_run_id": train_run_id or state.get("mlflow_run_id") or "",
        "checkpoint": str(path),
        "eval_key": records.eval_key(cfg.eval),
    }
    params = {f"eval.{k}": str(v) for k, v in OmegaConf.to_container(cfg.eval, resolve=True).items()}
    params["checkpoint_iteration"] = str(state.get("iteration"))
    run_id = records.log_evaluation(client, exp_id, rows, tags, params)
    return rows, run_id
