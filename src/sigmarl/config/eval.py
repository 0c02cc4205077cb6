"""The evaluation protocol (`eval.*`)."""

from __future__ import annotations

from dataclasses import dataclass, field

from sigmarl.ablation import PAPER_SCENARIOS
from sigmarl.config.ranges import SEED_MAX, ranged


@dataclass
class EvalConfig:
    """Evaluation protocol: every model faces the same scenarios, simulations and seed."""

    scenarios: list[str] = field(default_factory=lambda: list(PAPER_SCENARIOS))
    """Scenario names (conf/scenario/<name>.yaml); conf/config.yaml takes the study's."""
    n_sims: int = ranged(32, lo=1, hi=2**16, size=True)
    """Simulations per scenario."""
    steps: int = ranged(1200, lo=1, hi=10**6, size=True)
    """Steps per simulation."""
    seed: int = ranged(2024, lo=0, hi=SEED_MAX)
    """Seed of every evaluation, so every model faces the same initial states."""
    checkpoint: str = ranged("best", choices=("best", "final"))
    """Which checkpoint is evaluated: best (the paper's choice) | final."""
