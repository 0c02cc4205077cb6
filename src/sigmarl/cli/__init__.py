"""`sigmarl` command line: thin dispatch onto the library; user errors end in one message."""

from __future__ import annotations

import argparse
import errno
import os
import sys
from collections.abc import Sequence
from pathlib import Path

from sigmarl import __version__
from sigmarl.cli.info import (
    EVAL_KEYS_EPILOG,
    KEYS_EPILOG,
    KeysHelp,
    PrintAndExit,
    completion_script,
    info_text,
    print_cfg,
)
from sigmarl.cli.watch import add_watch_options, cmd_animate
from sigmarl.errors import SigmarlError, exit_code, handle_sigterm, interruption
from sigmarl.evaluation import import_command
from sigmarl.paths import add_user_conf_dir, check_surroundings, config_files, ensure_writable
from sigmarl.resources import use_threads
from sigmarl.scenarios import scenario, scenario_names


def _map_names() -> list[str]:
    return sorted(config_files("map"))  # the package's and those of a --config-dir


def _resolve_map(name: str, overrides: Sequence[str]):
    """A map by config name (conf/map/<name>.yaml) or by OSM file path."""
    # lazy: `sigmarl --help` and a bad argument answer without Hydra, torch or MLflow
    from sigmarl.compose import compose_config
    from sigmarl.compose.validate import check_map
    from sigmarl.config.suggest import did_you_mean
    from sigmarl.maps import load_map, map_config

    # a map's name in any case (`maps show CPM`): the config files are lower case
    name = {n.lower(): n for n in _map_names()}.get(name.lower(), name)
    if name.endswith(".osm") or Path(name).suffix == ".osm":
        cfg = compose_config(["map=osm", f"map.path={Path(name).resolve()}", *overrides])
    elif name in _map_names() and not overrides:  # its file alone: no composition (~1 s each)
        return load_map(check_map(map_config(name)))
    elif name in _map_names():
        cfg = compose_config([f"map={name}", *overrides])
    else:
        raise SigmarlError(f"unknown map {name!r}{did_you_mean(name, _map_names())}; known maps: "
                           f"{', '.join(_map_names())} (or a path to an .osm file)")
    return load_map(cfg.map)


def cmd_maps(args: argparse.Namespace) -> None:
    if args.action == "list":
        overrides = [args.map, *args.overrides] if args.map else args.overrides
        print(f"{'map':<18}{'lanelets':>9}{'routes':>8}{'size (m)':>14}{'lane width':>12}")
        for name in _map_names():
            if name == "osm":
                continue
            m = _resolve_map(name, overrides)
            w, h = m.size
            print(f"{name:<18}{len(m.lanelets):>9}{len(m.routes):>8}{f'{w:.2f} x {h:.2f}':>14}{m.lane_width:>12.2f}")
        return
    if not args.map:
        raise SigmarlError("sigmarl maps show needs a map name, e.g. `sigmarl maps show cpm`")
    from sigmarl.maps.multilane import width_check  # lazy, as above
    from sigmarl.maps.plot import save_map_figure

    m = _resolve_map(args.map, args.overrides)
    out = Path(args.out or Path("reports") / "maps" / f"{m.name}.png")
    ensure_writable(out.parent, "use --out <file.png> in another folder")
    save_map_figure(m, out, show_ids=args.ids)
    print(f"wrote {out}\n{width_check(m)}")


def cmd_train(args: argparse.Namespace) -> None:
    # lazy: `sigmarl --help` and a bad argument answer without Hydra, torch or MLflow
    from sigmarl.compose import compose_block

    cfgs = compose_block(args.overrides)  # a bad override is answered before torch is imported
    use_threads(cfgs[0].threads)
    from sigmarl.training import train_block

    for result in train_block(cfgs):
        best = "n/a" if result.best_reward is None else f"{result.best_reward:.2f}"
        state = "finished" if result.finished else "stopped (resume with resume=true)"
        print(f"{state} after {result.iterations} iterations; best mean episode reward {best}; "
              f"checkpoints in {result.run_dir}" + (f"; MLflow run {result.run_id}" if result.run_id else ""))


def cmd_evaluate(args: argparse.Namespace) -> None:
    # lazy: `sigmarl --help` and a bad argument answer without Hydra, torch or MLflow
    from sigmarl.compose import compose_config
    from sigmarl.evaluation import target

    if args.animate:
        return cmd_animate(args)
    if import_command.takes(args):  # a policy of the paper's own code
        return import_command.run(args)
    target.check_evaluate_overrides(args.overrides)
    for name in args.scenario or ():  # a wrong name is answered before Hydra, in well under a second
        scenario(name)
    cfg = compose_config(args.overrides)
    if args.scenario:
        cfg.eval.scenarios = list(args.scenario)
    path = target.into_its_experiment(target.resolve_checkpoint(args.target, cfg), cfg, args.overrides)  # no torch yet
    use_threads(cfg.threads)
    from sigmarl.evaluation.protocol import evaluate_and_log, rows_file_for
    from sigmarl.metrics import measured, scaled, units_text

    rows_file = Path(args.out) if args.out else rows_file_for(path, cfg)
    with target.run_folder_held(path):  # not while `sigmarl train` writes it (its best.pt may change)
        rows, run_id = evaluate_and_log(path, cfg, train_run_id=None, rows_file=rows_file, add_metrics=args.add_metrics)
    means = scaled(rows, measured(rows)).groupby(rows["scenario"], sort=False).mean()
    print(f"{rows['model'].iloc[0]} ({path}), {cfg.eval.n_sims} simulations x {cfg.eval.steps} steps, "
          f"seed {cfg.eval.seed}: {units_text()}")
    print(means.round(3).to_string())
    print(f"wrote {rows_file}")
    if run_id:
        print(f"MLflow evaluation run {run_id} in experiment {cfg.tracking.experiment!r}")


def cmd_sweep(args: argparse.Namespace) -> int:
    """A sweep; with `seeds=auto`, in rounds that add seeds where they decide (`sigmarl.cli.adaptive`)."""
    rest = [o for o in args.overrides if o.replace(" ", "") != "seeds=auto"]
    if len(rest) < len(args.overrides):
        from sigmarl.cli.adaptive import run_auto

        return run_auto(rest)
    # lazy: `sigmarl --help` and a bad argument answer without Hydra, torch or MLflow
    from sigmarl.sweep import run_sweep

    return run_sweep(args.overrides, check=args.check)


def cmd_report(args: argparse.Namespace) -> None:
    if args.plan and not args.source:
        raise SigmarlError("--plan reads a results folder: give it with --from FOLDER")
    # lazy: `sigmarl --help` and a bad argument answer without Hydra, torch or MLflow
    from sigmarl.compose import compose_config

    models = None if args.models is None else args.models.split(",")
    if args.plan:
        from sigmarl.report.plan import plan_from_folder

        print(plan_from_folder([Path(s) for s in args.source], models, study=compose_config(args.overrides).study),
              end="")
        return
    from sigmarl.tracking.store import missing_store

    cfg = compose_config(args.overrides)
    if not args.source and (db := missing_store(cfg)):  # nothing to read: create no empty store
        raise SigmarlError(f"nothing to report: no MLflow store at {db}; run `sigmarl sweep` here first, "
                           "point tracking.tracking_uri=... at the study's store, or use --from FOLDER")
    # after the store's check (no store: no pandas); --models '' or --animations -5: one line
    from sigmarl.cli.report import ReportOptions, make_report, make_report_from_folder

    options = ReportOptions(latex=args.latex, trim=args.trim, compare_paper=args.compare_paper, models=models, ci=args.ci,
                            figures=not args.no_figures, animation_steps=args.animations, partial=args.partial,
                            scenarios=list(cfg.eval.scenarios) if _sets(args.overrides, "eval.scenarios",
                                                                        "study.scenarios") else None,
                            overrides=tuple(args.overrides))
    if args.animations:
        use_threads(cfg.threads)
    out_dir = Path(args.out) if args.out else None
    if args.source:
        report = make_report_from_folder([Path(s) for s in args.source], cfg, out_dir, options)
    else:
        report = make_report(cfg, out_dir, options)
    from sigmarl.cli.report_console import console_text

    print(console_text(report, verbose=args.verbose))  # short; --verbose: the table's text, its notes, ...


def _sets(overrides: Sequence[str], *keys: str) -> bool:
    """Whether one of `overrides` sets one of `keys` (`key=...`, `+key=...`, `++key=...`)."""
    return any(o.split("=", 1)[0].lstrip("+") in keys for o in overrides)


def _disk_full(error: BaseException) -> str | None:
    """One line for a full disk or quota anywhere in `error`'s chain (a library may wrap the
    OSError), else None. Whatever was written before stays valid: every file is replaced whole."""
    seen: set[int] = set()
    while error is not None and id(error) not in seen:
        seen.add(id(error))
        if isinstance(error, OSError) and error.errno in (errno.ENOSPC, errno.EDQUOT):
            where = f": {error.filename}" if error.filename else ""
            return f"{error.strerror}{where}; every file written before is intact: free some space and run again"
        error = error.__cause__ or error.__context__
    return None
def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="sigmarl",
        description="The SigmaRL observation-design ablation study: maps, environment, MAPPO training, evaluation, report.",
    )
    p.add_argument("--config-dir", action="append", default=[], metavar="DIR",
                   help="a folder of your own configs laid out like conf/ (study/, scenario/, map/, ...), "
                        "searched before sigmarl's; repeatable")
    p.add_argument("--version", action="version", version=f"sigmarl {__version__}")
    p.add_argument("--info", action=PrintAndExit, nargs="?", text=info_text, metavar="KEY",
                   help="versions, the config folders, the config groups and their options (with --config-dir "
                        "DIR before it or $SIGMARL_CONFIG_PATH, yours too, marked [1], [2], ...); with KEY "
                        "(ppo.lr, or a group: ppo) its type, default and help")
    p.add_argument("--completion", action=PrintAndExit, choices=["bash"], text=completion_script,
                   help="print a shell completion script: eval \"$(sigmarl --completion bash)\" "
                        "(zsh: after `autoload bashcompinit && bashcompinit`)")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")
    _add_maps(sub)
    train = sub.add_parser("train", help="train one model with MAPPO (resumable, tracked in MLflow); seeds=[0,1,2,3] "
                           "trains those seeds as one seed block, one batched computation in one process",
                           epilog=KEYS_EPILOG, formatter_class=KeysHelp)
    train.add_argument(
        "overrides", nargs="*", default=[],
        help="Hydra overrides, e.g. obs=no_ego_view seed=3 resume=true; ppo=smoke is a seconds-long try, "
             "kept apart in experiment sigmarl-smoke (runs/sigmarl-smoke/...)",
    )
    train.set_defaults(func=cmd_train)
    ev = sub.add_parser("evaluate", help="evaluate a trained model on the test scenarios",
                        epilog=EVAL_KEYS_EPILOG, formatter_class=KeysHelp)
    ev.add_argument("target", help="checkpoint file, training run folder, MLflow training run id, or SigmaRL policy")
    ev.add_argument("--scenario", action="append", help=f"one of {', '.join(scenario_names())} (default: the "
                    "study's, the paper's four); repeatable")
    ev.add_argument("--out", help="the CSV for the per-simulation rows (default: evaluation_rows.csv beside the checkpoint)")
    ev.add_argument("--add-metrics", action="store_true", help="saved rows lacking a metric declared since: evaluate "
                    "again and add its column, the saved columns kept as they are")
    ev.add_argument("overrides", nargs="*", default=[], help="Hydra overrides, e.g. eval.n_sims=8 eval.steps=600")
    add_watch_options(ev)
    import_command.add_options(ev)  # --model, --label: a SigmaRL policy (paper:M<k>, a .pth file)
    ev.set_defaults(func=cmd_evaluate)
    sw = sub.add_parser("sweep", help="train the study's variants x seeds in parallel (Hydra multirun), then evaluate each")
    sw.add_argument("overrides", nargs="*", default=[],
                    help="Hydra overrides, e.g. study=quick seeds=[0,1,2] models=[M0,M4] hydra.launcher.n_jobs=3")
    sw.add_argument("--check", action="store_true", help="check the study, train nothing: load every map, build every "
                    "environment, print each job's estimated compute (timed here) and memory; writes nothing")
    sw.set_defaults(func=cmd_sweep)
    rp = _add_report(sub)
    for sub_parser in (train, ev, sw, rp):
        sub_parser.add_argument("--cfg", choices=["job", "hydra", "all"],
                                help="print the config instead of running: job (composed and resolved; a "
                                     "sweep's every job), hydra (Hydra's settings) or all")
    return p


def _add_maps(sub) -> None:
    maps = sub.add_parser("maps", help="list road maps or draw one to PNG")
    maps.add_argument("action", choices=["list", "show"])
    maps.add_argument("map", nargs="?", help="map name (see `sigmarl maps list`) or an .osm file")
    maps.add_argument("--out", help="PNG file to write (default: reports/maps/<map>.png)")
    maps.add_argument("--ids", action="store_true", help="label lanelet ids")
    maps.add_argument("overrides", nargs="*", default=[], help="Hydra overrides, e.g. map.lane_width=0.25")
    maps.set_defaults(func=cmd_maps)


def _add_report(sub) -> argparse.ArgumentParser:
    rp = sub.add_parser("report", help="the results table (paper's Table I layout), composite scores, figures")
    rp.add_argument("--latex", action="store_true", help="also write table.tex (booktabs)")
    rp.add_argument("--trim", action="store_true", help="drop the best and worst simulation for collision rates, as the paper did")
    rp.add_argument("--compare-paper", action="store_true", help="show the paper's numbers beside ours")
    rp.add_argument("--ci", action="store_true",
                    help="show 95%% bootstrap intervals (over seeds and simulations) in the cells")
    rp.add_argument("--models", help="comma-separated models to compare (default: all evaluated)")
    rp.add_argument("--from", dest="source", metavar="FOLDER", action="append",
                    help="rebuild from a results folder (<label>/seed<k>/ with evaluation_rows.csv, "
                         "metrics.csv) instead of reading MLflow; repeatable (a study whose variants "
                         "live in several folders)")
    rp.add_argument("--out", help="output folder (default: reports/<experiment>, or reports/<FOLDER name>)")
    rp.add_argument("--no-figures", action="store_true", help="tables only")
    rp.add_argument("--partial", action="store_true",
                    help="report what is there when a run failed, a variant has run folders but no "
                         "evaluation rows (unfinished or not evaluated), or a run under a variant's label "
                         "was trained with another config (each named in the notes); without it, such a "
                         "report is refused. A variant never run (no folder, no rows) is a note either way")
    rp.add_argument("--animations", type=int, nargs="?", const=200, default=0, metavar="STEPS",
                    help="also one GIF per scenario of the study's baseline driving (default 200 steps)")
    rp.add_argument("--verbose", action="store_true", help="print the full text (table, notes, statistics, verdicts), "
                    "not the short report (Table I's headline, the verdict counts, where the files are)")
    rp.add_argument("--plan", action="store_true",
                    help="with --from: print each comparison's verdict and the seeds a decision needs, nothing else")
    rp.add_argument("overrides", nargs="*", default=[], help="Hydra overrides, e.g. study=quick or tracking.experiment=NAME")
    rp.set_defaults(func=cmd_report)
    return rp


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    # Overrides may follow options (`evaluate RUN --scenario CPM eval.n_sims=8`).
    if extra and hasattr(args, "overrides") and all("=" in e and not e.startswith("-") for e in extra):
        args.overrides = [*args.overrides, *extra]
    elif extra:
        parser.error(f"unrecognized arguments: {' '.join(extra)}")
    handle_sigterm()
    try:
        check_surroundings()
        for folder in args.config_dir:
            add_user_conf_dir(folder)
        rc = print_cfg(args) if getattr(args, "cfg", None) else args.func(args)
    except SigmarlError as e:
        print(f"sigmarl: error: {e}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # `sigmarl maps list | head`: the reader left; nothing to say
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no second error at exit
        return 1
    except BaseException as e:
        if (full := _disk_full(e)) is not None:
            print(f"sigmarl: error: {full}", file=sys.stderr)
            return 2
        if (stop := interruption(e)) is None:
            raise
        said, code = exit_code(stop)
        print(f"sigmarl: {said}", file=sys.stderr)
        return code
    return rc if isinstance(rc, int) else 0

