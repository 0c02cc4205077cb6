"""`sigmarl evaluate paper:M5 --out DIR rules=paper`: a policy of the paper's own code evaluated
(`evaluation.imported`), its rows written where `--out` names, never into a run folder.

Light at import (no torch): a wrong model, rules or place is answered before the evaluation
starts. Imported rows are not logged to MLflow: they are no training run's evaluation.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from sigmarl.ablation import MODELS
from sigmarl.errors import SigmarlError

PAPER_PREFIX = "paper:"  # `paper:M5`: the shipped policy of the paper's M5
LABEL_SUFFIX = "-ITSC24"  # M5-ITSC24: `M5-paper` already names our M5 trained under rules=paper
RULES = ("paper", "ours")  # an imported policy drives under the paper's rules or ours, nothing between


def is_imported(target: str) -> bool:
    """Whether `sigmarl evaluate` is pointed at a SigmaRL policy (`paper:M<k>` or a .pth file)."""
    return target.startswith(PAPER_PREFIX) or target.endswith(".pth")


def takes(args: argparse.Namespace) -> bool:
    """Whether `sigmarl evaluate`'s target is a SigmaRL policy; --model or --label for any other
    target is refused (a checkpoint keeps its own model and label)."""
    if is_imported(args.target):
        return True
    given = [o for o, v in (("--model", args.model), ("--label", args.label)) if v is not None]
    if given:
        raise SigmarlError(f"{' and '.join(given)} {'name' if len(given) > 1 else 'names'} a SigmaRL policy's model "
                           f"or column (paper:M<k> or a .pth file); {args.target} keeps its training config's")
    return False


def policy_file(target: str) -> Path:
    """The policy file `target` names: `paper:M<k>` (shipped with sigmarl) or a path."""
    if target.startswith(PAPER_PREFIX):
        model = target[len(PAPER_PREFIX):]
        if model not in MODELS:
            raise SigmarlError(f"no shipped policy {target!r}; the paper's are "
                               f"{', '.join(PAPER_PREFIX + m for m in MODELS)}")
        from importlib import resources

        return Path(str(resources.files("sigmarl") / "data" / "paper_policies" / f"{model}_policy.pth"))
    path = Path(target)
    if not path.is_file():
        raise SigmarlError(f"policy file not found: {target}")
    return path


def add_options(ev: argparse.ArgumentParser) -> None:
    """`--model` and `--label`, for a policy of the paper's code."""
    ev.add_argument("--model", choices=list(MODELS), help="a SigmaRL policy's model (its observation flags); "
                    "paper:M<k> names its own")
    ev.add_argument("--label", help="a SigmaRL policy's column label (default: <model>-ITSC24)")


def model_of(target: str, model: str | None) -> str:
    """The named model: `paper:M<k>`'s own, or `--model` (which must agree with it)."""
    shipped = target[len(PAPER_PREFIX):] if target.startswith(PAPER_PREFIX) else None
    if shipped is not None and shipped not in MODELS:
        raise SigmarlError(f"no shipped policy {target!r}; the paper's are {', '.join(PAPER_PREFIX + m for m in MODELS)}")
    if model is None and shipped is None:
        raise SigmarlError(f"name the model {target} was trained as: --model {{{','.join(MODELS)}}} "
                           "(a SigmaRL policy file does not record its observation flags)")
    if model is not None and shipped is not None and model != shipped:
        raise SigmarlError(f"{target} is the paper's {shipped}, not {model}; leave --model out")
    return model or shipped


def rules_of(overrides: list[str]) -> tuple[str, list[str]]:
    """The rules named (`rules=paper` or `rules=ours`, default ours) and the other overrides,
    which must be evaluate's own (`target.HONOURED`)."""
    from sigmarl.evaluation.target import HONOURED

    rules, rest = "ours", []
    for o in overrides:
        key, _, value = o.lstrip("+~").partition("=")
        if key.strip() == "rules":
            rules = value.strip()
        else:
            rest.append(o)
    if rules not in RULES:
        raise SigmarlError(f"a SigmaRL policy is evaluated under rules=paper (as it is) or rules=ours (adapted), "
                           f"not rules={rules}")
    dropped = [o for o in rest if o.lstrip("+~").split("=", 1)[0].strip().split(".", 1)[0] not in HONOURED]
    if dropped:
        raise SigmarlError(f"evaluate cannot honour {', '.join(dropped)} for a SigmaRL policy: it takes rules=paper|ours "
                           f"and {', '.join(HONOURED)}")
    return rules, rest


def rows_file_of(out: str | None) -> Path:
    """Where the rows go: `--out` as a .csv file, or evaluation_rows.csv in `--out` as a folder;
    never a training run's folder (whose rows are its own checkpoint's)."""
    from sigmarl.run import Run

    if not out:
        raise SigmarlError("a SigmaRL policy's rows need --out FILE.csv or --out FOLDER (never a run folder)")
    path = Path(out)
    rows_file = path if path.suffix == ".csv" else Run(path).rows_file
    held = Run(rows_file.parent)
    if held.config_file.exists() or held.resume_file.exists():
        raise SigmarlError(f"{held.dir} is a training run's folder; write a SigmaRL policy's rows elsewhere (--out)")
    return rows_file


def run(args: argparse.Namespace) -> None:
    """The command: check everything cheap, evaluate (or reuse rows of the same file and
    protocol), write the rows and their note, print the means."""
    from sigmarl.compose import compose_config
    from sigmarl.scenarios import scenario

    model = model_of(args.target, args.model)
    rules, overrides = rules_of(args.overrides)
    rows_file = rows_file_of(args.out)
    path = policy_file(args.target)
    for name in args.scenario or ():
        scenario(name)
    cfg = compose_config([f"obs={MODELS[model]}", f"rules={rules}", *overrides])
    if args.scenario:
        cfg.eval.scenarios = list(args.scenario)
    from sigmarl.evaluation.imported import evaluate_rows_of
    from sigmarl.metrics import scaled, units_text
    from sigmarl.resources import use_threads

    use_threads(cfg.threads)
    label = args.label or model + LABEL_SUFFIX
    rows = evaluate_rows_of(path, args.target, cfg, model, label, rows_file)
    means = scaled(rows).groupby(rows["scenario"], sort=False).mean()
    print(f"{label} (SigmaRL policy {path}, as {model}, rules={rules}), {cfg.eval.n_sims} simulations x "
          f"{cfg.eval.steps} steps, seed {cfg.eval.seed}: {units_text()}")
    print(means.round(3).to_string())
    print(f"wrote {rows_file}")
