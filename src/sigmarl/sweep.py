"""`sigmarl sweep`: a study's variants x seeds as a Hydra multirun, each job training one run
and then evaluating it.

A study declares its variants (label -> overrides of the training config), a baseline and
seeds (`conf/study/<name>.yaml`). The sweep plans every job first, in this process: it
composes each job's config (a typo or bad value ends here, in one line, before anything
trains), refuses two different training configs under one label and a run folder that holds
another config's run, and writes the plan to a file. Hydra's launcher (joblib by default, any
other launcher plugin via `hydra/launcher=...`) then runs one job per plan entry, and each job
composes its config from the plan. A job that fails writes `failed.txt` into its run folder
and returns, so the others go on. Re-running the same sweep skips finished work: training
resumes from its last checkpoint or returns at once when finished, evaluation is skipped when
MLflow already holds a finished one under the same protocol.

On the command line, besides any override of the training config:
- `models=[M0,M4]` picks variants by label, `seeds=[0,1,2]` (or `seed=0,1,2`) the seeds;
- `obs=a,b` replaces the study's variants with those observation presets, labelled M0..M5
  (or custom-<hash>) from their flags, as a lone `sigmarl train` labels them;
- a sweep over any other key (`network.hidden=[64,64],[128,128]`) makes one variant per value
  and study variant, labelled `<variant>_<key>-<value>`.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import logging
import os
import re
import sys
import traceback
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.core.override_parser.types import Override
from hydra.errors import HydraException
from omegaconf import DictConfig

from sigmarl.ablation import check_eval
from sigmarl.config import Config, StudyConfig, as_config
from sigmarl.errors import SigmarlError, interruption, raise_if_interrupted
from sigmarl.progress import emit
from sigmarl.resources import (
    end_with_the_sweep,
    enter_sweep_folder,
    job_threads,
    sweep_folder_override,
    sweep_owner_override,
    use_threads,
)
from sigmarl.run import Run, write_atomic

PLANS = Path("multirun") / ".plans"  # in the sweep's folder: every job reads its entry there


@dataclass
class Job:
    key: str  # <label>/seed<k>: the plan's key, the multirun's sub-folder
    label: str
    seed: int
    overrides: list[str]  # everything the job composes its config from
    variant: list[str]  # the variant's own overrides (recorded in the run)
    run_dir: str
    fingerprint: str
    eval_key: str = ""  # the evaluation protocol it is evaluated under (sigmarl.tracking.records)


@dataclass
class SweepPlan:
    study: StudyConfig
    fixed: list[str]  # the user's overrides that every job shares
    hydra: list[str]  # Hydra's own settings (launcher, ...), for the multirun
    jobs: list[Job] = field(default_factory=list)
    config: Config | None = None  # the sweep's config without any variant (tracking, study)

    @property
    def labels(self) -> list[str]:
        return list(dict.fromkeys(j.label for j in self.jobs))


def run_job(cfg: DictConfig | Config) -> str:
    """Train (or resume, or skip) and evaluate one run; returns 'done', 'failed' or 'interrupted'.

    `cfg` is the job's config as Hydra's launcher hands it over (a DictConfig naming the plan
    and the job's key in it), or an already composed `Config`.

    Every step can be killed at any instant and the job run again: training resumes from
    `checkpoint.pt` (or starts from scratch if it never got that far) and completes the
    MLflow record of a training that was killed after its end; evaluation logs the saved
    `evaluation_rows.csv` if it was killed after evaluating, and is skipped once MLflow
    holds a finished evaluation run under the same protocol.
    """
    from sigmarl.errors import handle_sigterm

    handle_sigterm()  # in a launcher's worker process, SIGTERM must end runs as KILLED too
    enter_sweep_folder()
    end_with_the_sweep()
    try:
        cfg = _job_config(cfg)
    except SigmarlError as e:  # the plan is unreadable or the config tree changed under it
        print(f"sigmarl sweep: job failed: {e}", file=sys.stderr)
        return "failed"
    run_dir = Path(cfg.run_dir)
    try:
        with Run(run_dir).lock():  # one writer per run folder, for the whole job
            return _train_and_evaluate(cfg, run_dir)
    except SigmarlError as e:
        if "in use by another sigmarl process" not in str(e):
            raise
        print(f"sigmarl sweep: job {run_dir} skipped: {e}", file=sys.stderr)
        return "busy"


def _train_and_evaluate(cfg: Config, run_dir: Path) -> str:
    from sigmarl.evaluation.protocol import evaluate_and_log, evaluate_rows, has_rows
    from sigmarl.tracking import open_tracker, records
    from sigmarl.training.loop import train

    run = Run(run_dir)
    run.clear_failed()
    try:
        cfg = replace(cfg, resume=run.resume_file.exists(), threads=job_threads(cfg.threads))
        use_threads(cfg.threads)  # training and this job's evaluation
        if cfg.study.checkpoints_from:  # a study that evaluates trained runs, not trains them
            return _evaluate_trained(cfg, run_dir)
        tracker = open_tracker(cfg)  # one connection for the job's training and evaluation
        result = train(cfg, tracker)
        if not result.finished:
            return "interrupted"
        if result.run_id and (done := tracker.finished_evaluation(result.run_id, records.eval_key(cfg.eval))):
            if not has_rows(run.rows_file, cfg):  # the folder is the record: its rows come back
                emit(f"{run_dir}: already evaluated, but {run.rows_file.name} is missing: evaluating again "
                     "into the run folder", logging.WARNING)
                evaluate_rows(run.checkpoint(cfg.eval.checkpoint), cfg, run.rows_file)
            emit(f"{run_dir}: already evaluated")
            run.mark_done(done)
            return "done"
        _, eval_run = evaluate_and_log(run.checkpoint(cfg.eval.checkpoint), cfg, result.run_id,
                                       rows_file=run.rows_file, tracker=tracker)
        run.mark_done(eval_run)
        return "done"
    except BaseException as e:
        if interruption(e) is not None:  # Ctrl-C or SIGTERM: interrupted, not failed; a re-run resumes
            emit(f"sigmarl sweep: job {run_dir} interrupted; run the sweep again to resume", logging.WARNING)
            raise_if_interrupted(e)
        if not isinstance(e, Exception):
            raise
        message = str(e) if isinstance(e, SigmarlError) else traceback.format_exc()
        try:
            run_dir.mkdir(parents=True, exist_ok=True)
            run.mark_failed(message)
        except OSError:  # an unwritable run folder is itself the error reported
            pass
        emit(f"sigmarl sweep: job {run_dir} failed: {str(e)[:500]}", logging.ERROR)
        return "failed"


def _evaluate_trained(cfg: Config, run_dir: Path) -> str:
    """Evaluate the run of the same label, seed and training config under
    `study.checkpoints_from` into this job's own run folder (its config.yaml, rows and marks),
    leaving the trained run as it is."""
    import torch

    from sigmarl.evaluation.protocol import evaluate_and_log

    source = Run(Path(cfg.study.checkpoints_from) / cfg.model / f"seed{cfg.seed}")
    run = Run(run_dir)
    trained = _earlier_config(source.dir)
    if trained is None or not source.checkpoint(cfg.eval.checkpoint).is_file():
        raise SigmarlError(f"{source.dir} holds no trained run to evaluate (study.checkpoints_from)")
    if trained.fingerprint != cfg.fingerprint:
        from sigmarl.identity import differences

        raise SigmarlError(f"{source.dir} was trained with another config ({differences(trained, cfg)})")
    torch.set_num_threads(cfg.threads)
    write_atomic(run.config_file, source.config_file.read_text())
    _, eval_run = evaluate_and_log(source.checkpoint(cfg.eval.checkpoint), cfg, None, progress=False,
                                   rows_file=run.rows_file)
    run.mark_done(eval_run)
    return "done"


def _job_config(cfg: DictConfig | Config) -> Config:
    """A job's config: composed from its plan entry (Hydra's composition only carries the
    plan's path and the job's key), or as given."""
    if isinstance(cfg, Config):
        return cfg
    plan, key = str(cfg.study.plan), str(cfg.study.job)
    if not plan:
        return as_config(cfg)
    from hydra.core.singleton import Singleton

    from sigmarl.compose import compose_config
    from sigmarl.readers import read_json

    fix = "run the sweep again (it writes a new plan)"
    entry = read_json(Path(plan), "the sweep's plan", fix, {}).get(key) if Path(plan).is_file() else None
    if not isinstance(entry, dict) or not isinstance(entry.get("overrides"), list) \
            or not isinstance(entry.get("variant"), list) or not isinstance(entry.get("fingerprint"), str):
        raise SigmarlError(f"{plan}: the sweep's plan holds no readable job {key!r}; {fix}")
    state = Singleton.get_state()  # composing here must not disturb the running Hydra job
    try:
        job = compose_config(entry["overrides"])
    finally:
        Singleton.set_state(state)
    if job.fingerprint != entry["fingerprint"]:
        raise SigmarlError(f"job {key}: its config changed since the sweep was planned "
                           "(config files edited?); run the sweep again")
    return replace(job, overrides=list(entry["variant"]))


# ---------------------------------------------------------------------------------------------
# Planning


def _parse(items: Sequence[str]) -> list[Override]:
    """Overrides as Hydra's own parser reads them (lists, quoted strings, range(), choice())."""
    try:
        return OverridesParser.create().parse_overrides(list(items))
    except HydraException as e:
        raise SigmarlError(f"bad override: {e}") from e
    except ValueError as e:  # e.g. an integer too long for Python to parse (over 4300 digits)
        raise SigmarlError(f"bad override: {str(e).splitlines()[0]}") from e


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


def _key(override: str) -> str:
    """The key or group an override string sets (`+a.b=1` -> a.b, `obs=full` -> obs)."""
    return override.split("=", 1)[0].lstrip("+~")


def _slug(key: str, value: str) -> str:
    """`network.hidden`, `[64,64]` -> hidden-64-64: a label part that names a folder."""
    leaf = re.split(r"[./]", key)[-1]
    return f"{leaf}-" + (re.sub(r"[^A-Za-z0-9.]+", "-", value).strip("-") or "x")


def _seed_list(values: Sequence[object]) -> list[int]:
    """The seeds as whole numbers in the range `seed` takes, or one line naming the bad one."""
    from sigmarl.validate import SEED_MAX

    out = []
    for value in values:
        text = str(value).strip()
        if not re.fullmatch(r"\d{1,10}", text) or int(text) > SEED_MAX:
            raise SigmarlError(f"seeds: {text!r} is not a seed (a whole number in 0..{SEED_MAX}); "
                               "give e.g. seeds=[0,1,2]")
        out.append(int(text))
    return out


def plan_sweep(user: Sequence[str], cores: int | None = None,
               seeds_by_label: dict[str, list[int]] | None = None) -> SweepPlan:
    """Every job of `sigmarl sweep <user overrides>`, composed and checked; nothing is written.
    `seeds_by_label` gives each variant its own seeds (`seeds=auto`'s rounds)."""
    from sigmarl.compose import compose_config
    from sigmarl.identity import check_label

    fixed: list[str] = []
    hydra: list[str] = []
    sweeps: list[tuple[str, list[str]]] = []
    models = seeds = seed = obs = None
    for o in _parse(user):
        if o.key_or_group == "models":
            models = _items(o)
        elif o.key_or_group == "seeds":
            seeds = _items(o)
        elif _is_hydra(o):
            hydra.append(o.input_line)
        elif o.key_or_group == "seed":
            seed = _values(o)
        elif o.key_or_group == "obs":
            obs = _values(o)
        elif o.key_or_group in ("model", "overrides", "fingerprint") or o.key_or_group.startswith("study.job"):
            raise SigmarlError(f"{o.key_or_group} is set by the sweep itself (choose variants with models=[...])")
        elif o.is_sweep_override():
            sweeps.append((o.get_key_element(), _values(o)))
        else:
            fixed.append(o.input_line)
    if seeds is not None and seed is not None:
        raise SigmarlError("give either seeds=[...] or seed=..., not both")
    seeds = seeds if seeds is not None else seed
    if models is not None and obs is not None:
        raise SigmarlError("give either models=[...] or obs=..., not both")
    for short, given in (("models", models), ("seeds", seeds)):
        if given is not None and not given:
            raise SigmarlError(f"{short}=[] selects no jobs")

    base = compose_config(fixed)
    study = base.study
    if obs is not None:  # presets named on the command line replace the study's variants
        variants = {}
        for preset in obs:
            label = compose_config([*fixed, f"obs={preset}"]).model
            variants[label] = [f"obs={preset}"]
    else:
        variants = {check_label(k): list(v) for k, v in study.variants.items()}
        if not variants:  # a study without variants: the config as composed is the only one
            variants = {base.model: []}
    if models is not None:
        unknown = [m for m in models if m not in variants]
        if unknown:
            raise SigmarlError(f"unknown model(s) {unknown}; study {study.name!r} declares "
                               f"{', '.join(variants) or 'none'}")
        variants = {m: variants[m] for m in dict.fromkeys(models)}
    seed_list = _seed_list(seeds if seeds is not None else study.seeds)
    if not seed_list:
        raise SigmarlError(f"study {study.name!r} declares no seeds; give seeds=[...]")

    fixed_keys = {_key(o) for o in fixed}
    plan = SweepPlan(study, fixed, hydra, config=base)
    combos = list(itertools.product(*(values for _, values in sweeps))) if sweeps else [()]
    owners: dict[str, Job] = {}
    fingerprints: dict[str, tuple[str, Job]] = {}
    for label, variant in variants.items():
        clash = sorted(fixed_keys & {_key(v) for v in variant})
        if clash:
            raise SigmarlError(f"{', '.join(clash)} is set by variant {label} of study {study.name!r}; "
                               "change the study's variants, or leave it out of the command line")
        for combo in combos:
            extra = [f"{key}={v}" for (key, _), v in zip(sweeps, combo, strict=True)]
            name = "_".join([label, *(_slug(key, v) for (key, _), v in zip(sweeps, combo, strict=True))])
            name = check_label(name if len(name) <= 64 else
                               f"{label}_{hashlib.sha1(name.encode()).hexdigest()[:8]}")
            for seed in (seeds_by_label or {}).get(name, seed_list):
                overrides = [*fixed, *variant, *extra, f"model={name}", f"seed={seed}"]
                job = _checked_job(name, seed, overrides, [*variant, *extra], compose_config)
                if job.run_dir in owners:
                    raise SigmarlError(f"jobs {owners[job.run_dir].key} and {job.key} would share the run "
                                       f"folder {job.run_dir}")
                owners[job.run_dir] = job
                if name in fingerprints and fingerprints[name][0] != job.fingerprint:
                    raise SigmarlError(f"two different training configs under the label {name} "
                                       f"({fingerprints[name][1].key} and {job.key}); give each its own label")
                fingerprints.setdefault(name, (job.fingerprint, job))
                plan.jobs.append(job)
    if not any(_key(h) == "hydra/launcher" for h in hydra):
        plan.hydra.append("hydra/launcher=joblib")
        if not any(_key(h) == "hydra.launcher.n_jobs" for h in hydra):
            cores = cores or os.cpu_count() or 1
            plan.hydra.append(f"hydra.launcher.n_jobs={min(len(plan.jobs), cores)}")
    # `threads` is set in each job from what its launcher granted it (sigmarl.resources).
    return plan


def _checked_job(label: str, seed: int, overrides: list[str], variant: list[str], compose) -> Job:
    """One job composed and checked, and its run folder's earlier run (if any) compared."""
    from sigmarl.identity import differences

    cfg = compose(overrides)
    check_eval(cfg.eval)
    from sigmarl.tracking.records import eval_key

    job = Job(f"{label}/seed{seed}", label, seed, overrides, variant, cfg.run_dir, cfg.fingerprint,
              eval_key(cfg.eval))
    earlier = _earlier_config(Path(cfg.run_dir))
    if earlier is not None and earlier.fingerprint != cfg.fingerprint:
        raise SigmarlError(f"{cfg.run_dir} holds a run of another training config "
                           f"({differences(earlier, cfg)}); choose another runs_root=... or label")
    return job


def _earlier_config(run_dir: Path) -> Config | None:
    """The training config of the run already in `run_dir`, with its fingerprint recomputed."""
    from sigmarl.identity import fingerprint
    from sigmarl.readers import read_run_config

    path = Run(run_dir).config_file
    if not path.is_file():
        return None
    saved = read_run_config(path)
    return replace(saved, fingerprint=fingerprint(saved))


def write_plan(plan: SweepPlan) -> Path:
    """The plan as a file in the sweep's folder, named by its content (two sweeps never share
    one by accident), written whole or not at all."""
    from sigmarl.run import write_atomic

    entries = {j.key: {"overrides": j.overrides, "variant": j.variant, "fingerprint": j.fingerprint}
               for j in plan.jobs}
    text = json.dumps(entries, indent=1, sort_keys=True) + "\n"
    path = (PLANS / f"{hashlib.sha1(text.encode()).hexdigest()[:16]}.json").resolve()
    write_atomic(path, text)
    return path


def multirun_overrides(plan: SweepPlan, plan_file: Path) -> list[str]:
    """What Hydra's multirun gets: one job per plan entry, named by its key."""
    from sigmarl.compose import search_path_override
    from sigmarl.paths import CONFIG_PATH, user_conf_dirs

    users = [f"++hydra.job.env_set.{CONFIG_PATH}='{os.pathsep.join(map(str, user_conf_dirs()))}'"] \
        if user_conf_dirs() else []
    return [*search_path_override(), *plan.fixed, *plan.hydra, "study.job=" + ",".join(j.key for j in plan.jobs),
            f"study.plan='{plan_file}'", "hydra.sweep.subdir=${study.job}", *users]


def run_sweep(user_overrides: Sequence[str]) -> int:
    """Plan, then run the multirun in this process (Hydra's entry point), then summarise."""
    return launch(plan_sweep(user_overrides))


def launch(plan: SweepPlan) -> int:
    """Run a plan's jobs as Hydra's multirun in this process, then summarise them."""
    import hydra

    from sigmarl.config import register_configs
    from sigmarl.paths import conf_dir

    # conf/hydra/launcher/ray.yaml takes the Ray plugin's config name on purpose (a ready config
    # behind `hydra/launcher=ray`); Hydra warns that it validates it against the plugin's schema.
    warnings.filterwarnings("ignore", message=r"(?s).*validated against ConfigStore schema")
    if all(finished(job) for job in plan.jobs):  # answered from the run folders: no launcher, no store
        print("every job of this sweep is already trained and evaluated")
        return summarise(plan)
    _prepare_store(plan)
    overrides = multirun_overrides(plan, write_plan(plan))
    register_configs()
    argv = sys.argv
    sys.argv = ["sigmarl-sweep", "--multirun", *overrides, sweep_folder_override(), *sweep_owner_override()]
    try:
        main = hydra.main(config_path=str(conf_dir()), config_name="config", version_base=None)(run_job)
        main()
    finally:
        sys.argv = argv
    return summarise(plan)


def finished(job: Job) -> bool:
    """Whether the job's run folder holds this very job, done: `evaluated.txt`, no `failed.txt`,
    a config.yaml of the same fingerprint (checked when the plan was made) and its rows, measured
    under the job's evaluation protocol."""
    run = Run(job.run_dir)
    if not run.done_file.is_file() or run.failed_file.exists():
        return False
    try:
        evaluated = json.loads(run.rows_meta_file.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    return run.config_file.is_file() and run.rows_file.is_file() and isinstance(evaluated, dict) \
        and evaluated.get("eval_key") == job.eval_key


def job_overrides(user_overrides: Sequence[str]) -> tuple[list[str], list[list[str]]]:
    """For `sweep --cfg`: Hydra's settings the jobs share, and each job's own overrides."""
    plan = plan_sweep(user_overrides)
    return plan.hydra, [j.overrides for j in plan.jobs]


def _prepare_store(plan: SweepPlan) -> None:
    """Check the tracking store, here, before any job starts."""
    from sigmarl.tracking import open_tracker

    if plan.config is not None:
        open_tracker(plan.config)


def summarise(plan: SweepPlan) -> int:
    """Print each job's state from its run folder; non-zero if any failed or is unfinished."""
    bad = 0
    width = max([len(j.label) for j in plan.jobs] + [6])
    print("\nsweep summary:")
    for job in plan.jobs:
        run = Run(job.run_dir)
        run_dir = run.dir
        if (failure := run.failure()) is not None:
            state = "FAILED: " + failure
            bad += 1
        elif run.done_file.exists():
            state = "trained and evaluated"
        else:
            state = "unfinished (run the sweep again to resume)"
            bad += 1
        variant = " ".join(job.variant)
        print(f"  {job.label:<{width}} {variant:<28} seed {job.seed:<3} {state}   [{run_dir}]")
    if not bad:
        keep = [o for o in plan.fixed if o.startswith(("study", "tracking", "runs_root"))]
        print(f"next: sigmarl report {' '.join(keep)}".rstrip())
    return 1 if bad else 0

