"""One sweep job, as Hydra's launcher runs it: train (or resume, or skip) and evaluate one run,
or a seed block of one variant's runs."""

from __future__ import annotations

import contextlib
import logging
import os
import re
import sys
import traceback
from dataclasses import replace
from pathlib import Path

from hydra.core.singleton import Singleton
from omegaconf import DictConfig

from sigmarl.compose import compose_config, compose_seeds
from sigmarl.config import Config, as_config
from sigmarl.errors import SigmarlError, handle_sigterm, interruption, raise_if_interrupted
from sigmarl.eval_key import eval_key
from sigmarl.evaluation.protocol import evaluate_and_log, evaluate_rows, has_rows
from sigmarl.identity import differences
from sigmarl.progress import emit
from sigmarl.readers import read_json
from sigmarl.resources import end_with_the_sweep, enter_sweep_folder, job_threads, use_threads
from sigmarl.run import Run, write_atomic
from sigmarl.run_owner import NotOurs
from sigmarl.sweep.plan import earlier_config
from sigmarl.tracking import open_tracker
from sigmarl.training.loop import train_block


def run_job(cfg: DictConfig | Config) -> str:
    """Train (or resume, or skip) and evaluate one unit of the plan, a seed or a seed block of
    one variant; returns 'done', 'failed', 'interrupted' or 'busy' (for a block, the worst of
    its seeds').

    `cfg` is the job's config as Hydra's launcher hands it over (a DictConfig naming the plan
    and the job's key in it), or an already composed `Config`.

    Every step can be killed at any instant and the job run again: training resumes from
    `checkpoint.pt` (a block from its seeds' common one; or starts from scratch if it never got
    that far) and completes the MLflow record of a training that was killed after its end;
    evaluation logs the saved `evaluation_rows.csv` if it was killed after evaluating, and is
    skipped once MLflow holds a finished evaluation run under the same protocol.
    """
    handle_sigterm()  # in a launcher's worker process, SIGTERM must end runs as KILLED too
    enter_sweep_folder()
    end_with_the_sweep()
    try:
        cfgs = _job_configs(cfg)
    except SigmarlError as e:  # the plan is unreadable or the config tree changed under it
        print(f"sigmarl sweep: job failed: {e}", file=sys.stderr)
        return "failed"
    runs = [Run(Path(c.run_dir)) for c in cfgs]
    emit(f"sigmarl sweep: job {', '.join(str(r.dir) for r in runs)} started in process {os.getpid()}")
    try:
        with contextlib.ExitStack() as held:  # one writer per run folder, for the whole job
            for run in runs:
                held.enter_context(run.lock())
            return _train_and_evaluate(cfgs, runs)
    except SigmarlError as e:
        if "in use by another sigmarl process" not in str(e):
            raise
        print(f"sigmarl sweep: job {', '.join(str(r.dir) for r in runs)} skipped: {e}", file=sys.stderr)
        return "busy"


def _train_and_evaluate(cfgs: list[Config], runs: list[Run]) -> str:
    for run in runs:
        run.clear_failed()
    try:
        threads = job_threads(cfgs[0].threads)
        cfgs = [replace(c, resume=r.resume_file.exists(), threads=threads) for c, r in zip(cfgs, runs, strict=True)]
        use_threads(threads)  # training and this job's evaluation
        if cfgs[0].study.checkpoints_from:  # a study that evaluates trained runs, not trains them
            return _worst([_one_seed(_evaluate_trained, c, r) for c, r in zip(cfgs, runs, strict=True)])
        if cfgs[0].driver.kind != "mappo":  # a driver that needs no training: evaluated at once
            return _worst([_one_seed(_evaluate_driver, c, r) for c, r in zip(cfgs, runs, strict=True)])
        trackers = [open_tracker(c) for c in cfgs]  # one connection per seed, for its training and evaluation
        results = train_block(cfgs, trackers)  # one seed: a block of one
    except BaseException as e:
        return _worst([_failed(e, r) for r in runs])
    if not all(r.finished for r in results):
        return "interrupted"
    return _worst([_one_seed(_evaluate, c, r, t, res)
                   for c, r, t, res in zip(cfgs, runs, trackers, results, strict=True)])


def _one_seed(step, cfg: Config, run: Run, *args) -> str:
    """One seed's evaluation; its failure is its own, the block's other seeds go on."""
    try:
        return step(cfg, run, *args)
    except BaseException as e:
        return _failed(e, run)


def _worst(states: list[str]) -> str:
    return next((s for s in ("interrupted", "failed") if s in states), "done")


def _evaluate(cfg: Config, run: Run, tracker, result) -> str:
    """Evaluate a trained seed, or complete what a killed evaluation left."""
    run_dir = run.dir
    if result.run_id and (done := tracker.finished_evaluation(result.run_id, eval_key(cfg.eval))):
        if has_rows(run.rows_file, cfg):
            emit(f"{run_dir}: already evaluated")
        else:  # the store holds the evaluation, the folder lost its rows: measure them again
            emit(f"{run_dir}: evaluated, but its {run.rows_file.name} is missing or damaged: evaluating again",
                 logging.WARNING)
            evaluate_rows(run.checkpoint(cfg.eval.checkpoint), cfg, run.rows_file)
        run.mark_done(done)
        return "done"
    _, eval_run = evaluate_and_log(run.checkpoint(cfg.eval.checkpoint), cfg, result.run_id,
                                   rows_file=run.rows_file, tracker=tracker)
    run.mark_done(eval_run)
    return "done"


def _failed(e: BaseException, run: Run) -> str:
    """An interrupt goes on up (a re-run resumes); any other error is written to `failed.txt`
    and the job returns, so that the sweep's other jobs go on."""
    run_dir = run.dir
    if interruption(e) is not None:  # Ctrl-C or SIGTERM: interrupted, not failed
        emit(f"sigmarl sweep: job {run_dir} interrupted; run the sweep again to resume", logging.WARNING)
        raise_if_interrupted(e)
    if not isinstance(e, Exception):
        raise e
    message = str(e) if isinstance(e, SigmarlError) else traceback.format_exc()
    try:
        if not isinstance(e, NotOurs):  # a user's folder: not even a failure's mark goes into it
            run_dir.mkdir(parents=True, exist_ok=True)
            run.mark_failed(message)
    except OSError:  # an unwritable run folder is itself the error reported
        pass
    emit(f"sigmarl sweep: job {run_dir} failed: {str(e)[:500]}", logging.ERROR)
    return "failed"


def _evaluate_trained(cfg: Config, run: Run) -> str:
    """Evaluate the run of the same label, seed and training config under
    `study.checkpoints_from` into this job's own run folder (its config.yaml, rows and marks),
    leaving the trained run as it is."""
    source = Run(Path(cfg.study.checkpoints_from) / cfg.model / f"seed{cfg.seed}")
    trained = earlier_config(source.dir)
    if trained is None or not source.checkpoint(cfg.eval.checkpoint).is_file():
        raise SigmarlError(f"{source.dir} holds no trained run to evaluate (study.checkpoints_from)")
    if trained.fingerprint != cfg.fingerprint:
        raise SigmarlError(f"{source.dir} was trained with another config ({differences(trained, cfg)})")
    use_threads(cfg.threads)
    write_atomic(run.config_file, source.config_file.read_text())
    _, eval_run = evaluate_and_log(source.checkpoint(cfg.eval.checkpoint), cfg, None, progress=False,
                                   rows_file=run.rows_file)
    run.mark_done(eval_run)
    return "done"


def _evaluate_driver(cfg: Config, run: Run) -> str:
    """Evaluate the rule-based driver into the job's run folder (nothing to train)."""
    from sigmarl.evaluation.driven import evaluate_driver

    run.mark_done(evaluate_driver(cfg, run, open_tracker(cfg)))
    return "done"


def _job_configs(cfg: DictConfig | Config) -> list[Config]:
    """A job's configs, one per seed: composed from its plan entry (Hydra's composition only
    carries the plan's path and the job's key; a block's entry names its seeds' entries), or
    as given."""
    if isinstance(cfg, Config):
        return [cfg]
    plan, key = str(cfg.study.plan), str(cfg.study.job)
    if not plan:
        return [as_config(cfg)]
    entries = _plan_entries(Path(plan), key)
    state = Singleton.get_state()  # composing here must not disturb the running Hydra job
    try:
        jobs = _compose_entries(entries)
    finally:
        Singleton.set_state(state)
    for job, entry in zip(jobs, entries, strict=True):
        if job.fingerprint != entry["fingerprint"]:
            raise SigmarlError(f"job {key}: its config changed since the sweep was planned "
                               "(config files edited?); run the sweep again")
    return [replace(job, overrides=list(entry["variant"])) for job, entry in zip(jobs, entries, strict=True)]


def _compose_entries(entries: list[dict]) -> list[Config]:
    """The entries' configs: a block's seeds in one Hydra composition (their overrides, as the
    plan writes them, differ only in the last, `seed=<k>`), else one composition per entry."""
    shared = entries[0]["overrides"][:-1]
    seeds = [_last_seed(entry["overrides"], shared) for entry in entries]
    if len(entries) > 1 and None not in seeds:
        return compose_seeds(shared, seeds)
    return [compose_config(entry["overrides"]) for entry in entries]


def _last_seed(overrides: list[str], shared: list[str]) -> int | None:
    last = overrides[-1] if overrides else ""
    if overrides[:-1] != shared or not re.fullmatch(r"seed=\d+", last):
        return None
    return int(last.split("=", 1)[1])


def _plan_entries(plan: Path, key: str) -> list[dict]:
    """The seeds' entries of a job's key: its own, or its block members'."""
    fix = "run the sweep again (it writes its plan anew)"
    entries = read_json(plan, "the sweep's plan", fix, shape={key: dict})
    members = entries[key].get("members")
    if members is None:
        return [_plan_entry(plan, key, entries)]
    if not isinstance(members, list) or not all(isinstance(m, str) and isinstance(entries.get(m), dict)
                                                for m in members):
        raise SigmarlError(f"{plan}: the sweep's plan entry of block {key!r} does not name its seeds' entries; {fix}")
    return [_plan_entry(plan, m, entries) for m in members]


def _plan_entry(plan: Path, key: str, entries: dict) -> dict:
    """The job's entry of the plan file (written whole by `write_plan`, but a user's disk or
    hand can damage it), or one line naming the file."""
    fix = "run the sweep again (it writes its plan anew)"
    entry = entries[key]
    shape = {"overrides": list, "variant": list, "fingerprint": str}
    if any(not isinstance(entry.get(k), kind) for k, kind in shape.items()) \
            or not all(isinstance(o, str) for o in entry["overrides"] + entry["variant"]):
        raise SigmarlError(f"{plan}: the sweep's plan entry of job {key!r} is not overrides, variant and "
                           f"fingerprint; {fix}")
    return entry
