"""Planning a sweep: every job composed and checked in this process, before anything trains.

A typo or a bad value ends here in one line; so do two different training configs under one
label, two jobs sharing a run folder, and a run folder that holds another config's run. Each
variant is composed once, its seeds taken from that one composition.

A job is one seed of one variant (its run folder, its record); what the launcher runs is a
unit: one job, or `sweep.seeds_per_job` jobs of one variant trained as one seed block."""

from __future__ import annotations

import hashlib
import itertools
import os
import re
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

from sigmarl.compose import compose_config, compose_seeds
from sigmarl.compose.validate import check_eval, seeds_per_job
from sigmarl.config import Config, StudyConfig
from sigmarl.config.study import seed_list
from sigmarl.errors import SigmarlError
from sigmarl.eval_key import eval_key
from sigmarl.identity import check_label, differences, fingerprint
from sigmarl.policy_input import check_variant
from sigmarl.run import Run
from sigmarl.run.block_membership import check_membership, read_block
from sigmarl.sweep.command import Command, override_key, read_command, slug


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
class Unit:
    """What one launcher job runs: one seed, or a seed block of one variant's seeds."""

    key: str  # the plan's key and the multirun's sub-folder: <label>/seed<k> or <label>/seeds<a>_<b>_..
    jobs: list[Job]


@dataclass
class SweepPlan:
    study: StudyConfig
    fixed: list[str]  # the user's overrides that every job shares
    hydra: list[str]  # Hydra's own settings (launcher, ...), for the multirun
    jobs: list[Job] = field(default_factory=list)
    config: Config | None = None  # the sweep's config without any variant (tracking, study)
    units: list[Unit] = field(default_factory=list)
    swept: bool = False  # a key swept on the command line: the sweep's variants are a sub-study of their own
    twins: dict[str, str] = field(default_factory=dict)  # swept label -> the variant it composes the same as

    @property
    def labels(self) -> list[str]:
        return list(dict.fromkeys(j.label for j in self.jobs))


def plan_sweep(user: Sequence[str], cores: int | None = None,
               seeds_by_label: dict[str, list[int]] | None = None) -> SweepPlan:
    """Every job of `sigmarl sweep <user overrides>`, composed and checked; nothing is written.
    `seeds_by_label` gives each variant its own seeds (`seeds=auto`'s rounds)."""
    command = read_command(user)
    base = compose_config(command.fixed)
    variants = _variants(command, base)
    seeds = _seeds(command, base.study)
    plan = SweepPlan(base.study, command.fixed, command.hydra, config=base, swept=bool(command.sweeps))
    size = seeds_per_job(base)
    parents: dict[str, str] = {}  # variant -> its fingerprint without the swept values
    for name, own, parent in _labelled(command, base.study, variants):
        if name != parent and _same_as_parent(command, name, own, parent, variants[parent], parents):
            plan.twins[name] = parent  # its runs are the variant's own: reused, never trained twice
            name, own = parent, variants[parent]
        if name in plan.labels:
            continue
        jobs = _variant_jobs(name, [*command.fixed, *own, f"model={name}"], own,
                             (seeds_by_label or {}).get(name, seeds))
        plan.jobs += jobs
        plan.units += _units(jobs, size)
    _check_apart(plan.jobs)
    for unit in plan.units:  # a folder another block (or a lone run) trains in, refused before any job
        check_membership([Run(j.run_dir) for j in unit.jobs], [j.seed for j in unit.jobs])
    plan.hydra += _launcher(command.hydra, len(plan.units), cores)
    # `threads` is set in each job from what its launcher granted it (sigmarl.resources).
    return plan


def job_overrides(user_overrides: Sequence[str]) -> tuple[list[str], list[list[str]]]:
    """For `sweep --cfg`: Hydra's settings the jobs share, and each job's own overrides."""
    plan = plan_sweep(user_overrides)
    return plan.hydra, [j.overrides for j in plan.jobs]


def _variants(command: Command, base: Config) -> dict[str, list[str]]:
    """Label -> the variant's overrides: the presets named by obs=..., else the study's
    variants (or the config as composed, for a study without any), as models=[...] picks."""
    study = base.study
    if command.obs is not None:  # presets named on the command line replace the study's variants
        variants = {compose_config([*command.fixed, f"obs={p}"]).model: [f"obs={p}"] for p in command.obs}
    else:
        variants = {check_label(k): list(v) for k, v in study.variants.items()} or {base.model: []}
    if command.models is None:
        return variants
    unknown = [m for m in command.models if m not in variants]
    if unknown:
        raise SigmarlError(f"unknown model(s) {unknown}; study {study.name!r} declares "
                           f"{', '.join(variants) or 'none'}")
    return {m: variants[m] for m in dict.fromkeys(command.models)}


def _same_as_parent(command: Command, name: str, own: list[str], parent: str, variant: list[str],
                    parents: dict[str, str]) -> bool:
    """Whether a swept value composes to its variant's own training config (the swept key at its
    value there, e.g. the default max_speed)."""
    try:
        if parent not in parents:
            parents[parent] = compose_config([*command.fixed, *variant, f"model={parent}"]).fingerprint
        return compose_config([*command.fixed, *own, f"model={name}"]).fingerprint == parents[parent]
    except SigmarlError as e:
        raise SigmarlError(f"variant {name}: {e}") from e


def sub_study_baseline(plan: SweepPlan) -> str:
    """The column a sweep's variants are compared with: the study's baseline where the sweep
    holds it (a swept value at its default), else the first label swept from it, else the first."""
    baseline, labels = plan.study.baseline, plan.labels
    return baseline if baseline in labels else next((m for m in labels if m.startswith(baseline + "_")), labels[0])


def _seeds(command: Command, study: StudyConfig) -> list[int]:
    values = command.seeds if command.seeds is not None else study.seeds
    if not values:
        raise SigmarlError(f"study {study.name!r} declares no seeds; give seeds=[...]")
    return seed_list(values)


def _labelled(command: Command, study: StudyConfig,
              variants: dict[str, list[str]]) -> Iterator[tuple[str, list[str], str]]:
    """(label, own overrides, the variant's label) of each variant and each value of a swept key:
    `<variant>_<key>-<value>`, hashed where it would be longer than a label may be."""
    fixed_keys = {override_key(o) for o in command.fixed}
    keys = [key for key, _ in command.sweeps]
    for label, variant in variants.items():
        clash = sorted(fixed_keys & {override_key(v) for v in variant})
        if clash:
            raise SigmarlError(f"{', '.join(clash)} is set by variant {label} of study {study.name!r}; "
                               "change the study's variants, or leave it out of the command line")
        for combo in itertools.product(*(values for _, values in command.sweeps)):
            name = "_".join([label, *(slug(key, v) for key, v in zip(keys, combo, strict=True))])
            name = check_label(name if len(name) <= 64 else
                               f"{label}_{hashlib.sha1(name.encode()).hexdigest()[:8]}")
            yield name, [*variant, *(f"{key}={v}" for key, v in zip(keys, combo, strict=True))], label


def _variant_jobs(label: str, overrides: list[str], variant: list[str], seeds: list[int]) -> list[Job]:
    """The variant's jobs, one per seed, from one composition; each checked against the run
    its run folder already holds."""
    try:
        configs = compose_seeds(overrides, seeds) if seeds else []
    except SigmarlError as e:
        raise SigmarlError(f"variant {label}: {e}") from e
    if configs and configs[0].driver.kind != "mappo":  # deterministic and untrained: one run, the first seed
        seeds, configs = seeds[:1], configs[:1]
    jobs = []
    for seed, cfg in zip(seeds, configs, strict=True):
        check_variant(cfg, check_eval(cfg.eval), label)  # before training, not after it
        earlier = earlier_config(Path(cfg.run_dir))
        if earlier is not None and earlier.fingerprint != cfg.fingerprint:
            raise SigmarlError(f"{cfg.run_dir} holds a run of another training config "
                               f"({differences(earlier, cfg)}); choose another runs_root=... or label")
        jobs.append(Job(f"{label}/seed{seed}", label, seed, [*overrides, f"seed={seed}"], variant, cfg.run_dir,
                        cfg.fingerprint, eval_key(cfg.eval)))
    if configs:
        _check_siblings(configs[0], seeds)
    return jobs


def _check_siblings(cfg: Config, seeds: list[int]) -> None:
    """A seed joins its label's run folders only if their seeds were trained with its settings:
    a seed of another budget beside a study's seeds is refused before anything trains, naming
    the settings that differ (the report would refuse the mix only afterwards)."""
    label_dir = Path(cfg.run_dir).parent
    if Path(cfg.run_dir).name != f"seed{cfg.seed}" or not label_dir.is_dir():
        return  # a run_dir of the user's own layout: no study's seeds beside it
    ours = {f"seed{s}" for s in seeds}
    for sibling in sorted(label_dir.glob("seed*")):
        if sibling.name in ours or not re.fullmatch(r"seed\d+", sibling.name):
            continue
        try:
            earlier = earlier_config(sibling)
        except SigmarlError:
            continue  # a damaged config.yaml is its own run's to refuse, when it is swept
        if earlier is not None and earlier.fingerprint != cfg.fingerprint:
            raise SigmarlError(f"{label_dir} holds {sibling.name}, trained with other settings than seed(s) "
                               f"{', '.join(map(str, seeds))} ({differences(earlier, cfg)}); a study's run folders "
                               "hold one training config: drop the overrides that differ, or choose another "
                               "runs_root=... or label")


def _units(jobs: list[Job], size: int) -> list[Unit]:
    """One variant's jobs in blocks of `size` seeds, in seed order as given; a lone seed is its
    own job's unit. A re-run of the same sweep makes the same blocks, so each resumes whole.

    Blocks are formed from the seeds still to train, as a block's seeds must stand at one
    iteration: a finished seed gets no unit (nor a `failed.txt` from a block it cannot join),
    a seed that trained in a block goes on with that block's seeds (its `block.json`), and a
    lone run, part or fully trained, goes on alone."""
    if size <= 1:
        return [_unit([j]) for j in jobs]
    fresh: list[Job] = []
    started: dict[tuple, list[Job]] = {}  # each started seed's group, in the order first met
    for job in jobs:
        run = Run(job.run_dir)
        if finished(job):
            continue
        if (recorded := read_block(run)) is not None:
            started.setdefault(tuple(recorded), []).append(job)
        elif run.resume_file.exists() or run.final_file.exists():
            started[(job.seed,)] = [job]
        else:
            fresh.append(job)
    # a block's seeds in its recorded order, the order check_membership compares
    groups = [sorted(g, key=lambda j, k=k: k.index(j.seed) if j.seed in k else len(k)) for k, g in started.items()]
    groups += [fresh[i:i + size] for i in range(0, len(fresh), size)]
    return [_unit(g) for g in sorted(groups, key=lambda g: min(jobs.index(j) for j in g))]


def _unit(part: list[Job]) -> Unit:
    key = part[0].key if len(part) == 1 else f"{part[0].label}/seeds" + "_".join(str(j.seed) for j in part)
    return Unit(key, part)


def finished(job: Job) -> bool:
    """Whether the job's run folder holds this very job, done: `evaluated.txt`, no `failed.txt`,
    a config.yaml of the same fingerprint (checked when the plan was made) and whole rows
    measured under the job's evaluation protocol."""
    from sigmarl.rows import rows_measured

    run = Run(job.run_dir)
    if not run.done_file.is_file() or run.failed_file.exists() or not run.config_file.is_file():
        return False
    return rows_measured(run.rows_file, run.rows_meta_file, job.eval_key)


def _check_apart(jobs: list[Job]) -> None:
    """No two jobs share a run folder, and one label holds one training config."""
    owners: dict[str, Job] = {}
    first: dict[str, Job] = {}
    for job in jobs:
        if job.run_dir in owners:
            raise SigmarlError(f"jobs {owners[job.run_dir].key} and {job.key} would share the run "
                               f"folder {job.run_dir}")
        owners[job.run_dir] = job
        other = first.setdefault(job.label, job)
        if other.fingerprint != job.fingerprint:
            raise SigmarlError(f"two different training configs under the label {job.label} "
                               f"({other.key} and {job.key}); give each its own label")


def _launcher(hydra: list[str], n_jobs: int, cores: int | None) -> list[str]:
    """joblib with a worker per job up to the cores, unless the user chose a launcher."""
    if any(override_key(h) == "hydra/launcher" for h in hydra):
        return []
    if any(override_key(h) == "hydra.launcher.n_jobs" for h in hydra):
        return ["hydra/launcher=joblib"]
    return ["hydra/launcher=joblib", f"hydra.launcher.n_jobs={min(n_jobs, cores or os.cpu_count() or 1)}"]


def earlier_config(run_dir: Path) -> Config | None:
    """The training config of the run already in `run_dir`, with its fingerprint recomputed."""
    path = Run(run_dir).config_file
    if not path.is_file():
        return None
    from sigmarl.readers import read_run_config

    saved = read_run_config(path)
    return replace(saved, fingerprint=fingerprint(saved))
