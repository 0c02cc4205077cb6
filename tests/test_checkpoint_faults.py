"""Checkpoints that cannot be trusted or cannot be written: weights that are not finite are
refused in one line, and a disk that fills up while a checkpoint is written ends in one line
with the previous resume point intact."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest
import torch

from sigmarl.cli import main
from sigmarl.errors import SigmarlError
from sigmarl.training import checkpoint as ckpt

PAPER_RUN = Path(__file__).resolve().parents[1] / "results" / "paper-budget" / "M0" / "seed0"


def _poisoned(src: Path, dst: Path, key: str, value: float) -> Path:
    state = torch.load(src, weights_only=True)
    name = next(iter(state[key]))
    state[key][name].view(-1)[7] = value
    torch.save(state, dst)
    return dst


def _one_line(capsys) -> str:
    """The one error line on stderr (the training's progress bar aside)."""
    lines = [line for line in capsys.readouterr().err.strip().splitlines() if not line.startswith("train:")]
    assert len(lines) == 1 and lines[0].startswith("sigmarl: error: "), lines
    return lines[0]


@pytest.mark.parametrize("value", [float("nan"), float("inf")])
def test_evaluating_a_checkpoint_with_nan_weights_is_one_line(tmp_path, capsys, value):
    path = _poisoned(PAPER_RUN / "best.pt", tmp_path / "best.pt", "policy", value)
    rc = main(["evaluate", str(path), "--scenario", "On-Ramp", "--out", str(tmp_path / "rows.csv"),
               "eval.n_sims=1", "eval.steps=2", "tracking.enabled=false"])
    assert rc == 2
    line = _one_line(capsys)
    assert str(path) in line and "NaN or infinite" in line
    assert not (tmp_path / "rows.csv").exists()


def test_a_resume_point_with_nan_critic_weights_is_refused(tmp_path):
    path = _poisoned(PAPER_RUN / "checkpoint.pt", tmp_path / "checkpoint.pt", "critic", float("nan"))
    with pytest.raises(SigmarlError, match="critic tensor .* holds NaN or infinite values"):
        ckpt.load(path, resume=True)


@pytest.fixture
def tiny_disk(tmp_path):
    """A 3 MB tmpfs: room for config.yaml, metrics.csv, one resume point (2.1 MB with the
    optimiser state) and best.pt, not for writing the next resume point beside the first."""
    mount = tmp_path / "disk"
    mount.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=3m", "tmpfs", str(mount)],
                      capture_output=True).returncode != 0:
        pytest.skip("cannot mount a tmpfs here (needs root)")
    try:
        yield mount
    finally:
        subprocess.run(["umount", str(mount)], check=False)


def test_a_full_disk_while_a_checkpoint_is_written_is_one_line_and_keeps_the_resume_point(
        tiny_disk, capsys):
    run_dir = tiny_disk / "run"
    rc = main(["train", "ppo=smoke", "ppo.iterations=3", "ppo.checkpoint_every=1", "tracking.enabled=false",
               f"run_dir={run_dir}"])
    assert rc == 2
    line = _one_line(capsys)
    assert "No space left on device" in line and str(run_dir / ckpt.RESUME_FILE) in line
    state = ckpt.load(run_dir / ckpt.RESUME_FILE, resume=True)  # still a valid resume point
    assert state["iteration"] == 0
    assert not [p.name for p in run_dir.iterdir() if p.name.endswith(".tmp")]  # no half-written file


def test_a_checkpoint_is_hashed_in_blocks_not_read_whole(tmp_path):
    import hashlib
    import tracemalloc

    from sigmarl.compose import compose_config
    from sigmarl.evaluation.protocol import _identity

    big = tmp_path / "big.pt"
    block = bytes(range(256)) * 4096  # 1 MiB
    with big.open("wb") as f:
        for _ in range(64):
            f.write(block)
    cfg = compose_config([])
    tracemalloc.start()
    try:
        digest = _identity(big, cfg)["checkpoint_sha256"]
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert digest == hashlib.sha256(block * 64).hexdigest()
    assert peak < 8 * 2**20  # the file is 64 MiB
