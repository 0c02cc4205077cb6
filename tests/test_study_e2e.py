"""The whole study through the CLI: sweep (six models, parallel jobs) then report --latex."""

from __future__ import annotations

import pandas as pd
import pytest
from mlflow import MlflowClient

from sigmarl.ablation import MODELS
from sigmarl.cli import main
from sigmarl.metrics import METRIC_COLUMNS
from sigmarl.scenarios import PAPER_SCENARIOS

pytestmark = pytest.mark.slow

# Smaller still than study=quick: the test checks the plumbing, not learning.
TINY = ["study=quick", "ppo.iterations=1", "ppo.frames_per_iteration=128", "ppo.epochs=1",
        "ppo.minibatch_size=64", "eval.n_sims=2", "eval.steps=30"]


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    root = tmp_path_factory.mktemp("study")
    uri = f"sqlite:///{root}/mlflow.db"
    import os

    old = os.getcwd()
    os.chdir(root)
    try:
        rc_sweep = main(["sweep", *TINY, f"tracking.tracking_uri={uri}"])
        rc_report = main(["report", "--latex", "study=quick", f"tracking.tracking_uri={uri}"])
        # A second sweep finds everything done and only re-reads it.
        rc_again = main(["sweep", *TINY, f"tracking.tracking_uri={uri}"])
    finally:
        os.chdir(old)
    return root, uri, rc_sweep, rc_report, rc_again


def test_sweep_and_report_succeed(study):
    _, _, rc_sweep, rc_report, rc_again = study
    assert (rc_sweep, rc_report, rc_again) == (0, 0, 0)


def test_table_shape_and_latex(study):
    root = study[0]
    out = root / "reports" / "sigmarl-quick"
    table = pd.read_csv(out / "table.csv")
    ours = table[table["source"] == "ours"]
    assert sorted(ours["scenario"].unique()) == sorted(PAPER_SCENARIOS)  # the default: Table I
    assert len(ours) == 4 * 6  # 6 rows per scenario: CR_AA, CR_AL, CR_total, CD, AS, CS
    assert [c for c in ours.columns if c in MODELS] == list(MODELS)
    tex = (out / "table.tex").read_text()
    assert "\\toprule" in tex and "\\bottomrule" in tex


def test_table_agrees_with_mlflow_rows(study):
    root, uri = study[0], study[1]
    client = MlflowClient(tracking_uri=uri)
    exp = client.get_experiment_by_name("sigmarl-quick")
    runs = client.search_runs([exp.experiment_id], filter_string="tags.kind = 'evaluation'")
    assert len({r.data.tags["model"] for r in runs}) == 6
    frames = [pd.read_csv(client.download_artifacts(r.info.run_id, "evaluation_rows.csv", str(root)))
              for r in runs]
    rows = pd.concat(frames)
    assert len(rows) == 6 * 4 * 2  # models x scenarios x simulations
    table = pd.read_csv(root / "reports" / "sigmarl-quick" / "table.csv")
    ours = table[table["source"] == "ours"].set_index(["scenario", "metric"])
    means = rows.groupby(["scenario", "model"])[METRIC_COLUMNS].mean()
    for (scenario, model), m in means.iterrows():
        for metric in METRIC_COLUMNS:
            scale = 100 if metric.startswith("CR") else 1  # the table shows percent
            assert ours.loc[(scenario, metric), model] == pytest.approx(scale * m[metric], abs=1e-9)


def test_report_from_the_sweep_folder_equals_the_mlflow_report(study, monkeypatch):
    # the sweep's run folders alone (no MLflow reads) rebuild the same table
    root = study[0]
    monkeypatch.chdir(root)
    rc = main(["report", "--from", "runs/sigmarl-quick", "--out", "reports/from-folder", "--no-figures",
               "tracking.enabled=false"])
    assert rc == 0
    for name in ("table.csv", "table.md", "summary.csv", "improvement.csv"):
        assert (root / "reports" / "from-folder" / name).read_bytes() == (
            root / "reports" / "sigmarl-quick" / name).read_bytes(), name


def test_training_summary_is_the_same_from_mlflow_and_from_the_folder(study, monkeypatch):
    root = study[0]
    monkeypatch.chdir(root)
    assert main(["report", "--from", "runs/sigmarl-quick", "--out", "reports/from-folder-training",
                 "--no-figures", "tracking.enabled=false"]) == 0
    mlflow_side = pd.read_csv(root / "reports" / "sigmarl-quick" / "training.csv")
    folder_side = pd.read_csv(root / "reports" / "from-folder-training" / "training.csv")
    assert list(mlflow_side["model"]) == list(MODELS) and (mlflow_side["iterations"] == 1).all()
    assert (mlflow_side["compute_min"] > 0).all()  # each run's timings reached MLflow
    pd.testing.assert_frame_equal(mlflow_side, folder_side, rtol=1e-6)
