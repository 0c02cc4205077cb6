"""Never write into what is not ours (fault H1): `run_dir=` naming a folder that holds
anything but a run's files is refused in one line, before a single file in it changes; a run
folder sigmarl wrote, and an empty one, are sigmarl's to write."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from cli_errors import one_line_exit_2

from sigmarl.errors import SigmarlError
from sigmarl.run_owner import check_ours

TRAIN = ["train", "ppo=smoke", "tracking.enabled=false", "threads=1"]
COMMITTED = Path(__file__).resolve().parents[1] / "results" / "paper-budget" / "M0" / "seed0"


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_a_users_config_yaml_is_refused_and_left_byte_for_byte(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    mine = tmp_path / "mywork"
    mine.mkdir()
    (mine / "config.yaml").write_text("my: notes\n")
    (mine / "metrics.csv").write_text("day,hours\nmonday,3\n")
    before = _snapshot(mine)
    line = one_line_exit_2([*TRAIN, "run_dir=mywork"], capsys)
    assert "run_dir mywork is not a sigmarl run folder (its config.yaml is not a run's training config)" in line
    assert _snapshot(mine) == before and sorted(os.listdir(mine)) == ["config.yaml", "metrics.csv"]
    assert not (tmp_path / "runs").exists()


def test_the_root_folder_and_a_file_are_refused(tmp_path, capsys):
    assert "run_dir / is not a sigmarl run folder (it holds" in one_line_exit_2([*TRAIN, "run_dir=/"], capsys)
    (tmp_path / "notes.txt").write_text("mine")
    line = one_line_exit_2([*TRAIN, f"run_dir={tmp_path / 'notes.txt'}"], capsys)
    assert "is a file, not a folder" in line and (tmp_path / "notes.txt").read_text() == "mine"


@pytest.mark.parametrize("name, holds, says", [
    ("notes.txt", b"mine", "it holds notes.txt, which sigmarl does not write"),
    ("metrics.csv", b"day,hours\n", "its metrics.csv is not a training's metrics"),
    ("mlflow_run_id", b"line one\nline two\n", "its mlflow_run_id is not a run id"),
    ("evaluation_rows-mine.csv", b"scenario\n", "evaluation_rows-mine.csv, which sigmarl does not write"),
])
def test_what_sigmarl_never_writes_is_told_by_name_and_content(tmp_path, name, holds, says):
    (tmp_path / name).write_bytes(holds)
    with pytest.raises(SigmarlError, match=says.replace("(", r"\(")):
        check_ours(tmp_path)
    (tmp_path / name).unlink()
    (tmp_path / "inner").mkdir()
    with pytest.raises(SigmarlError, match="it holds inner, which is no file sigmarl writes"):
        check_ours(tmp_path)


def test_a_run_folder_sigmarl_wrote_is_its_own(tmp_path):
    check_ours(tmp_path / "absent")
    check_ours(tmp_path)  # empty
    check_ours(COMMITTED)  # every file a finished, evaluated run holds
    (tmp_path / "config.yaml").write_bytes(bytes(range(256)))  # damaged, beside its checkpoint: a resume's to mend
    (tmp_path / "checkpoint.pt").write_bytes(b"PK")
    (tmp_path / ".checkpoint.pt.k2j4x9ab.tmp").write_bytes(b"")  # what a kill mid-write leaves
    (tmp_path / "evaluation_rows-0123456789ab.csv").write_text("scenario\n")  # a one-off evaluation
    (tmp_path / "provenance.json").write_text("{}")  # what each start ran on (sigmarl.run names it)
    check_ours(tmp_path)
