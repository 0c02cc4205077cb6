"""A reliability round in one command: named fault probes against the `sigmarl` CLI, each in its
own temporary folder at a smoke budget, with PASS or FAIL per probe (exit code 1 if any fails).

    python scripts/probe.py            # every probe (about a minute on 2 cores)
    python scripts/probe.py F3 kill9   # the probes whose names contain one of the words

Bad input must end in one line `sigmarl: error: ...`, exit code 2, and leave nothing behind. A
run folder killed with SIGKILL mid-training must resume to one metrics row per iteration; the
same folder with a damaged file must be refused in one line naming that file, or repaired where
the checkpoint holds what was lost (config.yaml). A new round of
probes starts from this list: add a `Probe`.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

SIGMARL = [sys.executable, "-m", "sigmarl"]
SMOKE = ["ppo=smoke", "tracking.enabled=false", "threads=1"]
KILLED_ITERATIONS = 20  # long enough that the kill lands mid-training (it lands at about the 4th)


@dataclass
class Probe:
    name: str
    fault: str  # what is done, in words
    argv: list[str]
    refused: str | None = None  # the refusal's line must name this; None: the command must succeed
    setup: Callable[[Path], None] | None = None  # prepares the probe's folder
    check: Callable[[Path], str | None] | None = None  # after the command: None, or what is wrong
    new_files: bool = field(default=False)  # whether the command may create files


def run(argv: list[str], cwd: Path, timeout: int = 300) -> subprocess.CompletedProcess:
    env = {**os.environ, "OMP_NUM_THREADS": "1", "SIGMARL_CONFIG_PATH": ""}
    return subprocess.run([*SIGMARL, *argv], cwd=cwd, capture_output=True, text=True, timeout=timeout, env=env)


def killed_run(folder: Path) -> Path:
    """A run folder whose training was killed with SIGKILL after its third checkpoint."""
    argv = [*SIGMARL, "train", *SMOKE, f"ppo.iterations={KILLED_ITERATIONS}", "ppo.checkpoint_every=1",
            "runs_root=runs"]
    proc = subprocess.Popen(argv, cwd=folder, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True, env={**os.environ, "OMP_NUM_THREADS": "1"})
    run_dir = folder / "runs" / "M0" / "seed0"
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and proc.poll() is None:
        metrics = run_dir / "metrics.csv"
        if (run_dir / "checkpoint.pt").is_file() and metrics.is_file() and metrics.read_text().count("\n") >= 4:
            break
        time.sleep(0.2)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    if (run_dir / "final.pt").exists():
        raise SystemExit("probe: the training finished before the kill; raise KILLED_ITERATIONS")
    return run_dir


RESUME = ["train", *SMOKE, f"ppo.iterations={KILLED_ITERATIONS}", "ppo.checkpoint_every=1", "runs_root=runs",
          "resume=true"]


def _copy_killed(base: Path) -> Callable[[Path], None]:
    def setup(folder: Path) -> None:
        shutil.copytree(base, folder / "runs", dirs_exist_ok=True)
    return setup


def _then(first: Callable[[Path], None], damage: Callable[[Path], None]) -> Callable[[Path], None]:
    def setup(folder: Path) -> None:
        first(folder)
        damage(folder / "runs" / "M0" / "seed0")
    return setup


def _whole_metrics(folder: Path) -> str | None:
    lines = (folder / "runs" / "M0" / "seed0" / "metrics.csv").read_text().splitlines()[1:]
    found = [int(line.split(",")[0]) for line in lines]
    want = list(range(1, KILLED_ITERATIONS + 1))
    return None if found == want else f"metrics.csv holds iterations {found[:5]}... not 1..{KILLED_ITERATIONS}"


def _config_whole(folder: Path) -> str | None:
    """The resume wrote the record again, so `report` and `evaluate` can read the folder."""
    from sigmarl.errors import SigmarlError
    from sigmarl.readers import read_run_config

    try:
        read_run_config(folder / "runs" / "M0" / "seed0" / "config.yaml")
    except SigmarlError as e:
        return f"config.yaml left damaged: {e}"
    return _whole_metrics(folder)


def _bad_yaml(folder: Path) -> None:
    (folder / "conf" / "study").mkdir(parents=True)
    (folder / "conf" / "study" / "mine.yaml").write_text("variants:\n  A: [obs=paper\n")


def _drop_row(run_dir: Path) -> None:
    lines = (run_dir / "metrics.csv").read_text().splitlines(keepends=True)
    (run_dir / "metrics.csv").write_text("".join(lines[:2] + lines[3:]))


def _cut_half(run_dir: Path) -> None:
    data = (run_dir / "checkpoint.pt").read_bytes()
    (run_dir / "checkpoint.pt").write_bytes(data[: len(data) // 2])


def probes(killed: Path) -> list[Probe]:
    copy = _copy_killed(killed)
    return [
        Probe("unknown-key", "a misspelt key", ["train", *SMOKE, "ppo.epoch=3"], refused="ppo.epochs"),
        Probe("F1-experiment", "an experiment name that leaves the runs folder",
              ["train", *SMOKE, "tracking.experiment=../../etc"], refused="tracking.experiment"),
        Probe("F2-seeds", "a seed that is not a whole number", ["sweep", "study=quick", "models=[M0]", "seeds=[abc]"],
              refused="seed"),
        Probe("F3-nan", "NaN as a learning rate", ["train", *SMOKE, "ppo.lr=nan"], refused="ppo.lr"),
        Probe("F4-yaml", "a syntax error in a --config-dir", ["--config-dir", "conf", "train", *SMOKE],
              refused="mine.yaml", setup=_bad_yaml),
        Probe("agents", "more agents than the map holds", ["train", *SMOKE, "env.n_agents=10000"],
              refused="n_agents"),
        Probe("checkpoint-missing", "evaluating a checkpoint that is not there",
              ["evaluate", "nowhere/best.pt", "tracking.enabled=false"], refused="nowhere/best.pt"),
        Probe("kill9-resume", "SIGKILL mid-training, then the same command with resume=true", RESUME,
              setup=copy, check=_whole_metrics, new_files=True),
        Probe("F11-config", "a binary config.yaml in a killed run folder (the checkpoint holds its config)",
              RESUME, setup=_then(copy, lambda d: (d / "config.yaml").write_bytes(bytes(range(256)))),
              check=_config_whole, new_files=True),
        Probe("F12-metrics", "a row missing in the middle of metrics.csv", RESUME, refused="metrics.csv",
              setup=_then(copy, _drop_row)),
        Probe("F13-checkpoint", "checkpoint.pt cut in half", RESUME, refused="checkpoint.pt",
              setup=_then(copy, _cut_half)),
    ]


def _files(folder: Path) -> set[Path]:
    return {p.relative_to(folder) for p in folder.rglob("*")}


def verdict(probe: Probe, folder: Path) -> tuple[bool, str]:
    before = _files(folder)
    done = run(probe.argv, folder)
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    if probe.refused is None:
        if done.returncode != 0:
            return False, f"rc {done.returncode}: {(lines or ['(no output)'])[-1]}"
        wrong = probe.check(folder) if probe.check else None
        return wrong is None, wrong or "succeeded"
    if done.returncode != 2:
        return False, f"rc {done.returncode}, not 2: {(lines or ['(no output)'])[-1][:160]}"
    if len(lines) != 1 or not lines[0].startswith("sigmarl: error:"):
        return False, f"{len(lines)} lines on stderr, not one `sigmarl: error:` line"
    if probe.refused not in lines[0]:
        return False, f"the line does not name {probe.refused!r}: {lines[0][:160]}"
    if not probe.new_files and (new := _files(folder) - before):
        return False, f"left {sorted(map(str, new))[:3]} behind"
    return True, lines[0][:160]


def main(words: list[str]) -> int:
    with tempfile.TemporaryDirectory(prefix="sigmarl-probe-") as tmp:
        root = Path(tmp)
        (root / "base").mkdir()
        killed = killed_run(root / "base").parents[1]
        chosen = [p for p in probes(killed) if not words or any(w in p.name for w in words)]
        failed = 0
        for probe in chosen:
            folder = root / probe.name
            folder.mkdir()
            if probe.setup:
                probe.setup(folder)
            ok, said = verdict(probe, folder)
            failed += not ok
            print(f"{'PASS' if ok else 'FAIL'}  {probe.name:20} {probe.fault}: {said}", flush=True)
        print(f"{len(chosen) - failed} of {len(chosen)} probes passed")
        return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
