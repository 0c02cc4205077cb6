"""`report --from` holds each rows file to the SHA-256 its note records (fault H3): rows
edited to other valid values are refused in one line naming the file, or left out under
--partial; a note from before the field is taken after the rows' checks, said once."""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import pandas as pd
import pytest
from cli_errors import one_line_exit_2

from sigmarl.errors import SigmarlError
from sigmarl.eval_key import RULES_REVISION
from sigmarl.results.folders import read_results

FIXTURE = Path(__file__).parent / "data" / "results"


def _hashed(tmp_path: Path) -> tuple[Path, list[Path]]:
    root = tmp_path / "results"
    shutil.copytree(FIXTURE, root)
    rows = sorted(root.glob("*/seed*/evaluation_rows.csv"))
    for path in rows:
        digest = hashlib.sha256(path.read_bytes()).hexdigest()
        (path.parent / "evaluation.json").write_text(json.dumps({"eval_key": "k", "rules": RULES_REVISION,
                                                                 "rows_sha256": digest}))
    return root, rows


def _edit(path: Path) -> None:
    """Another valid value: one simulation's CD doubled (check_rows cannot tell)."""
    rows = pd.read_csv(path)
    rows.loc[0, "CD"] = rows.loc[0, "CD"] * 2 + 1
    rows.to_csv(path, index=False)


def test_rows_edited_to_other_valid_values_are_refused_naming_the_file(tmp_path, capsys):
    root, rows = _hashed(tmp_path)
    assert len(read_results(root).rows) > 0 and not read_results(root).notes
    _edit(rows[1])
    with pytest.raises(SigmarlError, match=f"{rows[1]} differs from the SHA-256 its evaluation.json records"):
        read_results(root)
    line = one_line_exit_2(["report", "--from", str(root), "--no-figures", "tracking.enabled=false",
                            "--out", str(tmp_path / "out")], capsys)
    assert f"{rows[1]} differs from the SHA-256" in line and "--partial" in line


def test_under_partial_the_edited_file_is_left_out_with_a_note(tmp_path):
    root, rows = _hashed(tmp_path)
    _edit(rows[1])
    results = read_results(root, partial=True)
    assert results.notes == [f"{rows[1].parent}: evaluation_rows.csv differs from the SHA-256 its evaluation.json "
                             "records (edited or damaged): left out"]
    assert len(results.rows[["model", "seed"]].drop_duplicates()) == len(rows) - 1


def test_notes_older_than_the_checksum_are_taken_after_the_checks_said_once(tmp_path):
    root, rows = _hashed(tmp_path)
    for path in rows[:2]:
        (path.parent / "evaluation.json").write_text(json.dumps({"eval_key": "k", "rules": RULES_REVISION}))
    _edit(rows[0])  # valid values, no checksum to compare with: taken
    results = read_results(root)
    assert len(results.rows[["model", "seed"]].drop_duplicates()) == len(rows)
    assert results.notes == [f"2 rows file(s) under {root} have no SHA-256 in their note (written before it was "
                             "recorded): taken after checking their contents"]

