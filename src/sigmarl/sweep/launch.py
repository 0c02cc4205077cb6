"""Running a plan: its file in the sweep's folder, Hydra's multirun over it in this process,
and the summary read back from the run folders."""

from __future__ import annotations

import hashlib
import json
import os
import re
import shlex
import sys
import warnings
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager, nullcontext
from pathlib import Path

import hydra

from sigmarl.compose import search_path_override
from sigmarl.config import register_configs
from sigmarl.identity import TRAINING_GROUPS
from sigmarl.paths import CONFIG_PATH, conf_dir, user_conf_dirs
from sigmarl.resources import sweep_folder_override, sweep_owner_override
from sigmarl.run import Run, write_atomic
from sigmarl.sweep.command import override_key
from sigmarl.sweep.plan import SweepPlan, finished, plan_sweep, sub_study_baseline
from sigmarl.sweep.task import run_job
from sigmarl.tracking import open_tracker
from sigmarl.tracking.records import evaluation_runs

PLANS = Path("multirun") / ".plans"  # in the sweep's folder: every job reads its entry there


def run_sweep(user_overrides: Sequence[str], check: bool = False) -> int:
    """Plan, then run the multirun in this process (Hydra's entry point), then summarise;
    `check`: plan, build and time everything instead, and write nothing (`sweep.check`)."""
    if check:
        from sigmarl.sweep.check import check_sweep

        return check_sweep(list(user_overrides))
    return launch(plan_sweep(user_overrides))


def launch(plan: SweepPlan) -> int:
    """Run a plan's jobs as Hydra's multirun in this process, then summarise them."""
    # conf/hydra/launcher/ray.yaml takes the Ray plugin's config name on purpose (a ready config
    # behind `hydra/launcher=ray`); Hydra warns that it validates it against the plugin's schema.
    warnings.filterwarnings("ignore", message=r"(?s).*validated against ConfigStore schema")
    if all(finished(job) for job in plan.jobs):  # answered from the run folders: no launcher, no store
        print("every job of this sweep is already trained and evaluated")
        return summarise(plan)
    # the tracking store checked here, before any job starts; it keeps the study's record
    tracker = open_tracker(plan.config) if plan.config is not None else None
    overrides = multirun_overrides(plan, write_plan(plan))
    register_configs()

    full_errors = bool(os.environ.get("HYDRA_FULL_ERROR"))  # the user asked for Hydra's tracebacks
    argv = sys.argv
    sys.argv = ["sigmarl-sweep", "--multirun", *overrides, sweep_folder_override(), *sweep_owner_override()]
    try:
        added = {j.label: j.variant for j in plan.jobs if j.label not in plan.study.variants}
        keys = [u.key for u in plan.units]
        where = f"multirun/{plan.config.tracking.experiment}" if plan.config is not None else "multirun"
        print(f"sigmarl sweep: {len(keys)} job(s) ({', '.join(keys[:6])}{' ...' if len(keys) > 6 else ''}); "
              f"each job's log in {where}/<job>/", flush=True)
        print(f"sigmarl sweep: starting {_workers(plan)} worker process(es); each imports torch and the simulator "
              "before its first line (tens of seconds)", flush=True)
        with tracker.study(added) if tracker is not None else nullcontext(), _launcher_errors_raised():
            main = hydra.main(config_path=str(conf_dir()), config_name="config", version_base=None)(run_job)
            main()
    except BaseException as e:
        if tracker is not None:
            end_orphaned_runs(plan, tracker)
        if not isinstance(e, Exception) or full_errors:
            raise
        # the launcher itself failed (a worker lost to SIGKILL, a cluster refusing jobs): one
        # line, then the summary from the run folders; a re-run resumes what was cut short
        print(f"sigmarl sweep: {launcher_failure(e, cut_short(plan))}", file=sys.stderr)
        summarise(plan)
        return 1
    finally:
        sys.argv = argv
    return summarise(plan)


def _workers(plan: SweepPlan) -> str:
    """How many worker processes the launcher starts, as the plan sets it (else: as it chooses)."""
    found = [h.split("=", 1)[1] for h in plan.hydra if override_key(h) == "hydra.launcher.n_jobs"]
    return found[-1] if found else "its"


@contextmanager
def _launcher_errors_raised() -> Iterator[None]:
    """Hydra prints a launcher's exception as a traceback and exits; under HYDRA_FULL_ERROR it
    raises it instead, for `launch` to answer in one line."""
    before = os.environ.get("HYDRA_FULL_ERROR")
    os.environ["HYDRA_FULL_ERROR"] = "1"
    try:
        yield
    finally:
        if before is None:
            os.environ.pop("HYDRA_FULL_ERROR", None)
        else:
            os.environ["HYDRA_FULL_ERROR"] = before


def launcher_failure(e: Exception, started: Mapping[str, str] | None = None) -> str:
    """What a launcher's exception means, in one line; `started`: the jobs it cut short, each
    with what it was doing (`cut_short`)."""
    first = (str(e).strip().splitlines() or [""])[0]
    if type(e).__name__ == "TerminatedWorkerError":  # loky: a worker died; it ends the others
        codes = re.search(r"exit codes of the workers are (\{[^}]*\})", str(e))
        return ("a worker process died" + (f" (exit {codes.group(1)})" if codes else "") + _during(started or {})
                + ", killed from outside (SIGKILL: the OOM killer?); joblib then ended the sweep's other "
                "workers. Their runs are ended KILLED and resume when the sweep runs again (fewer "
                "jobs at once, hydra.launcher.n_jobs=..., if memory ran out)")
    return (f"the launcher failed: {type(e).__name__}: {first[:300]} (HYDRA_FULL_ERROR=1 shows the traceback); "
            "finished jobs are kept and the sweep resumes the rest when run again")


def _during(started: Mapping[str, str]) -> str:
    """' while training one of A, B or evaluating C': which worker died is not known, only
    what each job it may have been was doing."""
    parts = []
    for doing in ("training", "evaluating"):
        keys = [key for key, what in started.items() if what == doing]
        if keys:
            parts.append(f"{doing} {'one of ' if len(keys) > 1 else ''}{', '.join(keys)}")
    return f" while {' or '.join(parts)}" if parts else ""


def cut_short(plan: SweepPlan) -> dict[str, str]:
    """The jobs begun but not finished, each with what it was doing: `evaluating` once its
    training is done (`final.pt`, or a study that evaluates trained runs), else `training`."""
    evaluates = plan.config is not None and bool(plan.config.study.checkpoints_from)
    return {job.key: "evaluating" if evaluates or Run(job.run_dir).final_file.exists() else "training"
            for job in plan.jobs if Run(job.run_dir).config_file.is_file() and not finished(job)}


def end_orphaned_runs(plan: SweepPlan, tracker) -> None:
    """A launcher that ends its workers (loky on Ctrl-C or SIGTERM, a worker's SIGKILL) leaves
    their MLflow runs RUNNING, the training run or the evaluation run being logged: end KILLED
    (interrupted, resumable) the ones whose run folder no process holds any more, as the
    worker itself would have."""
    source = plan.config.study.checkpoints_from if plan.config is not None else ""
    for job in plan.jobs:
        run = Run(job.run_dir)
        # a study of trained runs trains nothing: its evaluations name the trained run's record
        trained = Run(Path(source) / job.label / f"seed{job.seed}") if source else run
        if not trained.run_id_file.is_file() or run.done_file.exists():
            continue
        try:
            with run.lock():  # a worker that still lives holds it, and ends its own runs
                run_id = trained.run_id_file.read_text().strip()
                if not source:
                    record = tracker.training_run(run_id, reopen=False)
                    if record.status() == "RUNNING":
                        record.finish("KILLED")
                _end_evaluations(tracker, run_id, job.eval_key)
        except Exception:  # noqa: BLE001 (best effort on the way out; the re-run repairs it)
            continue


def _end_evaluations(tracker, train_run_id: str, key: str) -> None:
    """End KILLED the job's evaluation runs left RUNNING (a re-run deletes them before it logs
    its own: sigmarl.tracking.records). MLflow's alone: another tracker keeps its own."""
    client = getattr(tracker, "client", None)
    if client is None:
        return
    for old in evaluation_runs(client, tracker.experiment_id(), train_run_id, key, "RUNNING"):
        client.set_terminated(old.info.run_id, "KILLED")


def write_plan(plan: SweepPlan) -> Path:
    """The plan as a file in the sweep's folder, named by its content (two sweeps never share
    one by accident), written whole or not at all."""
    entries: dict[str, dict] = {j.key: {"overrides": j.overrides, "variant": j.variant,
                                        "fingerprint": j.fingerprint} for j in plan.jobs}
    entries.update({u.key: {"members": [j.key for j in u.jobs]} for u in plan.units if len(u.jobs) > 1})
    text = json.dumps(entries, indent=1, sort_keys=True) + "\n"
    path = (PLANS / f"{hashlib.sha1(text.encode()).hexdigest()[:16]}.json").resolve()
    write_atomic(path, text)
    return path


def multirun_overrides(plan: SweepPlan, plan_file: Path) -> list[str]:
    """What Hydra's multirun gets: one job per unit of the plan (a seed or a seed block), named by its key."""
    users = [f"++hydra.job.env_set.{CONFIG_PATH}='{os.pathsep.join(map(str, user_conf_dirs()))}'"] \
        if user_conf_dirs() else []
    return [*search_path_override(), *plan.fixed, *plan.hydra, "study.job=" + ",".join(u.key for u in plan.units),
            f"study.plan='{plan_file}'", "hydra.job.name=sweep", "hydra.sweep.subdir=${study.job}", *users]


def summarise(plan: SweepPlan) -> int:
    """Print each job's state from its run folder; non-zero if any failed or is unfinished."""
    bad = 0
    width = max([len(j.label) for j in plan.jobs] + [6])
    # each column as wide as its longest entry: a long variant never pushes its row's seed aside
    variant_width = max([len(" ".join(j.variant)) for j in plan.jobs] + [8])
    seed_width = max([len(str(j.seed)) for j in plan.jobs] + [1])
    print("\nsweep summary:")
    for name, parent in plan.twins.items():
        print(f"  {name} is {parent}'s training config: its runs are {parent}'s, not trained twice")
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
        print(f"  {job.label:<{width}}  {variant:<{variant_width}}  seed {job.seed:<{seed_width}}  {state:<21}  [{run_dir}]")
    if not bad:
        print(f"next: {report_hint(plan)}")
    return 1 if bad else 0


def report_hint(plan: SweepPlan) -> str:
    """The `sigmarl report` command that finds this sweep's runs, as typed in the same folder:
    its --config-dir folders and the overrides that choose the study, the store and the run
    folders and the training settings (all of the sweep's where others move them too)."""
    from sigmarl.compose import compose_config

    # and the training settings every job shares: the report composes each column's config with
    # them, and a column whose runs were trained otherwise is refused (sigmarl.results.columns)
    keep = [o for o in plan.fixed
            if override_key(o).split(".")[0].lstrip("+~") in ("study", "tracking", "runs_root", *TRAINING_GROUPS)]
    if len(keep) < len(plan.fixed) and _where(compose_config(keep)) != _where(plan.config):
        keep = list(plan.fixed)
    dirs = [f"--config-dir {shlex.quote(_shown(d))}" for d in user_conf_dirs()]
    # a swept key's variants are a sub-study: exactly its columns, compared with a stated baseline
    own = ["--models", ",".join(plan.labels)] if plan.swept else []
    if plan.swept:
        keep = [o for o in keep if override_key(o) != "study.baseline"] + [f"study.baseline={sub_study_baseline(plan)}"]
    return " ".join(["sigmarl", *dirs, "report", *own, *map(shlex.quote, keep)])


def _where(cfg) -> tuple[str, ...]:
    return cfg.study.name, cfg.tracking.experiment, cfg.tracking.tracking_uri, str(cfg.runs_root)


def _shown(folder: Path) -> str:
    """A folder as the user would type it here: relative below the working folder."""
    try:
        return str(folder.relative_to(Path.cwd()))
    except ValueError:
        return str(folder)
