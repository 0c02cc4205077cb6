"""`sigmarl report --from FOLDER --plan`: per comparison the current verdict and the seeds a
decision needs, from the folder's evaluation rows only (no MLflow, no figures)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from sigmarl.errors import SigmarlError
from sigmarl.report.aggregate import model_order, validate_rows
from sigmarl.report.folder import read_many, read_results
from sigmarl.report.verdicts import Design, design_of, plan_text, verdict_table


def plan_from_folder(root: Path | list[Path], models: list[str] | None = None, baseline: str | None = None,
                     study=None) -> str:
    """The seed plan of the results folder(s) `root` (models: default all, in the study's order;
    baseline: default the study's, else M0, or the first model; study: its metrics and margins)."""
    roots = [Path(r) for r in (root if isinstance(root, list) else [root])]
    rows = validate_rows((read_results(roots[0]) if len(roots) == 1 else read_many(roots)).rows)
    models = model_order(rows, models, list(study.variants) if study is not None and study.variants else None)
    if study is not None and baseline is None and study.baseline in models:
        baseline = study.baseline
    baseline = baseline or ("M0" if "M0" in models else models[0])
    if baseline not in models or len(models) < 2:
        raise SigmarlError(f"a plan compares other models with the baseline {baseline}; the models chosen "
                           f"from {root} are {', '.join(models)}")
    design = replace(design_of(study, models), baseline=baseline) if study is not None \
        else Design(variants=models, baseline=baseline)
    return plan_text(verdict_table(rows, design), design)
