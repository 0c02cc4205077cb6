"""Results and run folders found wrong by the third reliability round: a report refuses rows
that were duplicated or dropped, and a run counts as finished only with its rows."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pandas as pd
import pytest
from cli_errors import one_line_exit_2

from sigmarl.cli import main
from sigmarl.run import Run
from sigmarl.sweep import Job, finished

PAPER = Path(__file__).resolve().parents[1] / "results" / "paper-budget"




def _copy_results(tmp_path: Path, seeds=range(3)) -> Path:
    """The paper-budget rows and metrics of M0 and M4 (no checkpoints)."""
    root = tmp_path / "results"
    for model in ("M0", "M4"):
        for seed in seeds:
            src, dst = PAPER / model / f"seed{seed}", root / model / f"seed{seed}"
            dst.mkdir(parents=True)
            for name in ("evaluation_rows.csv", "evaluation.json", "config.yaml"):
                shutil.copy(src / name, dst / name)
    return root


def _edit_rows(root: Path, edit) -> Path:
    path = root / "M0" / "seed1" / "evaluation_rows.csv"
    rows = pd.read_csv(path)
    edit(rows).to_csv(path, index=False)
    return path


def _renumber(rows: pd.DataFrame) -> pd.DataFrame:
    rows.loc[1, "simulation"] = 0  # CPM's simulation 1 numbered 0
    return rows


@pytest.mark.parametrize("edit, says", [
    (lambda r: pd.concat([r, r.iloc[[5]]]), "twice"),  # a row duplicated
    (lambda r: r.drop(index=[0, 1]), "lacks simulation"),  # CPM's first two simulations dropped
    (_renumber, "twice"),  # a simulation number given twice
    (lambda r: r[~((r.scenario == "CPM") & (r.simulation == 31))], "different numbers"),  # CPM's last one
])
def test_f8_a_seed_plan_refuses_duplicated_or_dropped_simulation_rows(edit, says, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    root = _copy_results(tmp_path)
    path = _edit_rows(root, edit)
    line = one_line_exit_2(["report", "--from", str(root), "--plan"], capsys)
    assert str(path) in line and says in line


def test_f8_a_report_refuses_a_duplicated_row(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    root = _copy_results(tmp_path)
    path = _edit_rows(root, lambda r: pd.concat([r, r.iloc[[5]]]))
    line = one_line_exit_2(["report", "--from", str(root), "--no-figures", "tracking.enabled=false",
                            f"--out={tmp_path}/rep"], capsys)
    assert str(path) in line and "twice" in line
    assert not (tmp_path / "rep").exists()


def test_f8_uniformly_dropped_simulations_differ_from_the_protocols_count(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    root = _copy_results(tmp_path)
    path = _edit_rows(root, lambda r: r[r.simulation < 30])
    line = one_line_exit_2(["report", "--from", str(root), "--plan"], capsys)
    assert str(path.parent) in line and "30 simulations per scenario" in line


def test_f8_the_untouched_rows_report(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["report", "--from", str(_copy_results(tmp_path)), "--plan"]) == 0


def test_f10_a_run_without_its_rows_is_not_finished(tmp_path):
    run = Run(tmp_path / "M4" / "seed0")
    run.dir.mkdir(parents=True)
    for name in ("config.yaml", "evaluation.json", "evaluation_rows.csv", "evaluated.txt"):
        shutil.copy(PAPER / "M4" / "seed0" / name, run.path(name))
    key = json.loads(run.rows_meta_file.read_text())["eval_key"]
    job = Job("M4/seed0", "M4", 0, [], [], str(run.dir), "f", key)
    assert finished(job)
    run.rows_file.unlink()
    assert not finished(job)  # the sweep runs it again, and the job restores the rows
    assert not finished(Job("M4/seed0", "M4", 0, [], [], str(run.dir), "f", "another-protocol"))


def test_f18_evaluate_is_refused_on_a_run_folder_that_is_being_trained(tmp_path, capsys, monkeypatch):
    import subprocess
    import sys

    monkeypatch.chdir(tmp_path)
    run = Run(tmp_path / "runs" / "M0" / "seed0")
    run.dir.mkdir(parents=True)
    for name in ("config.yaml", "best.pt"):
        shutil.copy(PAPER / "M0" / "seed0" / name, run.path(name))
    holder = subprocess.Popen(  # what `sigmarl train` holds while it writes the folder
        [sys.executable, "-c", "import fcntl, os, sys, time; fd = os.open(sys.argv[1], os.O_RDWR | os.O_CREAT); "
         "fcntl.flock(fd, fcntl.LOCK_EX); os.write(fd, b'4242 trainer'); print('held', flush=True); time.sleep(60)",
         str(run.lock_file)], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        line = one_line_exit_2(["evaluate", str(run.dir), "--scenario", "On-Ramp", "eval.n_sims=1", "eval.steps=2",
                                "tracking.enabled=false"], capsys)
    finally:
        holder.kill()
        holder.wait()
    assert "in use by another sigmarl process (pid 4242 on trainer)" in line
    assert not run.rows_file.exists()


def _finished_run(tmp_path: Path) -> tuple[Run, Job]:
    run = Run(tmp_path / "M4" / "seed0")
    run.dir.mkdir(parents=True)
    for name in ("config.yaml", "evaluation.json", "evaluation_rows.csv", "evaluated.txt"):
        shutil.copy(PAPER / "M4" / "seed0" / name, run.path(name))
    key = json.loads(run.rows_meta_file.read_text())["eval_key"]
    return run, Job("M4/seed0", "M4", 0, [], [], str(run.dir), "f", key)


@pytest.mark.parametrize("damage", [
    lambda b: b[:-30],  # the last line cut
    lambda b: b[:200] + b"\xff\xfe" + b[202:],  # two bytes flipped into non-UTF-8
    lambda b: b + b.splitlines(keepends=True)[-1],  # the last row duplicated
])
def test_f10_a_run_with_damaged_rows_is_not_finished(tmp_path, damage):
    run, job = _finished_run(tmp_path)  # rows saved before their note held a hash
    run.rows_file.write_bytes(damage(run.rows_file.read_bytes()))
    assert not finished(job)


def test_f10_rows_whose_hash_differs_from_their_note_are_not_finished(tmp_path):
    import hashlib

    run, job = _finished_run(tmp_path)
    meta = json.loads(run.rows_meta_file.read_text())
    meta["rows_sha256"] = hashlib.sha256(run.rows_file.read_bytes()).hexdigest()
    run.rows_meta_file.write_text(json.dumps(meta))
    assert finished(job)
    # a value edited into another plausible one passes every check but the hash
    text = run.rows_file.read_text()
    run.rows_file.write_text(text[:-8] + ("1" if text[-8] != "1" else "2") + text[-7:])
    assert not finished(job)
