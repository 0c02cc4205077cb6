"""`sigmarl report --from FOLDER --plan`: per comparison the current verdict and the seeds a
decision needs, from the folder's evaluation rows only (no MLflow, no figures)."""

from __future__ import annotations

from pathlib import Path

from sigmarl.errors import SigmarlError
from sigmarl.report.aggregate import model_order, validate_rows
from sigmarl.report.folder import read_results
from sigmarl.report.verdicts import Design, plan_text, verdict_table


def plan_from_folder(root: Path, models: list[str] | None = None, baseline: str | None = None) -> str:
    """The seed plan of the results folder `root` (models: default all, in the table's order;
    baseline: default M0, or the first model)."""
    rows = validate_rows(read_results(Path(root)).rows)
    models = model_order(rows, models)
    baseline = baseline or ("M0" if "M0" in models else models[0])
    if baseline not in models or len(models) < 2:
        raise SigmarlError(f"a plan compares other models with the baseline {baseline}; the models chosen "
                           f"from {root} are {', '.join(models)}")
    design = Design(variants=models, baseline=baseline)
    return plan_text(verdict_table(rows, design), design)
