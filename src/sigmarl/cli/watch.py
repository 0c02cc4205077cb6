"""`sigmarl evaluate TARGET --animate SCENARIO[,...]`: watch a trained policy drive, instead of
evaluating it. Any checkpoint, run folder or MLflow run id that `evaluate` takes, or a policy of
the paper's own code (`paper:M5 rules=paper`); any of the evaluation's simulations (`--sims`);
files under reports/animations, never in a run folder.

Everything the command line can get wrong is answered before torch is imported.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from sigmarl.errors import SigmarlError
from sigmarl.resources import use_threads
from sigmarl.run import Run
from sigmarl.scenarios import scenario

DEFAULT_DIR = Path("reports") / "animations"


def add_watch_options(ev: argparse.ArgumentParser) -> None:
    g = ev.add_argument_group("watch the policy drive (instead of evaluating it)")
    g.add_argument("--animate", metavar="SCENARIO[,...]",
                   help="write an animation (GIF; also MP4 where imageio-ffmpeg is installed) of the policy "
                        "driving these scenarios under the evaluation protocol; no rows, no MLflow run")
    g.add_argument("--sims", default="0", metavar="K[,...]",
                   help="which of the evaluation's simulations to animate (0..eval.n_sims-1; default 0): "
                        "simulation k is the evaluation rows' simulation k")
    g.add_argument("--frames", type=int, default=200, metavar="STEPS",
                   help="steps to animate, one frame each (default 200; the evaluation runs eval.steps)")
    g.add_argument("--animate-dir", metavar="DIR",
                   help=f"folder for the animations (default: {DEFAULT_DIR.as_posix()}); never a run folder")


def _ints(text: str, what: str) -> list[int]:
    try:
        values = [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise SigmarlError(f"{what} takes whole numbers separated by commas, e.g. 0,3; got {text!r}") from None
    if not values:
        raise SigmarlError(f"{what} names no simulation")
    return sorted(set(values))


def check_out_dir(out_dir: Path) -> None:
    """Refuse a folder in a run folder: a study's runs hold what training and evaluation wrote."""
    for folder in (out_dir.resolve(), *out_dir.resolve().parents):
        if Run(folder).config_file.is_file():
            raise SigmarlError(f"{out_dir} is inside the run folder {folder}; animations go elsewhere "
                               f"(default: {DEFAULT_DIR.as_posix()})")


def cmd_animate(args: argparse.Namespace) -> None:
    if args.scenario or args.out:
        raise SigmarlError("--animate names its own scenarios and writes no rows: drop --scenario and --out "
                           "(the folder is --animate-dir)")
    scenarios = [s.strip() for s in args.animate.split(",") if s.strip()]
    for name in scenarios or [""]:  # a wrong name is answered before Hydra
        scenario(name)
    sims = _ints(args.sims, "--sims")
    if args.frames < 1:
        raise SigmarlError(f"--frames {args.frames}: animate at least one step")
    out_dir = Path(args.animate_dir) if args.animate_dir else DEFAULT_DIR
    check_out_dir(out_dir)
    cfg, films_of = _driver(args, sims, out_dir)
    from sigmarl.evaluation.animation import mp4_writer_installed

    for name in scenarios:
        films = films_of(name)
        for k, film in films.items():
            print(f"{name} simulation {k}, {args.frames} steps from eval.seed {cfg.eval.seed}: {film.agent} "
                  f"with an agent-agent collision, {film.lane} with a lane collision; wrote "
                  + ", ".join(str(f) for f in film.files))
    if not mp4_writer_installed():
        print("GIF only: `pip install imageio-ffmpeg` also writes an MP4 beside each")


def _driver(args: argparse.Namespace, sims: list[int], out_dir: Path):
    """The config the policy drives under, and scenario -> its films: a checkpoint's, or a
    policy of the paper's own code as the named model under rules=paper|ours."""
    # lazy: `sigmarl --help` and a bad argument answer without Hydra, torch or MLflow
    from sigmarl.ablation import MODELS
    from sigmarl.compose import compose_config
    from sigmarl.evaluation import import_command, target

    if import_command.takes(args):
        model = import_command.model_of(args.target, args.model)
        rules, overrides = import_command.rules_of(args.overrides)
        path = import_command.policy_file(args.target)
        cfg = compose_config([f"obs={MODELS[model]}", f"rules={rules}", *overrides])
        label = args.label or model + import_command.LABEL_SUFFIX
    else:
        target.check_evaluate_overrides(args.overrides)
        cfg = compose_config(args.overrides)
        path = target.resolve_checkpoint(args.target, cfg)
    use_threads(cfg.threads)
    from sigmarl.evaluation.animation import animate, check_sims
    from sigmarl.evaluation.imported import animate_imported

    check_sims(sims, cfg.eval.n_sims)
    if import_command.takes(args):
        return cfg, lambda name: animate_imported(path, cfg, model, label, name, sims, args.frames, out_dir)
    return cfg, lambda name: animate(path, name, sims, args.frames, cfg.eval.n_sims, cfg.eval.seed, out_dir,
                                     device=cfg.device)
