"""Study-level benchmarks.

1. Parallel efficiency: six smoke-budget sweep jobs on the joblib launcher with
   one job per core, against the sum of the same jobs run one at a time (each as
   its own one-job sweep, so both sides pay the same process start-up).
   Target: parallel wall time <= 1.2 x (sum of single-job times) / cores.
2. Evaluation speed: 32 simulations x 1200 steps, 15 agents, CPM map, one thread.

Run: python benchmarks/bench_study.py [--skip-parallel] [--skip-eval] [--eval-steps N]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import torch

from sigmarl.ablation import MODELS

SMOKE = ["study=quick", "ppo=smoke", "eval.n_sims=2", "eval.steps=30"]


def _sweep(workdir: Path, extra: list[str]) -> float:
    cmd = [sys.executable, "-m", "sigmarl.cli", "sweep", *SMOKE,
           f"tracking.tracking_uri=sqlite:///{workdir}/mlflow.db", *extra]
    t0 = time.perf_counter()
    subprocess.run(cmd, cwd=workdir, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - t0


def parallel_efficiency(cores: int) -> None:
    print(f"== parallel efficiency: 6 smoke jobs, joblib launcher, {cores} cores ==")
    singles = []
    for model in MODELS:
        with tempfile.TemporaryDirectory() as tmp:
            t = _sweep(Path(tmp), [f"models=[{model}]", "threads=1"])
        singles.append(t)
        print(f"  {model} alone: {t:6.1f} s")
    with tempfile.TemporaryDirectory() as tmp:
        wall = _sweep(Path(tmp), [f"hydra.launcher.n_jobs={cores}", "threads=1"])
    ideal = sum(singles) / cores
    print(f"  sum of single jobs: {sum(singles):.1f} s; ideal on {cores} cores: {ideal:.1f} s")
    print(f"  six jobs in parallel: {wall:.1f} s = {wall / ideal:.2f} x ideal (target <= 1.20)")


def evaluation_speed(steps: int) -> None:
    from sigmarl.compose import compose_config
    from sigmarl.evaluation.rollout import evaluate_policy
    from sigmarl.training.networks import make_actor

    torch.set_num_threads(1)
    cfg = compose_config([])
    # An untrained actor of the paper's shape: the cost does not depend on its weights.
    actor = make_actor(cfg.network, 32, 15, torch.tensor([-0.8, -0.6109]), torch.tensor([0.8, 0.6109]), "cpu")
    print(f"== evaluation speed: 32 simulations x {steps} steps, 15 agents, CPM, 1 thread ==")
    t0 = time.perf_counter()
    evaluate_policy(actor, cfg, "CPM", n_sims=32, steps=steps, progress=False)
    t = time.perf_counter() - t0
    print(f"  {t:.1f} s ({1000 * t / steps:.1f} ms per step of all 32 simulations)")
    if steps != 1200:
        print(f"  projected for 1200 steps: {t * 1200 / steps:.1f} s")


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--skip-parallel", action="store_true")
    p.add_argument("--skip-eval", action="store_true")
    p.add_argument("--eval-steps", type=int, default=1200)
    args = p.parse_args()
    if not args.skip_eval:
        evaluation_speed(args.eval_steps)
    if not args.skip_parallel:
        parallel_efficiency(os.cpu_count() or 1)


if __name__ == "__main__":
    main()
