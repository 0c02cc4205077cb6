"""`sigmarl report`: the study's evaluation runs from MLflow -> tables, figures, a report run."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
from omegaconf import DictConfig

from sigmarl.evaluation import records
from sigmarl.report.build import Report, build_report


def make_report(
    cfg: DictConfig,
    out_dir: Path | None = None,
    latex: bool = False,
    trim: bool = False,
    compare_paper: bool = False,
    models: list[str] | None = None,
    ci: bool = False,
    figures: bool = True,
) -> Report:
    """Build the report of experiment `cfg.tracking.experiment` and log it as a report run."""
    experiment = cfg.tracking.experiment
    client = records.client_for(cfg)
    rows = records.load_evaluation_rows(client, experiment)
    curves = records.load_training_curves(client, experiment) if figures else None
    out_dir = out_dir or Path("reports") / experiment
    report = build_report(rows, models, out_dir=out_dir, trim=trim, compare_paper=compare_paper,
                          latex=latex, curves=curves if curves is not None and len(curves) else None,
                          ci=ci, figures=figures)
    _log_report(client, experiment, report, rows)
    return report


def _log_report(client, experiment: str, report: Report, rows: pd.DataFrame) -> None:
    """A report run: the table files, figures and composite scores, with the runs it used."""
    exp_id = records.experiment_id(client, experiment, create=True)
    run = client.create_run(exp_id, run_name="report", tags={
        "kind": "report",
        "evaluation_runs": ",".join(sorted(set(rows["eval_run_id"]))) if "eval_run_id" in rows else "",
    })
    rid = run.info.run_id
    try:
        for _, r in report.composite.dropna(subset=["CS"]).iterrows():
            client.log_metric(rid, f"CS/{r['scenario']}/{r['model']}", float(r["CS"]))
        for path in report.paths.values():
            client.log_artifact(rid, str(path))
        client.set_terminated(rid, "FINISHED")
    except BaseException:
        client.set_terminated(rid, "FAILED")
        raise
