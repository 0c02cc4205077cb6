"""A reliability round in one command: one named probe per fault of the reliability rounds
(F1-F18, G1-G11) and per promise of the run folder (kill -9 resume, blocks, sweeps, `evaluate`'s
lock, `report`), each run against the `sigmarl` CLI in its own temporary folder at a smoke
budget, PASS or FAIL per probe (exit code 1 if any fails).

    python scripts/probe.py               # the whole round (83 s on 2 idle cores)
    python scripts/probe.py F13 G1 kill9  # the probes named so: an exact name, or its fault (F6: both F6 probes)
    python scripts/probe.py --list F6     # the names a selection runs, without running them
    python scripts/probe.py --quick       # the probes that train nothing (bad input; a minute)

Each probe checks the property its name promises, not a stand-in: F13 that a NaN optimiser state
never reaches best.pt, `kill9-resume` that the resumed weights equal an uninterrupted run's.
Bad input must end in one line `sigmarl: error: ...`, exit code 2, and leave nothing behind. A new
round of probes starts by adding a `Probe` to one of the lists (`probe_input`, `probe_runs`,
`probe_sweeps`).
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

ROOT = Path(__file__).resolve().parents[1]
SIGMARL = [sys.executable, "-m", "sigmarl"]
SMOKE = ["ppo=smoke", "tracking.enabled=false", "threads=1"]
# a study small enough for seconds: one iteration's evaluation of 5 steps on one scenario
TINY_EVAL = ["eval.n_sims=1", "eval.steps=5", "eval.scenarios=[Roundabout]"]


# A user's tracker (tracking.backend=module:Class) that fails: when it is made (Refuses), or on
# every metrics call once the work runs (Flaky); a probe writes it into its folder.
TRACKERS = '''
from sigmarl.tracking import Tracker, TrainingRun

class Run(TrainingRun):
    run_id = "r1"
    def set_tags(self, tags): pass
    def log_params(self, params): pass
    def log_metrics(self, rows): raise ConnectionError("the tracker's server went away")
    def sync_metrics(self, rows): self.log_metrics(rows)
    def log_artifact(self, path): pass
    def log_missing_artifacts(self, paths): pass
    def status(self): return "RUNNING"
    def finish(self, status="FINISHED"): pass

class Flaky(Tracker):
    def training_run(self, run_id=None, reopen=True): return Run()
    def discard_training_run(self, run_id): pass
    def finished_evaluation(self, train_run_id, eval_key): return None
    def log_evaluation(self, rows, tags, params): return None
    def log_report(self, composite, paths, tags, source=None): return None

class Refuses(Flaky):
    def __init__(self, cfg): raise PermissionError("no token for the tracker's server")
'''


@dataclass
class Probe:
    name: str  # "<fault>-<what>" (the fault, e.g. F13, selects every probe of it) or a plain name
    fault: str  # what is done, in words
    check: Callable[[Path], str | None]  # run in the probe's own folder: None, or what is wrong
    trains: bool = False  # it trains (or evaluates) a model: left out of `--quick`

    @property
    def fault_id(self) -> str:
        return self.name.split("-")[0]


def env(**extra: str) -> dict[str, str]:
    return {**os.environ, "OMP_NUM_THREADS": "1", "SIGMARL_CONFIG_PATH": "", **extra}


def sigmarl(argv: list[str], cwd: Path, timeout: int = 300, **extra: str) -> subprocess.CompletedProcess:
    return subprocess.run([*SIGMARL, *argv], cwd=cwd, capture_output=True, text=True, timeout=timeout,
                          env=env(**extra))


def start(argv: list[str], cwd: Path, **extra: str) -> subprocess.Popen:
    return subprocess.Popen([*SIGMARL, *argv], cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True, env=env(**extra))


def wait_for(condition: Callable[[], bool], seconds: float = 300) -> bool:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.2)
    return False


def files(folder: Path) -> dict[Path, bytes]:
    """Every file below `folder` with its bytes (to tell that a refusal changed nothing), but for
    the run folders' lock files beside them, which any command that checks a folder takes."""
    return {p.relative_to(folder): p.read_bytes() for p in folder.rglob("*")
            if p.is_file() and not (p.name.startswith(".") and p.name.endswith(".lock"))}


def last_line(done: subprocess.CompletedProcess) -> str:
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    return (lines or ["(no output)"])[-1][:200]


def one_line(done: subprocess.CompletedProcess, says: str) -> str | None:
    """None if `done` is a refusal in one line naming `says`, with exit code 2."""
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    if done.returncode != 2:
        return f"rc {done.returncode}, not 2: {last_line(done)}"
    if len(lines) != 1 or not lines[0].startswith("sigmarl: error:"):
        return f"{len(lines)} lines on stderr, not one `sigmarl: error:` line: {last_line(done)}"
    if says not in lines[0]:
        return f"the line does not name {says!r}: {lines[0][:200]}"
    return None


def refusal(argv: list[str], says: str, setup: Callable[[Path], None] | None = None) -> Callable[[Path], str | None]:
    """A probe: after `setup`, `sigmarl argv` is refused in one line naming `says`, and the folder
    is left exactly as it was (no new file, no changed one)."""
    def check(folder: Path) -> str | None:
        if setup:
            setup(folder)
        before = files(folder)
        wrong = one_line(sigmarl(argv, folder), says)
        if wrong:
            return wrong
        after = files(folder)
        if after != before:
            changed = sorted(str(p) for p in set(after) ^ set(before) | {p for p in after if after.get(p) != before.get(p)})
            return f"the refusal left the folder changed: {changed[:3]}"
        return None
    return check


def all_probes() -> list[Probe]:
    import probe_input
    import probe_runs
    import probe_sweeps

    # every run-folder and sweep probe trains; of the input probes, only those that say so
    probes = [*probe_input.PROBES, *(replace(p, trains=True) for p in (*probe_runs.PROBES, *probe_sweeps.PROBES))]
    names = [p.name for p in probes]
    assert len(set(names)) == len(names), "two probes share a name"
    return probes


def select(probes: list[Probe], words: list[str]) -> list[Probe]:
    """The probes a word names exactly (its whole name, or its fault: `F1` is F1's, never F11's)."""
    unknown = [w for w in words if not any(w in (p.name, p.fault_id) for p in probes)]
    if unknown:
        raise SystemExit(f"probe.py: no probe named {', '.join(unknown)}; `--list` names them all")
    return [p for p in probes if not words or p.name in words or p.fault_id in words]


def _run_one(probe: Probe, root: Path) -> tuple[Probe, bool, str, float]:
    folder = root / probe.name
    folder.mkdir()
    started = time.monotonic()
    try:
        wrong = probe.check(folder)
    except Exception as e:  # a probe that cannot even be run is a failure, not a crash of the round
        wrong = f"the probe raised {type(e).__name__}: {e}"
    return probe, wrong is None, wrong or "holds", time.monotonic() - started


def main(argv: list[str]) -> int:
    listing, quick = "--list" in argv, "--quick" in argv
    words = [w for w in argv if w not in ("--list", "--quick")]
    chosen = [p for p in select(all_probes(), words) if not (quick and p.trains)]
    if listing:
        print("\n".join(p.name for p in chosen))
        return 0
    import probe_fixtures

    started = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="sigmarl-probe-") as tmp:
        probe_fixtures.ROOT = Path(tmp) / "fixtures"
        failed = 0
        # two at a time: each probe is mostly one process on one thread
        with ThreadPoolExecutor(max_workers=2) as pool:
            for probe, ok, said, seconds in pool.map(lambda p: _run_one(p, Path(tmp)), chosen):
                failed += not ok
                print(f"{'PASS' if ok else 'FAIL'}  {probe.name:26} {seconds:5.1f} s  {probe.fault}: {said}",
                      flush=True)
    print(f"{len(chosen) - failed} of {len(chosen)} probes passed in {time.monotonic() - started:.0f} s")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
