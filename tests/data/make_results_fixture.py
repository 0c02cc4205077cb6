"""Regenerate tests/data/results/: a real, tiny results folder for the report's tests.

Two models (M0, M4) x two seeds, each trained at the smoke budget (ppo=smoke, tracking off)
and evaluated on the four scenarios with 3 simulations x 40 steps. Per run it keeps what
`sigmarl report --from` reads: config.yaml, metrics.csv (the training history, one row per
iteration) and evaluation_rows.csv. The checkpoints (best.pt, final.pt; ~300 kB each) are left
out to keep the fixture a few kB; the report does not read them.

    PYTHONPATH=src python tests/data/make_results_fixture.py
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

import pandas as pd
from omegaconf import OmegaConf

from sigmarl.compose import compose_config
from sigmarl.evaluation.protocol import evaluate_checkpoint
from sigmarl.training import train

OUT = Path(__file__).parent / "results"
RUNS = [("M0", "full"), ("M4", "no_distance_to_boundaries")]
SEEDS = [0, 1]
EVAL = ["eval.n_sims=3", "eval.steps=40"]


def main() -> None:
    shutil.rmtree(OUT, ignore_errors=True)
    with tempfile.TemporaryDirectory() as tmp:
        for label, preset in RUNS:
            for seed in SEEDS:
                run_dir = Path(tmp) / label / f"seed{seed}"
                cfg = compose_config([f"obs={preset}", f"seed={seed}", "ppo=smoke", "tracking.enabled=false",
                                      f"run_dir={run_dir}", *EVAL])
                result = train(cfg)
                rows, _ = evaluate_checkpoint(run_dir / "best.pt", cfg.eval, progress=False)
                out = OUT / label / f"seed{seed}"
                out.mkdir(parents=True)
                saved = OmegaConf.load(run_dir / "config.yaml")
                saved.run_dir = f"tests/data/results/{label}/seed{seed}"  # not the temporary folder
                OmegaConf.save(saved, out / "config.yaml")
                metrics = pd.DataFrame(result.history)
                metrics.insert(0, "iteration", range(1, len(metrics) + 1))
                # wall-clock columns would make the fixture differ on every regeneration
                metrics = metrics.drop(columns=[c for c in metrics if c.startswith("time_") or c == "frames_per_s"])
                metrics.to_csv(out / "metrics.csv", index=False, float_format="%.6g")
                rows.to_csv(out / "evaluation_rows.csv", index=False, float_format="%.6g")
                print(out, cfg.obs.preset, len(rows), "rows")


if __name__ == "__main__":
    main()
