"""Two-level variance components of a cell (one variant, one scenario, one metric).

The model: value of simulation j of seed i = mu + a_i + e_ij, with seed effects a_i of
variance sigma_seed^2 and simulation noise e_ij of variance sigma_sim^2. The one-way
random-effects ANOVA (method of moments) estimates them from the mean squares within and
between seeds:

    MSW = sum_ij (x_ij - xbar_i)^2 / (N - k)
    MSB = sum_i n_i (xbar_i - xbar)^2 / (k - 1)
    sigma_sim^2  = MSW
    sigma_seed^2 = max(0, (MSB - MSW) / n0),  n0 = (N - sum_i n_i^2 / N) / (k - 1)

(n0 is the simulations per seed in a balanced design). A seed's mean over n simulations
then has variance sigma_seed^2 + sigma_sim^2 / n: this, not a pooled per-simulation
variance, is what the power analysis of seed means needs.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Components:
    n_seeds: int
    n_sims: float  # simulations per seed (their mean when unbalanced)
    sigma2_seed: float
    sigma2_sim: float

    def seed_mean_variance(self, n_sims: float | None = None) -> float:
        """Variance of one seed's mean over n_sims simulations (default: as measured)."""
        n = self.n_sims if n_sims is None else n_sims
        return self.sigma2_seed + self.sigma2_sim / n

    @property
    def seed_share(self) -> float:
        """Fraction of a seed mean's variance that is seed-to-seed (NaN when it is 0)."""
        total = self.seed_mean_variance()
        return self.sigma2_seed / total if total > 0 else math.nan

    @property
    def spread_ratio(self) -> float:
        """sigma_seed^2 / (sigma_sim^2 / n_sims): how many times the seeds' spread exceeds the
        spread the simulations of one seed leave in its mean (inf when that is 0)."""
        sim = self.sigma2_sim / self.n_sims
        if sim == 0:
            return math.inf if self.sigma2_seed > 0 else math.nan
        return self.sigma2_seed / sim


def components(groups: Sequence[np.ndarray]) -> Components:
    """Variance components from each seed's 1-D array of finite values (seeds with none
    skipped). With one seed sigma_seed^2 is NaN; with one simulation per seed sigma_sim^2 is."""
    groups = [np.asarray(g, float)[np.isfinite(g)] for g in groups]
    groups = [g for g in groups if len(g)]
    k = len(groups)
    sizes = np.array([len(g) for g in groups], float)
    total = sizes.sum()
    means = np.array([g.mean() for g in groups])
    grand = float(np.dot(sizes, means) / total)
    ssw = float(sum(((g - m) ** 2).sum() for g, m in zip(groups, means, strict=True)))
    msw = ssw / (total - k) if total > k else math.nan
    if k < 2:
        return Components(k, float(sizes.mean()), math.nan, msw)
    msb = float(np.dot(sizes, (means - grand) ** 2)) / (k - 1)
    n0 = (total - (sizes**2).sum() / total) / (k - 1)
    within = 0.0 if math.isnan(msw) else msw
    return Components(k, float(sizes.mean()), max(0.0, (msb - within) / n0), msw)
