"""`sigmarl sweep`: a Hydra multirun in which every job trains one model, then evaluates it.

The launcher is Hydra's (joblib by default, so jobs run in parallel processes;
any other Hydra launcher plugin via `hydra/launcher=...`). A job that fails
writes `failed.txt` into its run folder and returns, so the others go on.
Re-running the same sweep skips finished work: training resumes from its last
checkpoint or returns at once when finished, evaluation is skipped when MLflow
already holds a finished one under the same protocol.
"""

from __future__ import annotations

import os
import sys
import traceback
from collections.abc import Sequence
from pathlib import Path

from omegaconf import DictConfig, open_dict

from sigmarl.errors import SigmarlError
from sigmarl.study import MODELS

FAILED_FILE = "failed.txt"
DONE_FILE = "evaluated.txt"


def run_job(cfg: DictConfig) -> str:
    """Train (or resume, or skip) and evaluate one model; returns 'done' or 'failed'."""
    from sigmarl.evaluation import records
    from sigmarl.evaluation.study import checkpoint_name, evaluate_and_log
    from sigmarl.training import checkpoint as ckpt
    from sigmarl.training.loop import train

    run_dir = Path(cfg.run_dir)
    (run_dir / FAILED_FILE).unlink(missing_ok=True)
    try:
        with open_dict(cfg):
            cfg.resume = (run_dir / ckpt.RESUME_FILE).exists()
        result = train(cfg)
        if not result.finished:
            return "interrupted"
        if cfg.tracking.enabled and result.run_id:
            client = records.client_for(cfg)
            exp_id = records.experiment_id(client, cfg.tracking.experiment, create=True)
            if records.finished_evaluation(client, exp_id, result.run_id, records.eval_key(cfg.eval)):
                print(f"{run_dir}: already evaluated")
                (run_dir / DONE_FILE).touch()
                return "done"
        path = run_dir / checkpoint_name(cfg.eval.checkpoint)
        rows, eval_run = evaluate_and_log(path, cfg, result.run_id, progress=False)
        rows.to_csv(run_dir / "evaluation_rows.csv", index=False)
        (run_dir / DONE_FILE).write_text(f"{eval_run or ''}\n")
        return "done"
    except (Exception, KeyboardInterrupt) as e:
        run_dir.mkdir(parents=True, exist_ok=True)
        message = str(e) if isinstance(e, SigmarlError) else traceback.format_exc()
        (run_dir / FAILED_FILE).write_text(message)
        print(f"sigmarl sweep: job {run_dir} failed: {str(e)[:500]}", file=sys.stderr)
        if isinstance(e, KeyboardInterrupt):
            raise
        return "failed"


def sweep_overrides(user: Sequence[str], cores: int | None = None) -> list[str]:
    """The multirun's overrides: the six presets and seed 0 unless the user chose, plus
    launcher settings from the core count. `seeds=[0,1,2]` and `models=[M0,M4]` are
    shorthands for `seed=0,1,2` and the models' presets."""
    out: list[str] = []
    keys = set()
    seeds = models = None
    for item in user:
        key, _, value = item.partition("=")
        if key == "seeds":
            seeds = [s.strip() for s in value.strip("[]").split(",") if s.strip()]
            continue
        if key == "models":
            names = [m.strip() for m in value.strip("[]").split(",") if m.strip()]
            unknown = [m for m in names if m not in MODELS]
            if unknown:
                raise SigmarlError(f"unknown model(s) {unknown}; choose from {', '.join(MODELS)}")
            models = [MODELS[m] for m in names]
            continue
        keys.add(key.lstrip("+~"))
        out.append(item)
    if "obs" not in keys:
        out.append("obs=" + ",".join(models or MODELS.values()))
    if "seed" not in keys:
        out.append("seed=" + ",".join(seeds or ["0"]))
    n_jobs = _count(out, "obs") * _count(out, "seed")
    cores = cores or os.cpu_count() or 1
    jobs = min(n_jobs, cores)
    if "hydra/launcher" not in keys:
        out.append("hydra/launcher=joblib")
    if "hydra.launcher.n_jobs" not in keys:
        out.append(f"hydra.launcher.n_jobs={jobs}")
    if "threads" not in keys:
        out.append(f"threads={max(1, cores // jobs)}")
    return out


def _count(overrides: list[str], key: str) -> int:
    for item in overrides:
        k, _, v = item.partition("=")
        if k == key:
            return len(v.split(","))
    return 1


def run_sweep(user_overrides: Sequence[str]) -> int:
    """Run the multirun in this process (Hydra's entry point), then summarise the jobs."""
    import hydra

    from sigmarl.config import register_configs
    from sigmarl.paths import conf_dir

    overrides = sweep_overrides(user_overrides)
    register_configs()
    _prepare_store(overrides)
    argv = sys.argv
    sys.argv = ["sigmarl-sweep", "--multirun", *overrides]
    try:
        main = hydra.main(config_path=str(conf_dir()), config_name="config", version_base=None)(run_job)
        main()
    finally:
        sys.argv = argv
    return summarise(overrides)


def _prepare_store(overrides: Sequence[str]) -> None:
    """Validate the sweep's configs, then create the MLflow store and experiment once, here:
    parallel jobs creating a new SQLite store at the same moment would race on its schema
    migration."""
    from sigmarl.compose import compose_config
    from sigmarl.evaluation import records

    fixed = _fixed(overrides)
    # Check every swept value here, so a typo ends with one message before any job starts.
    for item in overrides:
        key, _, values = item.partition("=")
        if "," in values and not key.startswith("hydra"):
            for value in values.split(","):
                compose_config([*fixed, f"{key}={value}"])
    cfg = compose_config(fixed)
    if cfg.tracking.enabled:
        records.experiment_id(records.client_for(cfg), cfg.tracking.experiment, create=True)


def _fixed(overrides: Sequence[str]) -> list[str]:
    """The overrides that are the same for every job (no sweep lists, no hydra settings)."""
    return [o for o in overrides if "," not in o and not o.startswith("hydra")]


def summarise(overrides: Sequence[str]) -> int:
    """Print each job's state from its run folder; non-zero if any failed or is unfinished."""
    from sigmarl.compose import compose_config

    fixed = _fixed(overrides)
    presets = next((o.split("=", 1)[1] for o in overrides if o.startswith("obs=")), "full").split(",")
    seeds = next((o.split("=", 1)[1] for o in overrides if o.startswith("seed=")), "0").split(",")
    bad = 0
    print("\nsweep summary:")
    for preset in presets:
        for seed in seeds:
            cfg = compose_config([*fixed, f"obs={preset}", f"seed={seed}"])
            run_dir = Path(cfg.run_dir)
            if (run_dir / FAILED_FILE).exists():
                state = "FAILED: " + (run_dir / FAILED_FILE).read_text().strip().splitlines()[-1][:200]
                bad += 1
            elif (run_dir / DONE_FILE).exists():
                state = "trained and evaluated"
            else:
                state = "unfinished (run the sweep again to resume)"
                bad += 1
            print(f"  {cfg.model:<6} {preset:<28} seed {seed:<3} {state}   [{run_dir}]")
    if not bad:
        print(f"next: sigmarl report {' '.join(o for o in fixed if o.startswith(('study', 'tracking')))}".rstrip())
    return 1 if bad else 0

