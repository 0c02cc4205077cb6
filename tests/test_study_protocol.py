"""Results are the study's (fault N1): an evaluation under another protocol (another scenario
set, fewer simulations, other steps) is written beside the study's rows, never over them, and a
report reads the study's protocol only, naming the seeds that lack it."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pandas as pd
from mlflow import MlflowClient

from sigmarl.compose import compose_config
from sigmarl.eval_key import RULES_REVISION, eval_key, protocol, protocol_key
from sigmarl.evaluation.protocol import rows_file_for
from sigmarl.results.folders import read_results
from sigmarl.tracking.records import load_evaluation_rows, log_evaluation

FIXTURE = Path(__file__).parent / "data" / "results"
PAPER_KEY = "e91834283d7e"  # results/paper-budget's rows' key, written before the protocol had a name


def test_the_protocol_leaves_out_the_metric_columns_and_keeps_the_committed_key(monkeypatch):
    from sigmarl import eval_key as key_module
    from sigmarl import metrics

    study = compose_config([]).eval
    assert protocol_key(study) == eval_key(study) == PAPER_KEY
    assert protocol(study)["rules"] == RULES_REVISION and protocol(study)["n_sims"] == 32
    monkeypatch.setattr(metrics, "MEASURED", [*metrics.MEASURED, "TTC"])
    assert key_module.protocol_key(study) == PAPER_KEY  # a metric added later: the same protocol
    assert key_module.eval_key(study) == PAPER_KEY  # and the same key: rows without it read "not measured"
    for change in ("eval.n_sims=8", "eval.steps=600", "eval.seed=1", "eval.scenarios=[CPM]"):
        assert protocol_key(compose_config([change]).eval) != PAPER_KEY, change


def _run(tmp_path: Path, note_key: str | None) -> Path:
    run = tmp_path / "M0" / "seed0"
    shutil.copytree(FIXTURE / "M0" / "seed0", run)
    if note_key is None:
        (run / "evaluation_rows.csv").unlink()
    else:
        (run / "evaluation.json").write_text(json.dumps({"eval_key": note_key}))
    return run


def test_a_one_off_evaluation_is_written_beside_the_study_rows(tmp_path):
    run = _run(tmp_path, PAPER_KEY)
    study, one_off = compose_config([]), compose_config(["eval.scenarios=[Roundabout]", "eval.n_sims=2"])
    assert rows_file_for(run / "best.pt", study) == run / "evaluation_rows.csv"
    assert rows_file_for(run / "best.pt", one_off) == run / f"evaluation_rows-{protocol_key(one_off.eval)}.csv"


def test_a_first_evaluation_under_another_protocol_than_the_runs_own_keeps_out_of_its_rows(tmp_path):
    """No rows yet: the run's config.yaml says which protocol its study evaluates under."""
    from sigmarl.readers import read_run_config

    run = _run(tmp_path, None)
    study = compose_config([])
    study.eval = read_run_config(run / "config.yaml").eval  # the fixture's study: 3 simulations of 40 steps
    one_off = compose_config([])
    assert protocol_key(one_off.eval) != protocol_key(study.eval)
    assert rows_file_for(run / "best.pt", one_off).name == f"evaluation_rows-{protocol_key(one_off.eval)}.csv"
    assert rows_file_for(run / "best.pt", study) == run / "evaluation_rows.csv"


def test_the_mlflow_report_reads_the_study_protocol_only(tmp_path):
    client = MlflowClient(f"sqlite:///{tmp_path / 'mlflow.db'}")
    exp = client.create_experiment("study")
    rows = pd.read_csv(FIXTURE / "M0" / "seed0" / "evaluation_rows.csv")
    one_off = rows[rows["scenario"] == rows["scenario"].iloc[0]].assign(CR_AA=0.0, CR_AL=0.5, CR_total=0.5)
    log_evaluation(client, exp, rows, {"model": "M0", "seed": "0", "protocol_key": "study"}, {})
    log_evaluation(client, exp, one_off, {"model": "M0", "seed": "0", "protocol_key": "oneoff"}, {})  # newer
    log_evaluation(client, exp, one_off.assign(seed=1), {"model": "M0", "seed": "1", "protocol_key": "oneoff"}, {})
    notes: list[str] = []
    read = load_evaluation_rows(client, "study", "study", notes)
    assert set(read["seed"]) == {0} and len(read) == len(rows)
    assert read["CR_total"].mean() == rows["CR_total"].mean()
    assert notes == ["M0 seed 1 evaluated under another protocol (oneoff) only, not the study's (study): left out; "
                     "`sigmarl sweep` evaluates it under the study's"]
    # a report composed without the sweep's eval overrides: the protocol most runs hold, the
    # earliest among equals (the study's evaluations come before one-offs)
    tie = client.create_experiment("tie")
    log_evaluation(client, tie, rows, {"model": "M0", "seed": "0", "protocol_key": "study"}, {})
    log_evaluation(client, tie, one_off, {"model": "M0", "seed": "0", "protocol_key": "oneoff"}, {})
    assert load_evaluation_rows(client, "tie", "the-reports-own")["CR_total"].mean() == rows["CR_total"].mean()


def test_a_folder_report_leaves_out_rows_of_another_protocol_than_its_study(tmp_path):
    root = tmp_path / "results"
    shutil.copytree(FIXTURE, root)
    for note in root.glob("*/seed*/evaluation.json"):
        note.unlink()
    runs = sorted(p.parent for p in root.glob("*/seed*/evaluation_rows.csv"))
    for run in runs:
        (run / "evaluation.json").write_text(json.dumps({"eval_key": "study", "rules": RULES_REVISION}))
    (runs[0] / "evaluation.json").write_text(json.dumps({"protocol_key": "oneoff", "eval_key": "x", "rules": RULES_REVISION}))
    results = read_results(root)
    assert len(runs) > 2 and f"{runs[0]}: evaluated under another protocol (oneoff)" in " ".join(results.notes)
    left = results.rows[["model", "seed"]].drop_duplicates()
    assert len(left) == len(runs) - 1
