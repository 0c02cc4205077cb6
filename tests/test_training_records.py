"""Training records a report or a resume must not trust blindly.

G4: `metrics.csv` is read through one checked reader (`sigmarl.readers.read_metrics`) by the
resume, the report and its curves figures: a cell that is not a number, an iteration such as
1e308 or a NaN is one line naming the file and line (exit code 2), never a traceback or a
reported number. G6: the resume point carries the checksum of its content; a flipped byte is
refused in one line and the run folder is left as it was."""

from __future__ import annotations

import shutil
from pathlib import Path

import pandas as pd
import pytest
import torch
from cli_errors import one_line_exit_2

from sigmarl.cli import main
from sigmarl.errors import SigmarlError
from sigmarl.readers import MAX_ITERATION
from sigmarl.report.training import training_summary
from sigmarl.training import checkpoint as ckpt

FIXTURE = Path(__file__).parent / "data" / "results"  # the smallest results folder: 3 iterations a run
PAPER_RUN = Path(__file__).resolve().parents[1] / "results" / "paper-budget" / "M0" / "seed0"
TRAIN = ["train", "ppo=smoke", "tracking.enabled=false"]  # 3 iterations, a resume point after each


def _damage_cell(path: Path, line: int, column: str, value: str) -> None:
    """Replace one cell of a CSV file's line (1: the header) by `value`, as text."""
    lines = path.read_text().splitlines(keepends=True)
    fields = lines[line - 1].rstrip("\n").split(",")
    fields[lines[0].rstrip("\n").split(",").index(column)] = value
    lines[line - 1] = ",".join(fields) + "\n"
    path.write_text("".join(lines))


# ---- G4: metrics.csv in a report ------------------------------------------------------------

@pytest.mark.parametrize("column, value, said", [
    ("episode_reward_mean", "abc", "episode_reward_mean 'abc' is not a number"),  # a non-number cell
    ("iteration", "1e308", f"iteration '1e308' is not a whole number in 1..{MAX_ITERATION}"),
    ("episode_reward_mean", "nan", "episode_reward_mean is nan, not a finite number"),
])
def test_g4_a_damaged_metrics_csv_is_one_line_in_a_folder_report(column, value, said, tmp_path, capsys):
    source = tmp_path / "results"
    shutil.copytree(FIXTURE, source)
    path = source / "M4" / "seed1" / "metrics.csv"
    _damage_cell(path, 3, column, value)
    line = one_line_exit_2(["report", "--from", str(source), "--out", str(tmp_path / "out"), "--no-figures",
                            "tracking.enabled=false"], capsys)
    assert f"{path}: line 3: {said}" in line
    assert not (tmp_path / "out" / "training.csv").exists()


def test_g4_a_lost_iteration_is_refused_and_a_repeated_one_counts_once(tmp_path, capsys):
    source = tmp_path / "results"
    shutil.copytree(FIXTURE, source)
    path = source / "M0" / "seed0" / "metrics.csv"
    lines = path.read_text().splitlines(keepends=True)
    path.write_text("".join([lines[0], lines[1], lines[3]]))  # iteration 2 lost
    line = one_line_exit_2(["report", "--from", str(source), "--out", str(tmp_path / "out"), "--no-figures",
                            "tracking.enabled=false"], capsys)
    assert f"{path} lacks iteration(s) 2 of 1..3" in line
    path.write_text("".join([*lines, lines[3]]))  # a resume before resumes cut the file: logged twice
    assert main(["report", "--from", str(source), "--out", str(tmp_path / "out"), "--no-figures",
                 "tracking.enabled=false"]) == 0
    training = pd.read_csv(tmp_path / "out" / "training.csv").set_index(["model", "seed"])
    assert training.loc[("M0", 0), "iterations"] == 3


@pytest.mark.parametrize("iteration, reward", [(1e308, 1.0), (2.5, 1.0), (0, 1.0), (3, float("nan"))])
def test_g4_a_tracking_stores_damaged_curve_is_refused_by_the_summary(iteration, reward):
    """The summary checks the curves it is given, whether a folder or a tracking store gave them."""
    curves = pd.DataFrame({"model": "M0", "seed": 0, "iteration": [1.0, 2.0, iteration],
                           "reward": [1.0, 2.0, reward]})
    with pytest.raises(SigmarlError, match=f"training curve of M0 seed 0 is damaged.*1..{MAX_ITERATION}"):
        training_summary(curves, ["M0"])


# ---- a tiny training, stopped resumable after 2 of its 3 iterations ------------------------

@pytest.fixture(scope="module")
def stopped_run(tmp_path_factory) -> Path:
    run = tmp_path_factory.mktemp("stopped") / "run"
    main([*TRAIN, "ppo.stop_after=2", f"run_dir={run}"])
    assert ckpt.load(run / ckpt.RESUME_FILE, resume=True)["iteration"] == 2
    return run


def _copy(stopped_run: Path, tmp_path: Path) -> Path:
    run = tmp_path / "run"
    shutil.copytree(stopped_run, run)
    return run


def _files(run: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(run.iterdir())}


def test_g4_a_nan_in_metrics_csv_is_not_resumed_past(stopped_run, tmp_path, capsys):
    run = _copy(stopped_run, tmp_path)
    _damage_cell(run / "metrics.csv", 2, "episode_reward_mean", "nan")
    before = _files(run)
    line = one_line_exit_2([*TRAIN, "resume=true", f"run_dir={run}"], capsys)
    assert f"{run / 'metrics.csv'}: line 2: episode_reward_mean is nan, not a finite number" in line
    assert _files(run) == before


# ---- G6: the resume point's checksum ----------------------------------------------------------

def test_g6_a_flipped_byte_in_the_resume_point_is_refused_and_an_intact_one_resumes(stopped_run, tmp_path,
                                                                                     capsys):
    run = _copy(stopped_run, tmp_path)
    path = run / ckpt.RESUME_FILE
    data = bytearray(path.read_bytes())
    at = len(data) // 2  # most of the file, its middle included, is weights and optimiser moments
    data[at] ^= 0x01
    path.write_bytes(data)
    before = _files(run)
    line = one_line_exit_2([*TRAIN, "resume=true", f"run_dir={run}"], capsys)
    assert f"checkpoint {path} is damaged" in line and "cannot be resumed" in line
    assert _files(run) == before  # nothing finished is lost: the rows, best.pt, the checkpoint itself
    data[at] ^= 0x01  # restored: it resumes to the end
    path.write_bytes(data)
    assert main([*TRAIN, "resume=true", f"run_dir={run}"]) == 0
    assert pd.read_csv(run / "metrics.csv")["iteration"].tolist() == [1, 2, 3]
    assert ckpt.load(run / ckpt.FINAL_FILE)["iteration"] == 3


def test_g6_every_checkpoint_carries_its_checksum_and_a_missing_one_is_damage(stopped_run, tmp_path):
    for name in (ckpt.RESUME_FILE, ckpt.BEST_FILE):
        state = torch.load(stopped_run / name, weights_only=True)
        assert state["format"] == ckpt.FORMAT and state[ckpt.CHECKSUM] == ckpt.digest(state)
    del state[ckpt.CHECKSUM]  # as a flipped bit in the key's name leaves it
    torch.save(state, tmp_path / "best.pt")
    with pytest.raises(SigmarlError, match="is damaged: what it holds differs from the checksum"):
        ckpt.load(tmp_path / "best.pt")


def test_g6_a_checkpoint_from_before_the_checksum_still_loads_for_a_resume():
    state = torch.load(PAPER_RUN / ckpt.RESUME_FILE, weights_only=True)
    assert state["format"] == ckpt.LEGACY_FORMAT and ckpt.CHECKSUM not in state  # committed before it
    assert ckpt.load(PAPER_RUN / ckpt.RESUME_FILE, resume=True)["iteration"] == 250
    assert ckpt.load(PAPER_RUN / ckpt.BEST_FILE)["iteration"] > 0
