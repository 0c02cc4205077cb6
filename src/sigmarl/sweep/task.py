"""What Hydra's launcher runs for each job of a sweep, imported by the sweep's own process.

The launcher pickles this function by name and each job's process calls it. `sigmarl.sweep.job`
imports torch, torchrl and the environment (4.5 s here, `python -X importtime`), which the
sweep's own process never needs: it only plans, hands the jobs over and summarises.
"""

from __future__ import annotations


def run_job(cfg):
    """`sigmarl.sweep.job.run_job`, imported in the job's process (lazy: see the module's note)."""
    from sigmarl.sweep.job import run_job as run

    return run(cfg)
