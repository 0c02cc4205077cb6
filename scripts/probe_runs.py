"""Probes of run folders: kill -9 and damaged files, one writer per folder however it is spelled,
a user's tracker failing mid-run, and a seed block killed and resumed."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import probe_fixtures as fx
from probe_kit import SMOKE, TRACKERS, Probe, files, one_line, refusal, sigmarl

BLOCK = ["train", *SMOKE, "seeds=[0,1]", f"ppo.iterations={fx.ITERATIONS}", "ppo.checkpoint_every=1", "runs_root=runs"]


def _weights(path: Path) -> dict:
    import torch

    return torch.load(path, weights_only=True)["policy"]


def _same_weights(a: Path, b: Path) -> str | None:
    import torch

    x, y = _weights(a), _weights(b)
    if x.keys() != y.keys() or not all(torch.equal(x[k], y[k]) for k in x):
        worst = max(float((x[k] - y[k]).abs().max()) for k in x if x[k].shape == y[k].shape)
        return f"{a} differs from the uninterrupted {b} (largest difference {worst:.3g})"
    return None


def _metrics_whole(run: Path) -> str | None:
    found = [int(line.split(",")[0]) for line in (run / "metrics.csv").read_text().splitlines()[1:]]
    want = list(range(1, fx.ITERATIONS + 1))
    return None if found == want else f"metrics.csv holds iterations {found[:6]}..., not 1..{fx.ITERATIONS}"


def _kill9_resume(folder: Path) -> str | None:
    fx.copy_of(fx.killed)(folder)
    done = sigmarl(fx.RESUME, folder)
    if done.returncode != 0:
        return f"the resume failed (rc {done.returncode}): {done.stderr[-200:]}"
    return _metrics_whole(folder / fx.RUN) or _same_weights(folder / fx.RUN / "final.pt",
                                                            fx.whole() / fx.RUN / "final.pt")


def _garbled_config(folder: Path) -> str | None:
    fx.copy_of(fx.killed)(folder)
    (folder / fx.RUN / "config.yaml").write_bytes(bytes(range(256)))
    done = sigmarl(fx.RESUME, folder)
    if done.returncode != 0:
        return f"the resume failed (rc {done.returncode}): {done.stderr[-200:]}"
    from sigmarl.errors import SigmarlError
    from sigmarl.readers import read_run_config

    try:
        read_run_config(folder / fx.RUN / "config.yaml")
    except SigmarlError as e:
        return f"config.yaml left damaged: {e}"
    return _metrics_whole(folder / fx.RUN)


def _damaged(damage: Callable[[Path], None]) -> Callable[[Path], None]:
    def setup(folder: Path) -> None:
        fx.copy_of(fx.killed)(folder)
        damage(folder / fx.RUN)
    return setup


def _drop_row(run: Path) -> None:
    lines = (run / "metrics.csv").read_text().splitlines(keepends=True)
    (run / "metrics.csv").write_text("".join(lines[:2] + lines[3:]))


def _nan_optimiser(run: Path) -> None:
    """A NaN in the resume point's optimiser state, saved as training saves (checksum and all):
    what a diverged step leaves, not damage a checksum would catch."""
    import torch

    from sigmarl.training import checkpoint

    state = torch.load(run / "checkpoint.pt", weights_only=True)
    next(iter(state["optimizer"]["state"].values()))["exp_avg"].view(-1)[3] = float("nan")
    checkpoint.save_atomic(state, run / "checkpoint.pt")


def _flip_bit(run: Path) -> None:
    data = bytearray((run / "checkpoint.pt").read_bytes())
    data[len(data) // 2] ^= 0x10
    (run / "checkpoint.pt").write_bytes(bytes(data))


HOLD = "import sys, time\nfrom sigmarl.run import Run\nwith Run(sys.argv[1]).lock():\n    print('held', flush=True)\n    time.sleep(600)\n"


def _held(folder: Path, run: Path) -> subprocess.Popen:
    proc = subprocess.Popen([sys.executable, "-c", HOLD, str(run)], cwd=folder, stdout=subprocess.PIPE, text=True)
    if proc.stdout.readline().strip() != "held":
        raise RuntimeError("the holder process did not take the lock")
    return proc


def _one_writer(folder: Path, held: Path, argv: list[str], setup=None) -> str | None:
    """`argv` is refused while another process holds `held` (the same folder, spelled otherwise)."""
    if setup:
        setup(folder)
    holder = _held(folder, held)
    try:
        before = files(folder)
        wrong = one_line(sigmarl(argv, folder), "is in use by another sigmarl process")
        return wrong or (None if files(folder) == before else "the refused command changed the folder")
    finally:
        holder.kill()
        holder.wait()


def _evaluate_while_trained(folder: Path) -> str | None:
    return _one_writer(folder, fx.RUN, ["evaluate", str(fx.RUN / "best.pt"), "eval.n_sims=1", "tracking.enabled=false"],
                       fx.copy_of(fx.whole))


def _symlinked(folder: Path) -> str | None:
    (folder / "runs" / "real").mkdir(parents=True)
    (folder / "link").symlink_to(folder / "runs" / "real")
    for spelling in ("run_dir=link", "run_dir=runs/../runs/real"):
        wrong = _one_writer(folder, Path("runs/real"), ["train", *SMOKE, spelling, "resume=true"])
        if wrong:
            return f"{spelling}: {wrong}"
    return None




def _tracker_mid_run(folder: Path) -> str | None:
    (folder / "flaky_tracker.py").write_text(TRACKERS)
    done = sigmarl(["train", *SMOKE, "tracking.enabled=true", "tracking.backend=flaky_tracker:Flaky",
                    "runs_root=runs"], folder)
    warnings = [line for line in done.stderr.splitlines() if line.startswith("sigmarl: warning: tracker")]
    if done.returncode != 0 or not (folder / fx.RUN / "final.pt").exists():
        return f"the training did not finish (rc {done.returncode}): {done.stderr[-200:]}"
    return None if len(warnings) == 1 else f"{len(warnings)} tracker warnings, not one"


def _block_kill9(folder: Path) -> str | None:
    (folder / "whole").mkdir()
    (folder / "killed").mkdir()
    done = sigmarl(BLOCK, folder / "whole")
    if done.returncode != 0:
        return f"the uninterrupted block failed (rc {done.returncode}): {done.stderr[-200:]}"
    killed = sigmarl(BLOCK, folder / "killed", SIGMARL_CRASH_AT=f"train:checkpoint:{fx.KILLED_AT}")
    if killed.returncode != -9:
        return f"the block was not killed at its crash point (rc {killed.returncode})"
    done = sigmarl([*BLOCK, "resume=true"], folder / "killed")
    if done.returncode != 0:
        return f"the block's resume failed (rc {done.returncode}): {done.stderr[-200:]}"
    for seed in (0, 1):
        run = Path("runs") / "M0" / f"seed{seed}"
        if wrong := _metrics_whole(folder / "killed" / run) or _same_weights(folder / "killed" / run / "final.pt",
                                                                             folder / "whole" / run / "final.pt"):
            return f"seed {seed}: {wrong}"
    return None


PROBES = [
    Probe("kill9-resume", "SIGKILL mid-training, then resume=true: the weights of an uninterrupted run",
          _kill9_resume),
    Probe("F11-config", "a binary config.yaml in a killed run folder (the checkpoint holds its config)",
          _garbled_config),
    Probe("F12-metrics", "a row missing in the middle of metrics.csv",
          refusal(fx.RESUME, "metrics.csv", _damaged(_drop_row))),
    Probe("F13-nan-optimiser", "a NaN in the resume point's optimiser state never reaches best.pt",
          refusal(fx.RESUME, "optimiser state", _damaged(_nan_optimiser))),
    Probe("G6-flipped-bit", "one flipped bit in checkpoint.pt", refusal(fx.RESUME, "is damaged", _damaged(_flip_bit))),
    Probe("F15-tracker-mid", "a user's tracker failing on every call once training runs", _tracker_mid_run),
    Probe("F18-evaluate-lock", "evaluate a run folder another process writes", _evaluate_while_trained),
    Probe("G1-symlink", "train through a symlink and a `..` path to a folder another process writes", _symlinked),
    Probe("block-kill9-resume", "SIGKILL mid-block, then resume: every seed equal to the uninterrupted block's",
          _block_kill9),
]
