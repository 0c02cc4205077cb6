"""`device=cuda` end to end: train, a seed block, resume, evaluate, sweep and report on a GPU.

Runs only where torch sees a CUDA GPU (`pytest -m cuda`; `benchmarks/device_check.sh` runs it on
a GPU machine); everywhere else every test here is skipped. Tracking is off (the GPU machine
need not carry MLflow): the records checked are the run folders, which a sweep's report reads.

What is checked against what, and how closely:
- a block of 2 on cuda against the cuda run of its seed 0 alone (a block of one) after one iteration, as
  tests/test_blocks.py checks it on the CPU but at 1e-4 relative (cuBLAS' batched and plain
  products may round differently, and Adam turns rounding noise near a zero gradient into a
  step of up to lr);
- the cuda-trained policy evaluated on cuda against the same checkpoint evaluated on the CPU:
  30 steps of 2 simulations, the mean speed within 1e-3 m/s (float rounding may differ, the
  trajectories may not drift apart in 30 steps).
"""

from __future__ import annotations

import json

import pandas as pd
import pytest
import torch

from sigmarl.cli import main
from sigmarl.run import BLOCK_FILE, FINAL_FILE, RESUME_FILE, ROWS_FILE
from sigmarl.training import checkpoint as ckpt

pytestmark = [pytest.mark.cuda, pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA GPU here")]

CUDA = ["ppo=smoke", "threads=1", "tracking.enabled=false", "device=cuda"]
EVAL = ["eval.n_sims=2", "eval.steps=30", "eval.scenarios=[Roundabout]", "tracking.enabled=false"]


def _weights(path) -> dict[str, torch.Tensor]:
    state = ckpt.load(path)
    return {f"{part}.{k}": v.cpu() for part in ("policy", "critic") for k, v in state.get(part, {}).items()}


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """A cuda run of seed 0 alone and a cuda block of seeds 0 and 1: one iteration, then resumed
    to the smoke budget's end."""
    root = tmp_path_factory.mktemp("cuda")
    lone, block = root / "lone", root / "block"
    first = {"lone": main(["train", *CUDA, "ppo.stop_after=1", f"run_dir={lone}"]),
             "block": main(["train", *CUDA, "ppo.stop_after=1", "seeds=[0,1]", f"runs_root={block}"])}
    one = {"lone": _weights(lone / RESUME_FILE), "block": _weights(block / "M0" / "seed0" / RESUME_FILE)}
    rest = {"lone": main(["train", *CUDA, "resume=true", f"run_dir={lone}"]),
            "block": main(["train", *CUDA, "resume=true", "seeds=[0,1]", f"runs_root={block}"])}
    return root, first, one, rest


def test_a_lone_run_trains_and_resumes_on_cuda(trained) -> None:
    root, first, _, rest = trained
    assert first["lone"] == 0 and rest["lone"] == 0
    state = ckpt.load(root / "lone" / RESUME_FILE, resume=True)
    assert state["iteration"] == 3 and state["resolved"]["device"] == "cuda"
    assert all(torch.isfinite(v).all() for v in _weights(root / "lone" / FINAL_FILE).values())


def test_a_block_of_two_trains_on_cuda_as_its_lone_seeds_do(trained) -> None:
    root, first, one, rest = trained
    assert first["block"] == 0 and rest["block"] == 0
    for s in (0, 1):
        folder = root / "block" / "M0" / f"seed{s}"
        assert json.loads((folder / BLOCK_FILE).read_text())["seeds"] == [0, 1]
        assert ckpt.load(folder / RESUME_FILE, resume=True)["iteration"] == 3
        assert (folder / FINAL_FILE).exists()
    mine, alone = one["block"], one["lone"]
    assert mine.keys() == alone.keys()
    for key in alone:
        assert float((mine[key] - alone[key]).norm() / alone[key].norm()) <= 1e-4, key


def test_evaluate_on_cuda_scores_what_the_cpu_scores(trained, tmp_path) -> None:
    root = trained[0]
    final = root / "lone" / FINAL_FILE
    assert main(["evaluate", str(final), *EVAL, "device=cuda", "--out", str(tmp_path / "cuda.csv")]) == 0
    assert main(["evaluate", str(final), *EVAL, "device=cpu", "--out", str(tmp_path / "cpu.csv")]) == 0
    gpu, cpu = pd.read_csv(tmp_path / "cuda.csv"), pd.read_csv(tmp_path / "cpu.csv")
    assert len(gpu) == len(cpu) == 2
    assert abs(gpu["AS"].mean() - cpu["AS"].mean()) <= 1e-3


def test_a_sweep_and_its_report_run_on_cuda(tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    runs = tmp_path / "runs"
    tiny = ["study=quick", "models=[M0]", "seeds=[0,1]", "ppo.iterations=1", "ppo.frames_per_iteration=128",
            "ppo.epochs=1", "ppo.minibatch_size=64", "hydra.launcher.n_jobs=1", *EVAL]
    assert main(["sweep", *tiny, "device=cuda", f"runs_root={runs}"]) == 0
    for s in (0, 1):  # on cuda the default packs a variant's seeds into one block job
        assert (runs / "M0" / f"seed{s}" / ROWS_FILE).exists()
        assert json.loads((runs / "M0" / f"seed{s}" / BLOCK_FILE).read_text())["seeds"] == [0, 1]
    out = tmp_path / "report"
    assert main(["report", "study=quick", "--from", str(runs), "tracking.enabled=false", "--no-figures",
                 "--out", str(out)]) == 0
    assert "M0" in next(ln for ln in (out / "table.md").read_text().splitlines() if ln.startswith("| Scenario"))
