"""`sigmarl report`: evaluation rows (from MLflow, or from a results folder with --from) ->
tables, figures, and a report run in the tracker (none with tracking.enabled=false)."""

from __future__ import annotations

import os
import re
import shutil
import socket
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from functools import partial
from pathlib import Path

from sigmarl.config import Config
from sigmarl.errors import SigmarlError
from sigmarl.eval_key import protocol_key
from sigmarl.readers import read_run_config
from sigmarl.report.build import BuildOptions, Report, build_report
from sigmarl.report.cells import label_order
from sigmarl.report.compare.verdicts import design_of
from sigmarl.report.study import run_records
from sigmarl.results import columns, folders
from sigmarl.run import Run
from sigmarl.scenarios import scenario, scenario_names
from sigmarl.tracking import connect, open_tracker, records
from sigmarl.tracking.meta import git_commit


@dataclass(frozen=True)
class ReportOptions:
    """What `sigmarl report` draws, whatever the rows come from."""

    latex: bool = False
    trim: bool = False  # drop each evaluation's best and worst simulation from the collision rates
    compare_paper: bool = False
    models: list[str] | None = None  # the columns, in order (default: the study's variants)
    ci: bool = False
    figures: bool = True
    animation_steps: int = 0  # > 0: one GIF per scenario of the baseline driving
    partial: bool = False  # report what is there when a run failed or a variant has no rows
    scenarios: list[str] | None = None  # only these (eval.scenarios=/study.scenarios= given), in this order
    overrides: tuple[str, ...] = ()  # the report's command line: each variant's column composes with them

    def __post_init__(self) -> None:
        if not 0 <= self.animation_steps <= MAX_ANIMATION_STEPS:
            raise SigmarlError(f"--animations takes 1..{MAX_ANIMATION_STEPS} steps, got {self.animation_steps}")
        if self.models is not None and (not self.models or not all(m.strip() for m in self.models)):
            raise SigmarlError(f"--models needs comma-separated labels, e.g. --models M0,M4; got {','.join(self.models)!r}")


MAX_ANIMATION_STEPS = 10_000  # a GIF of 10,000 frames is already beyond use; an evaluation's are 1200 steps


def make_report(cfg: Config, out_dir: Path | None = None, options: ReportOptions = ReportOptions()) -> Report:
    """Build the report of experiment `cfg.tracking.experiment` from its MLflow store; log it as
    a report run to the tracker.

    With figures, also the maps of the table's scenarios; with animation_steps > 0, one GIF
    per scenario of the baseline (its first seed's evaluated checkpoint) driving under the
    evaluation protocol.
    """
    experiment = cfg.tracking.experiment
    check_baseline(cfg, options)
    tracker = open_tracker(cfg)  # checked before any work
    client = connect(cfg, write=False)  # the rows are read from MLflow whichever tracker logs
    runs, where = _study_folders(cfg)
    lacking: list[str] = []  # seeds evaluated under other protocols only (one-off evaluations)
    try:
        rows = records.load_evaluation_rows(client, experiment, _study_protocol(cfg, options), lacking)
    except SigmarlError as e:  # no rows at all: say what became of the study's runs
        missing = columns.left_out(list(cfg.study.variants), set(), runs, where, declared=False)
        raise SigmarlError(f"{e}; " + "; ".join(map(str, missing)) if missing else str(e)) from e
    rows = only_scenarios(rows, options.scenarios, experiment)
    _refuse_other_labels(rows, cfg, options)
    expected = columns.variant_configs(options.overrides, dict(cfg.study.variants), rows["model"].astype(str))
    recorded = partial(records.evaluated_config, client)  # a run id -> its training config
    rows, wrong = columns.check_columns(rows, expected, options.partial, recorded)
    rows = columns.one_config_per_run(rows, list(expected))
    notes = [*wrong, *lacking, *_coverage(rows, cfg, options, runs, where)]
    curves = records.load_training_curves(client, experiment) if options.figures else None
    out_dir = out_dir or report_folder(experiment, cfg, options)
    configs = _column_configs(rows, recorded, expected)
    report = _build(rows, curves if curves is not None and len(curves) else None, out_dir, cfg,
                    lambda: _mlflow_checkpoint(client, experiment, cfg.study.baseline), options, notes, configs,
                    run_records(runs, rows))
    tracker.log_report(report.composite, report.paths.values(), {
        "evaluation_runs": ",".join(sorted(set(rows["eval_run_id"]))) if "eval_run_id" in rows else "",
        **what_it_reports(report, cfg, options),
    })
    return report


def _study_protocol(cfg: Config, options: ReportOptions) -> str:
    """The protocol (`eval_key.protocol_key`) of the study's evaluations, the only rows a report
    reads: the config's, composed without the scenarios a report of some of them chose."""
    if options.scenarios is None:
        return protocol_key(cfg.eval)
    from sigmarl.compose import compose_config

    chosen = ("eval.scenarios", "study.scenarios")
    return protocol_key(compose_config([o for o in options.overrides
                                        if o.split("=", 1)[0].lstrip("+") not in chosen]).eval)


def report_folder(name: str, cfg: Config, options: ReportOptions) -> Path:
    """reports/<name>, or, for a report of other columns or another baseline than the study's,
    a folder of its own beside it (reports/<name>_baseline-M3_models-M0+M3): another report
    never overwrites the study's."""
    parts = []
    if any(o.lstrip("+").split("=", 1)[0].strip() == "study.baseline" for o in options.overrides):
        parts.append(f"baseline-{cfg.study.baseline}")
    if options.models:
        models = "+".join(options.models)
        parts.append(f"models-{models if len(models) <= 80 else str(len(options.models)) + '-models'}")
    return Path("reports") / "_".join([name, *parts])


def what_it_reports(report: Report, cfg: Config, options: ReportOptions) -> dict[str, str]:
    """What tells one report run from another of the same experiment: its baseline, columns,
    scenarios and metrics, and the command line it was given (tags and params of the run)."""
    return {"baseline": cfg.study.baseline, "models": ",".join(report.table.models),
            "scenarios": ",".join(report.table.scenarios), "metrics": ",".join(cfg.study.metrics),
            "overrides": " ".join(options.overrides)}


def make_report_from_folder(root: Path | list[Path], cfg: Config, out_dir: Path | None = None,
                            options: ReportOptions = ReportOptions()) -> Report:
    """The report of a results folder, or of several (a study whose variants live in different
    folders, e.g. reused runs of another study), `sigmarl.results.folders`: no MLflow reads, no
    training.

    Logged as a report run to the tracker (experiment `cfg.tracking.experiment`).
    Default output: reports/<folder name> (several folders: reports/<study name>).
    """
    check_baseline(cfg, options)
    roots = [Path(r) for r in (root if isinstance(root, list) else [root])]
    results = folders.read_many(roots, options.partial)
    results.rows = only_scenarios(results.rows, options.scenarios, ", ".join(map(str, roots)))
    root = roots[0]
    out_dir = out_dir or report_folder(roots[0].resolve().name if len(roots) == 1 else cfg.study.name, cfg, options)
    curves = results.curves if len(results.curves) else None  # read anyway: training.md needs them
    runs = [(r.label, r.seed, r.path) for r in results.runs]
    # the folders' runs without rows are in the notes already (read_results): only variants never run added
    notes = _coverage(results.rows, cfg, options, runs, ", ".join(map(str, roots)), runs_noted=True)
    tracker = open_tracker(cfg)  # checked before any work
    configs = _folder_configs(results.runs)
    beside = folders.imported_folder_beside(root) if options.compare_paper else None  # the paper's own policies
    report = _build(results.rows, curves, out_dir, cfg, lambda: _folder_checkpoint(results, root, cfg),
                    options, extra_notes=[*results.notes, *notes], configs=configs,
                    provenance=run_records(runs, results.rows),
                    imported=folders.read_imported(beside) if beside is not None else None)
    tracker.log_report(report.composite, report.paths.values(),
                       {"source": ",".join(str(r.resolve()) for r in roots), **what_it_reports(report, cfg, options)},
                       source=",".join(str(r) for r in roots))
    return report


def check_baseline(cfg: Config, options: ReportOptions) -> None:
    """--models keeps the study's baseline among the columns, or names another with
    study.baseline=...; never the first listed in silence."""
    models = options.models
    if models is None or not cfg.study.variants or cfg.study.baseline in models:
        return
    if any(o.split("=", 1)[0].lstrip("+") == "study.baseline" for o in options.overrides):
        raise SigmarlError(f"study.baseline={cfg.study.baseline} is not among --models {','.join(models)}: "
                           "the baseline must be one of the columns")
    raise SigmarlError(f"--models {','.join(models)} leaves out study {cfg.study.name!r}'s baseline "
                       f"{cfg.study.baseline}: add it, or say which column is the baseline with "
                       "study.baseline=<one of them>")


def _refuse_other_labels(rows, cfg: Config, options: ReportOptions) -> None:
    """A study's report shows its declared variants; a store holding only other labels (a
    command-line sweep's own variants, e.g. M0_max_speed-0.6) is refused, naming them."""
    present = list(dict.fromkeys(rows["model"].astype(str)))
    declared = list(cfg.study.variants)
    if options.models is None and declared and not set(present) & set(declared):
        raise SigmarlError(f"no evaluation rows of study {cfg.study.name!r}'s variants ({', '.join(declared)}); "
                           f"its store holds {', '.join(present)}: report those with --models "
                           f"{','.join(present)} study.baseline=<one of them>")


def only_scenarios(rows, scenarios: list[str] | None, where: str):
    """The rows of `scenarios` (all rows where None); a scenario without rows is refused in one line."""
    if scenarios is None:
        return rows
    have = list(dict.fromkeys(rows["scenario"].astype(str)))
    if absent := [s for s in scenarios if s not in have]:
        raise SigmarlError(f"no evaluation rows of scenario(s) {', '.join(absent)} in {where}; "
                           f"its rows are of {', '.join(have)}")
    return rows[rows["scenario"].astype(str).isin(scenarios)].reset_index(drop=True)


def _column_configs(rows, recorded: Callable[[str], Config | None], expected: dict[str, Config]) -> dict[str, Config]:
    """label -> the training config of its first evaluated run (its run folder's config.yaml),
    else the variant's composition (the columns were checked to be it, `check_columns`)."""
    out = {}
    for label, group in rows.groupby(rows["model"].astype(str), sort=False):
        own = recorded(str(group["eval_run_id"].iloc[0])) if "eval_run_id" in group else None
        if own is not None or label in expected:
            out[label] = own if own is not None else expected[label]
    return out


def _folder_configs(runs) -> dict[str, Config]:
    """label -> the config.yaml of its first run folder that has one (checked reader)."""
    out = {}
    for run in runs:
        path = Run(run.path).config_file
        if run.label not in out and path.is_file():
            out[run.label] = read_run_config(path)
    return out


def _build(rows, curves, out_dir: Path, cfg: Config, baseline_checkpoint: Callable[[], Path],
           options: ReportOptions, extra_notes=(), configs: dict[str, Config] | None = None,
           provenance: dict | None = None, imported=None) -> Report:
    """Tables, figures, the scenarios' maps and the baseline's animations, drawn into a staging
    folder and moved into out_dir only when all are complete."""
    models = options.models
    if models is None and cfg.study.variants:
        models = _study_labels(rows, list(cfg.study.variants))
    with staged(out_dir) as staging:
        build = BuildOptions(out_dir=staging, models=models, trim=options.trim,
                             compare_paper=options.compare_paper, latex=options.latex, ci=options.ci,
                             figures=options.figures, extra_notes=tuple(extra_notes),
                             order=list(cfg.study.variants) or None, baseline=cfg.study.baseline,
                             design=design_of(cfg.study, models or sorted(set(rows["model"].astype(str)))),
                             configs=configs, defaults=_defaults() if configs is not None else None,
                             commit=git_commit(), provenance=provenance, imported=imported)
        report = build_report(rows, build, curves)
        known = [s for s in report.table.scenarios if s in scenario_names()]  # the maps the rows ran on
        if options.figures:
            _add_maps(report, staging, known)
        if options.animation_steps > 0:
            report.paths.update(_animations(baseline_checkpoint(), cfg, staging, options.animation_steps, known))
        publish(report, staging, out_dir)
    return report


def _defaults() -> Config:
    """The configuration without overrides: what the study page's shared settings are measured from."""
    from sigmarl.compose import compose_config

    return compose_config([])


def _coverage(rows, cfg: Config, options: ReportOptions, runs, where: str, runs_noted: bool = False) -> list[str]:
    """Notes of the study's runs the report leaves out; refused in one line where a run failed
    or a declared variant has no rows (`columns.check`), unless options.partial. Checked against
    the study's variants where the rows hold any of them, else against every label present."""
    present = list(dict.fromkeys(rows["model"].astype(str)))
    declared = options.models or list(cfg.study.variants)
    claimed = any(m in declared for m in present)
    variants = declared if claimed else list(dict.fromkeys([*present, *(label for label, _, _ in runs)]))
    reported = set(zip(rows["model"].astype(str), rows["seed"].astype(int), strict=True))
    missing = columns.left_out(variants, reported, runs, where, declared=claimed)
    columns.check(declared if claimed else [], reported, missing, cfg.study.name, options.partial)
    return [f"Left out: {m}." for m in missing if not runs_noted or m.seed is None]


def _study_folders(cfg: Config) -> tuple[list[tuple[str, int, Path]], str]:
    """(label, seed, path) of every run folder under the study's runs_root (and those its
    variants set of their own), and where they were looked for."""
    roots = [Path(cfg.runs_root)] + [Path(o.split("=", 1)[1]) for v in cfg.study.variants.values()
                                     for o in v if o.startswith("runs_root=")]
    roots = list(dict.fromkeys(roots))
    found = []
    for root in roots:
        try:
            found += [(r.label, r.seed, r.path) for r in folders.run_folders(root)]
        except SigmarlError:  # no folder there, or none inside it
            pass
    return found, ", ".join(map(str, roots))


def _study_labels(rows, declared: list[str]) -> list[str] | None:
    """The study's variants in the rows, in the study's order (a command-line sweep's own
    variants, e.g. M0_hidden-64-64, are a sub-study of their own: `--models`); None (all labels)
    if none is there."""
    present = list(dict.fromkeys(rows["model"].astype(str)))
    ours = [m for m in present if m in declared]
    return label_order(ours, declared) if ours else None


def _folder_checkpoint(results, root: Path, cfg: Config) -> Path:
    """The baseline's evaluated checkpoint (its first seed) in a results folder."""
    # lazy: torch only where a checkpoint is named
    from sigmarl.evaluation.protocol import checkpoint_name

    baseline = cfg.study.baseline
    path = folders.checkpoint_of(results.runs, baseline, checkpoint_name(cfg.eval.checkpoint))
    if path is None:
        raise SigmarlError(f"animations need {baseline}'s {checkpoint_name(cfg.eval.checkpoint)} in {root}; "
                           "none found")
    return path


@contextmanager
def staged(out_dir: Path) -> Iterator[Path]:
    """A staging folder inside `out_dir` for the report's files, removed afterwards: files are
    moved in only when all are complete, so a report killed half-way (Ctrl-C, SIGTERM) leaves
    the previous files, never a half-written one."""
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        _remove_stale_staging(out_dir)
        staging = Path(tempfile.mkdtemp(prefix=f".staging-{os.getpid()}@{socket.gethostname()}-", dir=out_dir))
    except OSError as e:
        raise SigmarlError(f"{out_dir} is not a folder the report can write ({e.strerror}); "
                           "use --out <folder>") from None
    try:
        yield staging
    finally:
        shutil.rmtree(staging, ignore_errors=True)


def _remove_stale_staging(out_dir: Path) -> None:
    """The staging folders a report killed by SIGKILL left (no `finally` ran): those of a process
    of this host that is gone, and those of older versions, which did not name theirs."""
    for old in out_dir.glob(".staging-*"):
        owner = re.fullmatch(r"\.staging-(\d+)@(.+)-[^-]+", old.name)
        if owner and (owner.group(2) != socket.gethostname() or _alive(int(owner.group(1)))):
            continue  # another host's, or a live report's
        shutil.rmtree(old, ignore_errors=True)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # another user's process: alive
        return True
    return True


def publish(report: Report, staging: Path, out_dir: Path) -> None:
    paths = {}
    for key, path in report.paths.items():
        target = out_dir / Path(path).relative_to(staging)
        target.parent.mkdir(parents=True, exist_ok=True)
        os.replace(path, target)
        paths[key] = target
    report.paths = paths


def _add_maps(report: Report, out_dir: Path, scenarios: list[str]) -> None:
    """The maps the scenarios ran on, as the evaluation builds them."""
    # lazy: Hydra and the maps only where map figures are drawn
    from sigmarl.maps import load_map, scenario_map_config
    from sigmarl.maps.plot import save_scenario_maps

    maps = [(s, load_map(scenario_map_config(s)), scenario(s).n_agents) for s in scenarios]
    report.paths["scenario_maps"] = save_scenario_maps(out_dir / "scenario_maps.png", maps)


def _mlflow_checkpoint(client, experiment: str, baseline: str) -> Path:
    """The baseline's evaluated checkpoint (its first seed) as recorded in MLflow, if on this
    machine."""
    path = records.evaluated_checkpoint(client, experiment, baseline)
    if path is None:
        raise SigmarlError(f"animations need {baseline}'s evaluated checkpoint on this machine; none found")
    return path


def _animations(path: Path, cfg: Config, out_dir: Path, steps: int, scenarios: list[str]) -> dict[str, Path]:
    """One GIF per scenario of checkpoint `path` driving (evaluation's work; the report only
    collects the files)."""
    # lazy: torch only for --animations
    from sigmarl.evaluation.animation import animate_checkpoint

    # simulation 0 of the evaluation's batch: the rows' simulation 0
    return animate_checkpoint(path, scenarios, steps, int(cfg.eval.seed), out_dir, prefix=cfg.study.baseline,
                              device=cfg.device, n_sims=int(cfg.eval.n_sims))
