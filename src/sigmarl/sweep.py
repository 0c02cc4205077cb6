"""`sigmarl sweep`: a Hydra multirun in which every job trains one model, then evaluates it.

The launcher is Hydra's (joblib by default, so jobs run in parallel processes;
any other Hydra launcher plugin via `hydra/launcher=...`). A job that fails
writes `failed.txt` into its run folder and returns, so the others go on.
Re-running the same sweep skips finished work: training resumes from its last
checkpoint or returns at once when finished, evaluation is skipped when MLflow
already holds a finished one under the same protocol.
"""

from __future__ import annotations

import itertools
import logging
import math
import os
import sys
import traceback
import warnings
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.core.override_parser.types import Override
from hydra.errors import HydraException
from omegaconf import DictConfig

from sigmarl.ablation import MODELS, check_eval
from sigmarl.config import Config, as_config
from sigmarl.errors import SigmarlError, Terminated, was_interrupted
from sigmarl.progress import emit
from sigmarl.resources import enter_sweep_folder, job_threads, sweep_folder_override, use_threads

FAILED_FILE = "failed.txt"
DONE_FILE = "evaluated.txt"


def run_job(cfg: DictConfig | Config) -> str:
    """Train (or resume, or skip) and evaluate one model; returns 'done' or 'failed'.

    `cfg` is the job's config as Hydra's launcher hands it over (a DictConfig, typed here)
    or an already composed `Config`.

    Every step can be killed at any instant and the job run again: training resumes from
    `checkpoint.pt` (or starts from scratch if it never got that far) and completes the
    MLflow record of a training that was killed after its end; evaluation logs the saved
    `evaluation_rows.csv` if it was killed after evaluating, and is skipped once MLflow
    holds a finished evaluation run under the same protocol.
    """
    from sigmarl.cli import handle_sigterm
    from sigmarl.evaluation.protocol import ROWS_FILE, checkpoint_name, evaluate_and_log
    from sigmarl.tracking import connect, experiment_id, records
    from sigmarl.training import checkpoint as ckpt
    from sigmarl.training.loop import train

    handle_sigterm()  # in a launcher's worker process, SIGTERM must end runs as KILLED too
    enter_sweep_folder()
    cfg = as_config(cfg)
    run_dir = Path(cfg.run_dir)
    (run_dir / FAILED_FILE).unlink(missing_ok=True)
    try:
        cfg = replace(cfg, resume=(run_dir / ckpt.RESUME_FILE).exists(), threads=job_threads(cfg.threads))
        use_threads(cfg.threads)  # training and this job's evaluation
        result = train(cfg)
        if not result.finished:
            return "interrupted"
        if cfg.tracking.enabled and result.run_id:
            client = connect(cfg)
            exp_id = experiment_id(client, cfg.tracking.experiment, create=True)
            if done := records.finished_evaluation(client, exp_id, result.run_id, records.eval_key(cfg.eval)):
                emit(f"{run_dir}: already evaluated")
                (run_dir / DONE_FILE).write_text(f"{done.info.run_id}\n")
                return "done"
        path = run_dir / checkpoint_name(cfg.eval.checkpoint)
        _, eval_run = evaluate_and_log(path, cfg, result.run_id, rows_file=run_dir / ROWS_FILE)
        (run_dir / DONE_FILE).write_text(f"{eval_run or ''}\n")
        return "done"
    except BaseException as e:
        if was_interrupted(e):  # Ctrl-C or SIGTERM: interrupted, not failed; a re-run resumes
            emit(f"sigmarl sweep: job {run_dir} interrupted; run the sweep again to resume", logging.WARNING)
            if isinstance(e, KeyboardInterrupt):
                raise
            raise Terminated() from e
        if not isinstance(e, Exception):
            raise
        message = str(e) if isinstance(e, SigmarlError) else traceback.format_exc()
        try:
            run_dir.mkdir(parents=True, exist_ok=True)
            (run_dir / FAILED_FILE).write_text(message)
        except OSError:  # an unwritable run folder is itself the error reported
            pass
        emit(f"sigmarl sweep: job {run_dir} failed: {str(e)[:500]}", logging.ERROR)
        return "failed"


def _parse(items: Sequence[str]) -> list[Override]:
    """Overrides as Hydra's own parser reads them (lists, quoted strings, range(), choice())."""
    try:
        return OverridesParser.create().parse_overrides(list(items))
    except HydraException as e:
        raise SigmarlError(f"bad override: {e}") from e


def _values(o: Override) -> list[str]:
    """What one override takes, as Hydra override strings: its single value, or each value
    of a sweep (`a,b`, `range(3)`, `choice(...)`)."""
    if not o.is_sweep_override():
        return [o.get_value_element_as_str()]
    if not o.is_discrete_sweep():
        raise SigmarlError(f"{o.input_line}: a sweep needs discrete values (a,b or range() or choice()), "
                           "not an interval")
    return list(o.sweep_string_iterator())


def _items(o: Override) -> list[str]:
    """A shorthand's values: the elements of `[a,b]`, the values of a sweep, or one value."""
    if not o.is_sweep_override() and isinstance(o.value(), list):
        return [str(v) for v in o.value()]
    return _values(o)


def _is_hydra(o: Override) -> bool:
    return o.key_or_group.split("/")[0].split(".")[0] == "hydra"


def _sweeps(overrides: Sequence[str]) -> list[tuple[str, list[str]]]:
    """(key as written, values) of every sweep over the job's config (not Hydra's settings)."""
    return [(o.get_key_element(), _values(o)) for o in _parse(overrides)
            if o.is_sweep_override() and not _is_hydra(o)]


def sweep_overrides(user: Sequence[str], cores: int | None = None) -> list[str]:
    """The multirun's overrides: the six presets and seed 0 unless the user chose, plus
    launcher settings from the core count. `seeds=[0,1,2]` (or `seeds=range(3)`) and
    `models=[M0,M4]` are shorthands for `seed=0,1,2` and the models' presets."""
    out: list[str] = []
    keys = set()
    seeds = models = None
    for o in _parse(user):
        if o.key_or_group == "seeds":
            seeds = _items(o)
            continue
        if o.key_or_group == "models":
            names = _items(o)
            unknown = [m for m in names if m not in MODELS]
            if unknown:
                raise SigmarlError(f"unknown model(s) {unknown}; choose from {', '.join(MODELS)}")
            models = [MODELS[m] for m in names]
            continue
        keys.add(o.key_or_group)
        out.append(o.input_line)
    for short, key, given in (("models", "obs", models), ("seeds", "seed", seeds)):
        if given is not None and key in keys:
            raise SigmarlError(f"give either {short}=[...] or {key}=..., not both")
        if given is not None and not given:
            raise SigmarlError(f"{short}=[] selects no jobs")
    if "obs" not in keys:
        out.append("obs=" + ",".join(models or MODELS.values()))
    if "seed" not in keys:
        out.append("seed=" + ",".join(seeds or ["0"]))
    n_jobs = math.prod(len(values) for _, values in _sweeps(out))
    cores = cores or os.cpu_count() or 1
    jobs = min(n_jobs, cores)
    if "hydra/launcher" not in keys:
        out.append("hydra/launcher=joblib")
        if "hydra.launcher.n_jobs" not in keys:
            out.append(f"hydra.launcher.n_jobs={jobs}")
    # `threads` is set in each job from what its launcher granted it (sigmarl.resources).
    return out


def _jobs(overrides: Sequence[str]) -> list[list[str]]:
    """Each job's overrides on top of `_fixed`: one value of every sweep, all combinations."""
    sweeps = _sweeps(overrides)
    return [[f"{key}={v}" for (key, _), v in zip(sweeps, combo, strict=True)]
            for combo in itertools.product(*(values for _, values in sweeps))]


def job_overrides(user_overrides: Sequence[str]) -> tuple[list[str], list[list[str]]]:
    """The overrides every job shares (Hydra's launcher settings included) and each job's own."""
    overrides = sweep_overrides(user_overrides)
    swept = {o.input_line for o in _parse(overrides) if o.is_sweep_override() and not _is_hydra(o)}
    return [o for o in overrides if o not in swept], _jobs(overrides)


def run_sweep(user_overrides: Sequence[str]) -> int:
    """Run the multirun in this process (Hydra's entry point), then summarise the jobs."""
    import hydra

    from sigmarl.config import register_configs
    from sigmarl.paths import conf_dir

    # conf/hydra/launcher/ray.yaml takes the Ray plugin's config name on purpose (a ready config
    # behind `hydra/launcher=ray`); Hydra warns that it validates it against the plugin's schema.
    warnings.filterwarnings("ignore", message=r"(?s).*validated against ConfigStore schema")
    overrides = sweep_overrides(user_overrides)
    if all_finished(overrides):  # answered from the run folders: no launcher, no store
        print("every job of this sweep is already trained and evaluated")
        return summarise(overrides)
    register_configs()
    _prepare_store(overrides)
    argv = sys.argv
    sys.argv = ["sigmarl-sweep", "--multirun", *overrides, sweep_folder_override()]
    try:
        main = hydra.main(config_path=str(conf_dir()), config_name="config", version_base=None)(run_job)
        main()
    finally:
        sys.argv = argv
    return summarise(overrides)


# set per invocation (the launcher's grant, resume, an interruption): not part of what ran
PER_INVOCATION = ("threads", "resume", "ppo.stop_after")


def all_finished(overrides: Sequence[str]) -> bool:
    """Whether every job's run folder holds a finished job of this very config: `evaluated.txt`,
    no `failed.txt`, the folder's config.yaml equal to the job's (evaluation settings aside) and
    its rows measured under the job's evaluation protocol."""
    from sigmarl.compose import compose_config

    fixed = _fixed(overrides)
    return all(_finished(compose_config([*fixed, *job])) for job in _jobs(overrides))


def _finished(cfg: Config) -> bool:
    import json

    import yaml

    from sigmarl.ablation import ROWS_META
    from sigmarl.config import as_dict
    from sigmarl.tracking.meta import flatten
    from sigmarl.tracking.records import eval_key

    run_dir = Path(cfg.run_dir)
    if not (run_dir / DONE_FILE).is_file() or (run_dir / FAILED_FILE).exists():
        return False
    try:
        saved = flatten(yaml.safe_load((run_dir / "config.yaml").read_text(encoding="utf-8")))
        evaluated = json.loads((run_dir / ROWS_META).read_text(encoding="utf-8"))
    except (OSError, ValueError, AttributeError):
        return False
    same = all(saved.get(key, object()) == value for key, value in flatten(as_dict(cfg)).items()
               if key not in PER_INVOCATION and not key.startswith("eval."))
    return same and evaluated.get("eval_key") == eval_key(cfg.eval)


def _prepare_store(overrides: Sequence[str]) -> None:
    """Validate every job's config, then check the MLflow store and create the experiment,
    here, before any job starts."""
    from sigmarl.compose import compose_config
    from sigmarl.tracking import connect, experiment_id

    fixed = _fixed(overrides)
    # Compose every job here, so a typo or a bad evaluation setting ends with one message
    # before anything trains, and two jobs never share a run folder.
    owner: dict[str, list[str]] = {}
    for job in _jobs(overrides):
        cfg = compose_config([*fixed, *job])
        check_eval(cfg.eval)
        if cfg.run_dir in owner:
            raise SigmarlError(
                f"jobs {' '.join(owner[cfg.run_dir])} and {' '.join(job)} would share the run folder "
                f"{cfg.run_dir}; sweep only models and seeds, and run one sweep per other setting, "
                "each with its own tracking.experiment=..."
            )
        owner[cfg.run_dir] = job
    cfg = compose_config(fixed)
    if cfg.tracking.enabled:
        experiment_id(connect(cfg), cfg.tracking.experiment, create=True)


def _fixed(overrides: Sequence[str]) -> list[str]:
    """The overrides that are the same for every job (no sweeps, no hydra settings)."""
    return [o.input_line for o in _parse(overrides) if not o.is_sweep_override() and not _is_hydra(o)]


def summarise(overrides: Sequence[str]) -> int:
    """Print each job's state from its run folder; non-zero if any failed or is unfinished."""
    from sigmarl.compose import compose_config

    fixed = _fixed(overrides)
    bad = 0
    print("\nsweep summary:")
    for job in _jobs(overrides):
        cfg = compose_config([*fixed, *job])
        run_dir = Path(cfg.run_dir)
        if (run_dir / FAILED_FILE).exists():
            state = "FAILED: " + (run_dir / FAILED_FILE).read_text().strip().splitlines()[-1][:200]
            bad += 1
        elif (run_dir / DONE_FILE).exists():
            state = "trained and evaluated"
        else:
            state = "unfinished (run the sweep again to resume)"
            bad += 1
        # Swept values other than the model and seed, if any, name the job too.
        extra = " ".join(j for j in job if not j.startswith(("obs=", "seed=")))
        print(f"  {cfg.model:<6} {cfg.obs.preset:<28} seed {cfg.seed:<3} {extra + '  ' if extra else ''}"
              f"{state}   [{run_dir}]")
    if not bad:
        print(f"next: sigmarl report {' '.join(o for o in fixed if o.startswith(('study', 'tracking')))}".rstrip())
    return 1 if bad else 0
