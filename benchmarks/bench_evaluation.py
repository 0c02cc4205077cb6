"""Evaluation speed: this tree against a baseline tree, in one run, with ratios.

Times what `sigmarl evaluate` does per scenario (build the environment, roll out 32
simulations x 1200 steps) for one checkpoint, on the paper's four scenarios and on the
whole CPM map with 30 and 45 agents (the dense scenarios of the generalisation matrix).
Each (tree, repeat) is a fresh subprocess with one thread; the trees take turns, so load
from other processes hits both alike, and each scenario keeps its best wall and CPU time.

Projections from the best times:
- a scenario's time: its set-up (measured with a one-step evaluation) plus the rollout
  scaled to 1200 steps;
- `sigmarl evaluate` of one model-seed: the four paper scenarios' sum;
- the generalisation matrix (18 model-seeds x 14 scenarios, two processes of one thread):
  18 x (12 maps x the paper test maps' mean + CPM-30 + CPM-45) / 2. The twelve maps carry
  6-10 agents, as the paper's test maps (6-8) do; their own times replace this estimate
  once they are scenarios;
- the floor: the CPU time of the policy's forward passes alone (the rows stay bit for bit
  only with the same network on the same batch shapes, so no evaluation goes below it).

Run: python benchmarks/bench_evaluation.py [--baseline-rev REV | --baseline-src PATH]
     [--checkpoint FILE] [--steps N] [--repeats R] [--no-dense]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PAPER = [("CPM", 15), ("Intersection", 6), ("On-Ramp", 8), ("Roundabout", 8)]
DENSE = [("CPM", 30), ("CPM", 45)]
BASELINE_REV = "a917b62"  # main before the evaluation-speed work

# Runs in the subprocess, against whichever tree is first on its PYTHONPATH; uses only
# what both trees offer (load_policy, config_of, evaluate_policy).
CHILD = r"""
import json, sys, time
import torch
torch.set_num_threads(1)
from pathlib import Path
from sigmarl.evaluation.rollout import evaluate_policy
from sigmarl.training import checkpoint as ckpt
from sigmarl.training.loop import load_policy
path, steps, sims, cases = Path(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3]), json.loads(sys.argv[4])
out = {}
def timed(scenario, n_agents, n_steps):
    t, c = time.perf_counter(), time.process_time()
    actor, state = load_policy(path, n_agents=n_agents)
    rows = evaluate_policy(actor, ckpt.config_of(state, path), scenario, n_sims=sims, steps=n_steps,
                           n_agents=n_agents, progress=False)
    return time.perf_counter() - t, time.process_time() - c, float(rows["CR_total"].mean())
for scenario, n_agents in cases:
    # set-up (map, route tables, policy) and one step, then the rollout: projections scale
    # only the rollout to 1200 steps
    setup_wall, setup_cpu, _ = timed(scenario, n_agents, 1)
    wall, cpu, cr = timed(scenario, n_agents, steps)
    out[f"{scenario}-{n_agents}"] = [setup_wall, max(wall - setup_wall, 0.0), setup_cpu, max(cpu - setup_cpu, 0.0), cr]
print(json.dumps(out))
"""


def cpu_name() -> str:
    try:
        for line in subprocess.run(["lscpu"], capture_output=True, text=True).stdout.splitlines():
            if line.startswith("Model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def baseline_tree(rev: str, into: Path) -> Path:
    """`git archive` of the baseline revision's src/ (and conf/, which src/sigmarl/conf links to)
    into a temporary folder."""
    archive = into / "baseline.tar"
    subprocess.run(["git", "-C", str(ROOT), "archive", "-o", str(archive), rev, "src", "conf"], check=True)
    with tarfile.open(archive) as tar:
        tar.extractall(into, filter="data")
    return into / "src"


def run_tree(src: Path, args, cases) -> dict[str, list[float]]:
    env = {**os.environ, "PYTHONPATH": str(src), "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    res = subprocess.run([sys.executable, "-c", CHILD, str(args.checkpoint), str(args.steps), str(args.sims),
                          json.dumps(cases)], env=env, cwd=ROOT, capture_output=True, text=True)
    if res.returncode != 0:
        sys.exit(f"benchmark child failed on {src}:\n{res.stderr[-3000:]}")
    return json.loads(res.stdout.strip().splitlines()[-1])


def policy_floor(checkpoint: Path, cases, steps: int, sims: int, repeats: int) -> dict[str, float]:
    """CPU seconds of the actor's forward passes alone over a 1200-step evaluation, per
    scenario: what any evaluation that keeps the rows bit for bit (same network, same batch
    shapes) spends at least."""
    import torch

    from sigmarl.training.loop import load_policy
    from sigmarl.training.networks import PolicyHead

    torch.set_num_threads(1)
    out = {}
    for scenario, n_agents in cases:
        actor, state = load_policy(checkpoint, n_agents=n_agents)
        act = PolicyHead(actor).deterministic_action
        obs = torch.randn(sims, n_agents, state["dims"]["obs_dim"])
        best = float("inf")
        with torch.inference_mode():
            for _ in range(repeats):
                c = time.process_time()
                for _ in range(steps):
                    act(obs)
                best = min(best, time.process_time() - c)
        out[f"{scenario}-{n_agents}"] = best * 1200 / steps
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--baseline-rev", default=BASELINE_REV, help="git revision to compare with")
    p.add_argument("--baseline-src", type=Path, help="a src/ folder to compare with instead of a revision")
    p.add_argument("--checkpoint", type=Path, default=ROOT / "results/paper-budget/M0/seed0/best.pt")
    p.add_argument("--steps", type=int, default=1200)
    p.add_argument("--sims", type=int, default=32)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--no-dense", action="store_true", help="leave out CPM with 30 and 45 agents")
    args = p.parse_args()
    cases = PAPER + ([] if args.no_dense else DENSE)
    with tempfile.TemporaryDirectory() as tmp:
        base = args.baseline_src or baseline_tree(args.baseline_rev, Path(tmp))
        trees = {"baseline": base, "current": ROOT / "src"}
        best: dict[str, dict[str, list[float]]] = {name: {} for name in trees}
        for r in range(args.repeats):
            for name, src in trees.items():
                for key, values in run_tree(src, args, cases).items():
                    old = best[name].get(key, [float("inf")] * 4)
                    best[name][key] = [min(a, b) for a, b in zip(old[:4], values[:4], strict=True)] + [values[4]]
            print(f"repeat {r + 1}/{args.repeats} done", file=sys.stderr)

    scale = 1200 / args.steps

    def full(times: list[float], k: int) -> float:
        """Seconds of a 1200-step evaluation: set-up plus the rollout scaled to 1200 steps
        (k = 0: wall clock, k = 2: CPU time)."""
        return times[k] + times[k + 1] * scale

    print(f"CPU: {cpu_name()}; 1 thread per process; {args.sims} simulations x {args.steps} steps, "
          f"projected to 1200; best of {args.repeats}; baseline {args.baseline_src or args.baseline_rev}")
    print(f"checkpoint {args.checkpoint}")
    print(f"{'scenario':<16}{'base setup':>11}{'cur setup':>10}{'base wall':>10}{'cur wall':>9}{'ratio':>7}"
          f"{'base cpu':>10}{'cur cpu':>9}{'ratio':>7}  same CR_total")
    for key in best["current"]:
        b, c = best["baseline"][key], best["current"][key]
        bw, cw, bc, cc = full(b, 0), full(c, 0), full(b, 2), full(c, 2)
        print(f"{key:<16}{b[0]:>11.2f}{c[0]:>10.2f}{bw:>10.1f}{cw:>9.1f}{bw / cw:>7.2f}"
              f"{bc:>10.1f}{cc:>9.1f}{bc / cc:>7.2f}  {b[4] == c[4]}")

    def projections(times: dict[str, list[float]], k: int) -> tuple[float, float | None]:
        evaluate = sum(full(times[f"{s}-{n}"], k) for s, n in PAPER)
        if args.no_dense:
            return evaluate, None
        small = sum(full(times[f"{s}-{n}"], k) for s, n in PAPER[1:]) / 3
        per_model = 12 * small + full(times["CPM-30"], k) + full(times["CPM-45"], k)
        return evaluate, 18 * per_model / 2

    floor = policy_floor(args.checkpoint, cases, min(args.steps, 300), args.sims, args.repeats)
    print("[cpu] the policy's forward passes alone, 1200 steps: "
          + ", ".join(f"{key} {sec:.1f} s" for key, sec in floor.items())
          + f"; the four paper scenarios {sum(floor[f'{s}-{n}'] for s, n in PAPER):.1f} s")
    for k, what in ((0, "wall"), (2, "cpu")):
        (be, bm), (ce, cm) = projections(best["baseline"], k), projections(best["current"], k)
        print(f"[{what}] sigmarl evaluate, 4 paper scenarios: baseline {be:.1f} s, current {ce:.1f} s, "
              f"{be / ce:.2f}x (target <= 10 s)")
        if bm is not None:
            print(f"[{what}] generalisation matrix on 2 processes (projected): baseline {bm / 60:.1f} min, "
                  f"current {cm / 60:.1f} min, {bm / cm:.2f}x (target <= 30 min)")


if __name__ == "__main__":
    main()
