"""scripts/compare_folders.py: a variant's study folder against a baseline's (the bf16 check)."""

from __future__ import annotations

import importlib.util
import shutil
from pathlib import Path

import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
FIXTURE = ROOT / "tests" / "data" / "results"


def _script():
    spec = importlib.util.spec_from_file_location("compare_folders", ROOT / "scripts" / "compare_folders.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_a_folder_agrees_with_its_copy(tmp_path, capsys):
    shutil.copytree(FIXTURE, tmp_path / "copy")
    rc = _script().main([f"fp32={FIXTURE}", f"bf16={tmp_path / 'copy'}", "--models", "M0,M4",
                         "--out", str(tmp_path / "out"), "--no-figures"])
    out = capsys.readouterr().out
    assert rc == 0 and "agree:" in out
    table = pd.read_csv(tmp_path / "out" / "table.csv")
    assert [c for c in table.columns if c.startswith("M")] == ["M0 fp32", "M0 bf16", "M4 fp32", "M4 bf16"]
    training = pd.read_csv(tmp_path / "out" / "training.csv")
    assert set(training["model"]) == {"M0 fp32", "M0 bf16", "M4 fp32", "M4 bf16"}


def test_a_shifted_variant_is_named_and_exits_1(tmp_path, capsys):
    variant = tmp_path / "variant"
    shutil.copytree(FIXTURE, variant)
    for path in (variant / "M0").glob("seed*/evaluation_rows.csv"):
        rows = pd.read_csv(path)
        rows["AS"] = rows["AS"] + 0.3  # every simulation 0.3 m/s faster: no overlap possible
        rows.to_csv(path, index=False)
    for path in (variant / "M0").glob("seed*/metrics.csv"):
        metrics = pd.read_csv(path)
        metrics["episode_reward_mean"] += 100.0
        metrics.to_csv(path, index=False)
    rc = _script().main([f"fp32={FIXTURE}", f"bf16={variant}", "--out", str(tmp_path / "out"), "--no-figures"])
    out = capsys.readouterr().out
    assert rc == 1
    lines = [line for line in out.splitlines() if line.startswith("  ")]
    assert sum(" AS: M0 fp32 " in line for line in lines) == 4  # one per scenario
    assert any(line.startswith("  final training reward: M0 fp32") for line in lines)
    assert not any(" CD: " in line for line in lines)  # unchanged metrics still agree


def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys):
    script = _script()
    assert script.main([f"a={FIXTURE}", f"a={FIXTURE}"]) == 2
    assert "different tags" in capsys.readouterr().err
    assert script.main([f"a={FIXTURE}", f"b={tmp_path / 'none'}"]) == 2
    assert "results folder not found" in capsys.readouterr().err
    assert script.main([f"a={FIXTURE}", f"b={FIXTURE}", "--models", "M3"]) == 2
    assert "no evaluation rows for M3" in capsys.readouterr().err
