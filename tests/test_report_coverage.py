"""A report names every run of the study it leaves out, and why (failed, not evaluated, never
run), and refuses in one line where a run failed or a declared variant has runs but no rows,
unless --partial. Folders built by hand from tests/data/results (M0 and M4, seeds 0 and 1)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pandas as pd
import pytest
from cli_errors import one_line_exit_2
from mlflow import MlflowClient

from sigmarl.cli import main
from sigmarl.tracking.records import log_evaluation

FIXTURE = Path(__file__).parent / "data" / "results"
# the study: the fixture's two models and K4, a third that each test gives a fate by hand
STUDY_YAML = """# @package _global_
study:
  name: cover
  variants:
    M0: [obs=full]
    M4: [obs=no_distance_to_boundaries]
    K4: [obs=full, obs.n_nearest=3]
  baseline: M0
"""
STUDY = "study=cover"
ERROR = "the policy cannot act on CPM's observations (size 54) (60x54 and 43x256)"


@pytest.fixture(autouse=True)
def _cover_study(tmp_path, monkeypatch):
    (tmp_path / "conf" / "study").mkdir(parents=True)
    (tmp_path / "conf" / "study" / "cover.yaml").write_text(STUDY_YAML)
    monkeypatch.setenv("SIGMARL_CONFIG_PATH", str(tmp_path / "conf"))  # what --config-dir sets


def _folder(tmp_path: Path, k4: dict[str, str]) -> Path:
    """The fixture plus K4/seed0 holding the files `k4` names (file -> text)."""
    root = tmp_path / "results"
    shutil.copytree(FIXTURE, root)
    run = root / "K4" / "seed0"
    run.mkdir(parents=True)
    shutil.copy(FIXTURE / "M0" / "seed0" / "config.yaml", run / "config.yaml")
    for name, text in k4.items():
        (run / name).write_text(text)
    return root


def _report(root: Path, tmp_path: Path, *args: str) -> list[str]:
    return ["report", "--from", str(root), "--out", str(tmp_path / "out"), "--no-figures", STUDY,
            "tracking.enabled=false", *args]


def test_a_failed_variant_is_named_and_refused_unless_partial(tmp_path, capsys):
    root = _folder(tmp_path, {"failed.txt": f"Traceback (most recent call last):\n  ...\nSigmarlError: {ERROR}\n"})
    line = one_line_exit_2(_report(root, tmp_path), capsys)
    assert "K4 of study 'cover' has no evaluation rows and 1 run(s) failed" in line
    assert f"K4 seed 0 failed: SigmarlError: {ERROR}" in line and "--partial" in line
    assert not (tmp_path / "out" / "table.md").exists()
    assert main(_report(root, tmp_path, "--partial")) == 0
    table = (tmp_path / "out" / "table.md").read_text()
    assert f"{root / 'K4' / 'seed0'}: failed: SigmarlError: {ERROR}: left out" in table
    assert next(ln for ln in table.splitlines() if ln.startswith("| Scenario")) == "| Scenario | Metric | M0 | M4 |"


def test_not_evaluated_is_told_from_failed(tmp_path, capsys):
    root = _folder(tmp_path, {"final.pt": "", "metrics.csv": "iteration\n1\n"})
    line = one_line_exit_2(_report(root, tmp_path), capsys)
    assert line.endswith("K4 of study 'cover' has no evaluation rows: K4 seed 0 trained, not evaluated yet. "
                         "Fix it and run the sweep again, or give --partial to report the rest")
    assert "failed" not in line


def test_a_failed_seed_of_a_reported_variant_is_refused(tmp_path, capsys):
    root = _folder(tmp_path, {})
    shutil.rmtree(root / "K4")
    (root / "M4" / "seed1" / "evaluation_rows.csv").unlink()
    (root / "M4" / "seed1" / "failed.txt").write_text("out of memory\n")
    line = one_line_exit_2(_report(root, tmp_path, "--models", "M0,M4"), capsys)
    assert "1 run(s) failed: M4 seed 1 failed: out of memory." in line


def test_a_variant_never_run_is_a_note(tmp_path, capsys):
    root = _folder(tmp_path, {})
    shutil.rmtree(root / "K4")
    assert main(_report(root, tmp_path)) == 0
    table = (tmp_path / "out" / "table.md").read_text()
    assert f"Left out: K4 not run (no rows, no run folder in {root})." in table


def test_nothing_evaluated_names_each_run(tmp_path, capsys):
    root = tmp_path / "results"
    run = root / "K4" / "seed0"
    run.mkdir(parents=True)
    (run / "failed.txt").write_text(ERROR)
    line = one_line_exit_2(["report", "--from", str(root), "--no-figures", "tracking.enabled=false"], capsys)
    assert f"nothing evaluated to report on; {run}: failed: {ERROR}: left out" in line


def test_the_mlflow_report_reads_the_failures_from_the_run_folders(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    uri = f"sqlite:///{tmp_path}/mlflow.db"
    client = MlflowClient(tracking_uri=uri)
    exp = client.create_experiment("cover")
    for model, seed in (("M0", 0), ("M4", 0)):
        rows = pd.read_csv(FIXTURE / model / f"seed{seed}" / "evaluation_rows.csv")
        log_evaluation(client, exp, rows, {"model": model, "seed": str(seed)}, {})
    runs = tmp_path / "runs"
    (runs / "K4" / "seed0").mkdir(parents=True)
    (runs / "K4" / "seed0" / "failed.txt").write_text(ERROR)
    (runs / "M4" / "seed1").mkdir(parents=True)
    (runs / "M4" / "seed1" / "checkpoint.pt").write_text("")
    args = ["report", STUDY, f"tracking.tracking_uri={uri}", "tracking.experiment=cover", f"runs_root={runs}",
            "--no-figures", "--out", str(tmp_path / "out")]
    capsys.readouterr()  # MLflow's own lines on creating the store
    line = one_line_exit_2(args, capsys)
    assert line.endswith("K4 of study 'cover' has no evaluation rows and 1 run(s) failed: M4 seed 1 not evaluated "
                         f"yet, training unfinished (no final.pt); K4 seed 0 failed: {ERROR}. Fix it and run the "
                         "sweep again, or give --partial to report the rest")
    assert main([*args, "--partial"]) == 0
    table = (tmp_path / "out" / "table.md").read_text()
    assert f"Left out: K4 seed 0 failed: {ERROR}." in table
    assert "Left out: M4 seed 1 not evaluated yet, training unfinished (no final.pt)." in table
