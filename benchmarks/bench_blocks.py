"""Seed blocks against one seed: the per-seed time of a training iteration, in one process.

A block of S seeds (`sigmarl train seeds=[...]`, `training.learner.Learner`) trains S seeds of
one config as one batched computation; one seed (`sigmarl train seed=0`) is a block of one, the
baseline ("one seed"; the JSON keys `lone_*`). Both are built here, in this process, at the
paper's settings (32 envs x 128 steps per seed, 8 minibatches of 512, the paper's network), and
timed iteration by iteration through their own `iterate()`, the code `sigmarl train` runs. Each
block size is measured beside iterations of one seed (one, block, one, block, ...), so load from
other processes hits both alike; the ratio per seed is (block seconds / S) / (one seed's
seconds): 1.00 means a block seed costs what a seed alone costs, 0.25 a quarter of it.

To keep the run short the optimisation runs `--epochs` epochs (default 3) and is scaled to the
configured ppo.epochs (60): iteration = collection + GAE + optimisation x 60 / epochs, each
phase as `iterate()` times it. On a CPU the clock is the process's CPU time with one thread
(robust when other processes share the cores; split into phases in the proportions of their
wall times); on cuda it is wall time, synchronised. One warm-up iteration (one epoch) per
learner is excluded.

    python benchmarks/bench_blocks.py [--device cpu|cuda] [--sizes 1 2 4 8] [--iterations 2]
        [--epochs 3] [--time-limit SECONDS] [--json out.json] [overrides...]

Defaults: S = 1 2 4 8 on cpu, 1 8 64 256 on cuda (eager; CUDA graphs are not built). On cuda it
also prints the peak memory; everywhere, model-seeds per hour at the paper's budget (250
iterations of this iteration time).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import time
from dataclasses import replace
from datetime import UTC, datetime
from pathlib import Path

import torch

from sigmarl.compose import compose_config
from sigmarl.config import PPOConfig
from sigmarl.training.learner import Learner
from sigmarl.training.loop import learning_rate

PAPER_ITERATIONS = PPOConfig().iterations  # the budget model-seeds per hour are counted at
SIZES = {"cpu": [1, 2, 4, 8], "cuda": [1, 8, 64, 256]}


def cpu_name() -> str:
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def device_name(device: torch.device) -> str:
    if device.type == "cuda":
        return torch.cuda.get_device_name(device)
    return f"{cpu_name()}, {os.cpu_count()} cores, {torch.get_num_threads()} thread(s)"


class Timer:
    """Seconds of one learner's iterations at the configured epochs (optimisation scaled)."""

    def __init__(self, learner, cfg, epochs: int, device: torch.device):
        self.learner, self.cfg, self.device = learner, cfg, device
        self.scale = cfg.ppo.epochs / epochs
        self.run_cfg = replace(cfg, ppo=replace(cfg.ppo, epochs=epochs))
        self.it = 0
        self.seconds: list[float] = []
        self.phases: list[dict[str, float]] = []
        self._iterate(replace(cfg, ppo=replace(cfg.ppo, epochs=1)))  # warm-up, not counted

    def _sync(self) -> None:
        if self.device.type == "cuda":
            torch.cuda.synchronize(self.device)

    def _iterate(self, cfg) -> tuple[float, float, dict[str, float]]:
        learner = self.learner
        learner.cfg = cfg  # iterate() reads the epochs from its config
        learner.reseed(self.it)
        learner.set_lr(learning_rate(cfg.ppo, self.it))
        self._sync()
        w, c = time.perf_counter(), time.process_time()
        _, phases = learner.iterate()
        self._sync()
        self.it += 1
        return time.perf_counter() - w, time.process_time() - c, phases

    def measure(self) -> float:
        """One iteration; its seconds at the configured epochs (the clock: see the module)."""
        wall, cpu, ph = self._iterate(self.run_cfg)
        scaled = ph["collect"] + ph["advantage"] + ph["optimise"] * self.scale
        seconds = scaled * wall / ph["total"] if self.device.type == "cuda" else cpu * scaled / ph["total"]
        share = seconds / scaled
        self.phases.append({k: v * share * (self.scale if k == "optimise" else 1.0) for k, v in ph.items()
                            if k != "total"})
        self.seconds.append(seconds)
        return seconds

    def median(self) -> float:
        return statistics.median(self.seconds)


def measure_size(base, lone: Timer, size: int, args, device: torch.device) -> dict:
    """Iterations of a block of `size` seeds, each beside one iteration of one seed."""
    if device.type == "cuda":
        torch.cuda.empty_cache()
        torch.cuda.reset_peak_memory_stats(device)
    learner = Learner(base, list(range(size)), device)
    try:
        block = Timer(learner, base, args.epochs, device)
        alone = []
        for _ in range(args.iterations):
            alone.append(lone.measure())
            block.measure()
    finally:
        learner.close()
    per_iter = block.median()
    lone_s = statistics.median(alone)
    row = {"S": size, "s_per_iteration": per_iter, "s_per_seed_iteration": per_iter / size,
           "lone_s_per_iteration": lone_s, "ratio_per_seed": per_iter / size / lone_s,
           "model_seeds_per_hour": size * 3600 / (PAPER_ITERATIONS * per_iter),
           "phases": {k: statistics.median(p[k] for p in block.phases) for k in block.phases[0]}}
    if device.type == "cuda":
        row["peak_memory_gib"] = torch.cuda.max_memory_allocated(device) / 2**30
    return row


def table(result: dict) -> str:
    """The results as a markdown table: each block size against the iterations of one seed
    measured beside it; the "one seed" row is the median of all of them (1.00 by definition)."""
    cuda = result["device_type"] == "cuda"
    head = ["S", "s per iteration", "s per seed-iteration", "one seed beside it, s", "per seed vs one",
            "model-seeds per hour"] + (["peak memory (GiB)"] if cuda else [])
    lines = ["| " + " | ".join(head) + " |", "|" + "---:|" * len(head)]
    lone = result.get("lone_s_per_iteration")
    if lone:
        cells = ["one seed", f"{lone:.2f}", f"{lone:.2f}", f"{lone:.2f}", "1.00",
                 f"{3600 / (result['paper_iterations'] * lone):.2f}"]
        lines.append("| " + " | ".join(cells + ([f"{result['lone_peak_memory_gib']:.2f}"] if cuda else [])) + " |")
    for row in result["rows"]:
        if "skipped" in row:
            lines.append(f"| {row['S']} | {row['skipped']} |" + " |" * (len(head) - 2))
            continue
        cells = [str(row["S"]), f"{row['s_per_iteration']:.2f}", f"{row['s_per_seed_iteration']:.3f}",
                 f"{row['lone_s_per_iteration']:.2f}", f"{row['ratio_per_seed']:.2f}",
                 f"{row['model_seeds_per_hour']:.2f}"]
        if cuda:
            cells.append(f"{row['peak_memory_gib']:.2f}")
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _estimate(rows: list[dict], size: int, iterations: int) -> float:
    """Seconds a block of `size` should take here (warm-up, its iterations and the lone ones
    beside them), from the largest block measured so far; linear in S, an upper bound while
    the device is not busy."""
    done = [r for r in rows if "s_per_iteration" in r]
    if not done:
        return 0.0
    last = done[-1]
    per_iter = last["s_per_iteration"] * max(1.0, size / last["S"])
    return per_iter * (1 + iterations) + last["lone_s_per_iteration"] * iterations


def run(args) -> dict:
    device = torch.device(args.device)
    cfg = compose_config(["tracking.enabled=false", f"device={args.device}", "threads=1", *args.overrides])
    torch.set_num_threads(cfg.threads)
    ppo = cfg.ppo
    args.epochs = max(1, min(args.epochs, ppo.epochs))
    result = {"date": datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC"), "device_type": device.type,
              "device": device_name(device), "torch": torch.__version__, "load_average": os.getloadavg()[0],
              "settings": f"{ppo.num_envs} envs x {ppo.frames_per_iteration // ppo.num_envs} steps per seed, "
                          f"{ppo.epochs} epochs (measured over {args.epochs}, scaled) x "
                          f"{ppo.frames_per_iteration // ppo.minibatch_size} minibatches of {ppo.minibatch_size}, "
                          f"network {list(cfg.network.hidden)}, precision {ppo.precision}",
              "paper_iterations": PAPER_ITERATIONS, "iterations": args.iterations, "cuda_graphs": "not built",
              "rows": []}
    print(f"{result['device']}; torch {torch.__version__}; load average {result['load_average']:.2f} at start")
    print(f"settings: {result['settings']}; {args.iterations} measured iteration(s) per size, warm-up excluded")
    print("cuda graphs: not built (eager)" if device.type == "cuda" else "clock: CPU time, one thread", flush=True)
    start = time.perf_counter()
    if device.type == "cuda":
        torch.cuda.reset_peak_memory_stats(device)
    lone = Timer(Learner(cfg, [cfg.seed], device), cfg, args.epochs, device)  # one seed
    lone.measure()
    if device.type == "cuda":
        result["lone_peak_memory_gib"] = torch.cuda.max_memory_allocated(device) / 2**30
    for size in args.sizes:
        left = args.time_limit - (time.perf_counter() - start) if args.time_limit else None
        if left is not None and _estimate(result["rows"], size, args.iterations) > left:
            result["rows"].append({"S": size, "skipped": f"skipped: over the time limit ({args.time_limit:g} s)"})
        else:
            try:
                result["rows"].append(measure_size(cfg, lone, size, args, device))
            except torch.cuda.OutOfMemoryError:
                result["rows"].append({"S": size, "skipped": "out of memory"})
        result["lone_s_per_iteration"] = lone.median()
        _report_row(result["rows"][-1])
        if args.json:
            Path(args.json).write_text(json.dumps(result, indent=1) + "\n", encoding="utf-8")
    lone.learner.close()
    return result


def _report_row(row: dict) -> None:
    if "skipped" in row:
        print(f"S={row['S']}: {row['skipped']}", flush=True)
        return
    ph = ", ".join(f"{k} {v:.2f}" for k, v in row["phases"].items())
    print(f"S={row['S']}: {row['s_per_iteration']:.2f} s per iteration ({ph}); "
          f"{row['s_per_seed_iteration']:.3f} s per seed-iteration; lone {row['lone_s_per_iteration']:.2f} s; "
          f"per seed x{row['ratio_per_seed']:.2f}", flush=True)


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--device", default="cpu", help="cpu or cuda (default cpu)")
    p.add_argument("--sizes", type=int, nargs="+", help="block sizes S (default: 1 2 4 8 on cpu, "
                   "1 8 64 256 on cuda)")
    p.add_argument("--iterations", type=int, default=2, help="measured iterations per size (median)")
    p.add_argument("--epochs", type=int, default=3, help="epochs actually run (scaled to ppo.epochs)")
    p.add_argument("--time-limit", type=float, default=0.0,
                   help="seconds: skip a block size that would end past it (0: none)")
    p.add_argument("--json", help="also write the results to this JSON file (after every size)")
    p.add_argument("overrides", nargs="*", default=[], help="Hydra overrides (default: the paper's settings)")
    args = p.parse_args(argv)
    if torch.device(args.device).type == "cuda" and not torch.cuda.is_available():
        sys.exit("bench_blocks: --device cuda but no CUDA GPU is available")
    args.sizes = args.sizes or SIZES[torch.device(args.device).type]
    result = run(args)
    print()
    print(table(result))


if __name__ == "__main__":
    main()
