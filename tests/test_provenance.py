"""Each start of a training records what it ran on (provenance.json in the run folder, the same
values as `provenance.*` tags of its MLflow run), and the study page lists it per column,
flagging columns trained under other library versions or hardware; runs from before the
record read "not recorded"."""

from __future__ import annotations

import json
import platform
import subprocess
from importlib import metadata
from pathlib import Path

import mlflow
import pandas as pd
import pytest

from sigmarl.compose import compose_config
from sigmarl.report.study import provenance_markdown, run_records
from sigmarl.run import Run
from sigmarl.training import train

ROOT = Path(__file__).resolve().parents[1]


def _git(*args: str) -> str:
    return subprocess.run(["git", "-C", str(ROOT), *args], capture_output=True, text=True, check=True).stdout.strip()


@pytest.mark.slow
def test_a_training_and_its_resume_each_record_what_they_ran_on(tmp_path):
    run_dir, db = tmp_path / "run", tmp_path / "mlflow.db"
    base = ["ppo=smoke", "ppo.iterations=2", f"run_dir={run_dir}", f"tracking.tracking_uri=sqlite:///{db}", "threads=1"]
    first = train(compose_config([*base, "ppo.stop_after=1"]))  # stopped after one iteration
    train(compose_config([*base, "resume=true"]))
    records = json.loads((run_dir / "provenance.json").read_text())["records"]
    assert [r["from_iteration"] for r in records] == [0, 1]
    mine = records[0]
    assert mine["python"] == platform.python_version()
    for package in ("torch", "torchrl", "tensordict", "vmas", "hydra-core", "mlflow", "numpy"):
        assert mine[package] == metadata.version(package)
    cpu = [line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines()
           if line.startswith("model name")]
    assert mine["cpu"] == " ".join(cpu[0].split())
    assert mine["threads"] == 1 and mine["device"] == "cpu"
    assert mine["sigmarl_commit"] == _git("rev-parse", "HEAD")
    assert mine["dirty"] == bool(_git("status", "--porcelain", "--untracked-files=no"))
    tags = mlflow.MlflowClient(f"sqlite:///{db}").get_run(first.run_id).data.tags
    assert tags["provenance.torch"] == metadata.version("torch") and tags["provenance.cpu"] == mine["cpu"]
    assert tags["provenance.sigmarl_commit"] == mine["sigmarl_commit"] and tags["provenance.threads"] == "1"


def _record(**changes) -> dict:
    base = {"python": "3.11.7", "torch": "2.13.0", "torchrl": "0.14.1", "tensordict": "0.14.3", "vmas": "1.5.2",
            "hydra-core": "1.3.8", "mlflow": "3.18.0", "numpy": "2.4.6", "cpu": "AMD EPYC", "gpu": "none",
            "device": "cpu", "threads": 1, "sigmarl_commit": "0123456789abcdef", "dirty": False}
    return {"from_iteration": 0, **base, **changes}


def _folder(root: Path, label: str, seed: int, records: list[dict] | None) -> tuple[str, int, Path]:
    path = root / label / f"seed{seed}"
    path.mkdir(parents=True)
    if records is not None:
        (path / "provenance.json").write_text(json.dumps({"format": 1, "records": records}))
    return label, seed, path


def test_the_study_page_lists_each_column_and_flags_what_differs(tmp_path):
    """A: two seeds alike; B: torch 2.12 on an H100, resumed on the EPYC; C: from before the record."""
    folders = [_folder(tmp_path, "A", 0, [_record()]), _folder(tmp_path, "A", 1, [_record()]),
               _folder(tmp_path, "B", 0, [_record(torch="2.12.0", gpu="NVIDIA H100", device="cuda"),
                                          _record(from_iteration=40)]),
               _folder(tmp_path, "C", 0, None), _folder(tmp_path, "C", 9, [_record()])]  # seed 9: no rows
    rows = pd.DataFrame({"model": ["A", "A", "B", "C"], "seed": [0, 1, 0, 0]})
    records = run_records(folders, rows)
    assert set(records) == {"A", "B", "C"} and records["C"] == {0: None}
    lines = provenance_markdown(records, ["A", "B", "C"])
    assert "| torch | 2.13.0 | 2.12.0 / 2.13.0 | not recorded |" in lines
    assert "| gpu | none | NVIDIA H100 / none | not recorded |" in lines
    assert "| sigmarl_commit | 0123456789ab | 0123456789ab | not recorded |" in lines
    assert "| dirty | clean | clean | not recorded |" in lines
    assert "**Trained under different library versions**: torch 2.13.0 (A, B); 2.12.0 (B)." in lines
    assert "**Trained on different hardware**: gpu none (A, B); NVIDIA H100 (B)." in lines
    assert "Runs of C are not recorded (trained before sigmarl recorded it)." in lines
    same = provenance_markdown(run_records(folders[:2], rows), ["A"])
    assert "Every recorded run used the same library versions and hardware." in same


def test_committed_runs_read_not_recorded():
    folders = [("M0", 0, ROOT / "results" / "paper-budget" / "M0" / "seed0"),
               ("M5", 3, ROOT / "results" / "paper-budget" / "M5" / "seed3")]
    assert not any(Run(p).provenance_file.exists() for _, _, p in folders)
    rows = pd.DataFrame({"model": ["M0", "M5"], "seed": [0, 3]})
    assert provenance_markdown(run_records(folders, rows), ["M0", "M5"])[-1] == (
        "Provenance: not recorded (every run was trained before sigmarl recorded it in `provenance.json`).")
