"""How fast the commands that have little or nothing to do answer, in two source trees.

Each command runs as a fresh process (the way a user meets it), with one tree's `src` first on
PYTHONPATH, the two trees interleaved (and their order alternating) so that both see the same
machine load; the table gives each tree's median wall time and the ratio baseline / current.

- `sigmarl --help`
- a bad override (`sigmarl train ppo.epoch=3`)
- a missing checkpoint (`sigmarl evaluate nonexistent.pt`)
- `sigmarl report` in an empty folder (a fresh folder every run; whether it leaves `mlflow.db`
  behind is shown too)
- re-running a finished sweep (one tiny sweep is run first with the current tree; both trees
  then re-run it in that folder, with the same explicit experiment name)

Run: python benchmarks/bench_startup.py --baseline-rev a917b62 [--repeats 3]
     python benchmarks/bench_startup.py --baseline-src /path/to/old/src
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ENTRY = "import sys; from sigmarl.cli import main; sys.exit(main(sys.argv[1:]))"
SWEEP = ["models=[M0]", "ppo=smoke", "ppo.iterations=1", "eval.n_sims=1", "eval.steps=5",
         "eval.scenarios=[Intersection]", "hydra/launcher=basic", "tracking.experiment=bench-startup"]


def cpu_name() -> str:
    try:
        out = subprocess.run(["lscpu"], capture_output=True, text=True).stdout
        return next(line.split(":", 1)[1].strip() for line in out.splitlines() if line.startswith("Model name"))
    except (OSError, StopIteration):
        return platform.processor() or "unknown CPU"


def baseline_from_rev(rev: str, into: Path) -> Path:
    """The tree of `rev` (src and conf) unpacked into `into`; its src folder."""
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", rev, "src", "conf"], capture_output=True,
                             check=True).stdout
    subprocess.run(["tar", "-x", "-C", str(into)], input=archive, check=True)
    return into / "src"


def run(src: Path, args: list[str], cwd: Path) -> tuple[float, int]:
    env = dict(os.environ, PYTHONPATH=str(src))
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", ENTRY, *args], cwd=cwd, env=env,
                          stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - t0, proc.returncode


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    given = p.add_mutually_exclusive_group(required=True)
    given.add_argument("--baseline-src", type=Path, help="a source tree's src folder (with its conf beside)")
    given.add_argument("--baseline-rev", help="a git revision of this repository (unpacked into a temp folder)")
    p.add_argument("--current-src", type=Path, default=ROOT / "src")
    p.add_argument("--repeats", type=int, default=3)
    args = p.parse_args()

    with tempfile.TemporaryDirectory(prefix="bench-startup-") as tmp:
        tmp = Path(tmp)
        if args.baseline_rev:
            (tmp / "baseline").mkdir()
            baseline = baseline_from_rev(args.baseline_rev, tmp / "baseline")
        else:
            baseline = args.baseline_src.resolve()
        trees = {"baseline": baseline, "current": args.current_src.resolve()}
        swept = tmp / "swept"
        swept.mkdir()
        _, rc = run(trees["current"], ["sweep", *SWEEP], swept)
        if rc:
            sys.exit(f"the tiny sweep failed (exit {rc}) in {swept}")

        commands = {
            "sigmarl --help": (["--help"], None),
            "bad override (ppo.epoch=3)": (["train", "ppo.epoch=3"], None),
            "missing checkpoint": (["evaluate", "nonexistent.pt"], None),
            "report in an empty folder": (["report"], "empty"),
            "re-run a finished sweep": (["sweep", *SWEEP], swept),
        }
        times: dict[tuple[str, str], list[float]] = {}
        codes: dict[tuple[str, str], set[int]] = {}
        left_store: dict[str, bool] = {}
        for k in range(args.repeats):
            for name, (argv, where) in commands.items():
                order = list(trees) if k % 2 == 0 else list(reversed(trees))
                for tree in order:
                    cwd = where if isinstance(where, Path) else Path(tempfile.mkdtemp(dir=tmp))
                    seconds, rc = run(trees[tree], argv, cwd)
                    times.setdefault((name, tree), []).append(seconds)
                    codes.setdefault((name, tree), set()).add(rc)
                    if where == "empty":
                        left_store[tree] = (cwd / "mlflow.db").exists()

    print(f"startup, {args.repeats} interleaved runs each, median wall time; CPU: {cpu_name()}, "
          f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} at the end")
    print(f"baseline: {trees['baseline']}\ncurrent:  {trees['current']}\n")
    print("| command | baseline (s) | current (s) | baseline / current | exit codes |")
    print("|---|---:|---:|---:|---|")
    for name in commands:
        b, c = (statistics.median(times[(name, t)]) for t in trees)
        exits = " / ".join(",".join(map(str, sorted(codes[(name, t)]))) for t in trees)
        print(f"| {name} | {b:.2f} | {c:.2f} | {b / c:.1f} | {exits} |")
    print("\n`sigmarl report` in an empty folder left mlflow.db behind: "
          + ", ".join(f"{t} {'yes' if v else 'no'}" for t, v in left_store.items()))


if __name__ == "__main__":
    main()
