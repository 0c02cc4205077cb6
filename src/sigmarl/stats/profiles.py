"""Performance profiles and seed-bootstrap bands, as rliable draws them.

A performance profile of a model is the fraction of its simulations whose CR_total exceeds
tau, for every tau (lower curves are better). Each seed weighs equally: the profile is the
mean over seeds of each seed's fraction, and over scenarios the mean of the scenarios'
profiles. Its band is the percentile interval of the same profile over two-level bootstrap
replicates (seeds, then simulations; `bootstrap.resample`), drawn independently per
scenario (stratified).

The training curves' band: per iteration, the percentile interval of the mean over seeds
when the seeds are drawn with replacement.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence

import numpy as np

from sigmarl.stats import bootstrap as bs


def exceedance(values: np.ndarray, valid: np.ndarray, taus: np.ndarray) -> np.ndarray:
    """[..., T]: per seed slot, the fraction of its valid values above each tau, averaged over
    the seed axis (-2) with seeds weighing equally; values/valid are [..., S, n]."""
    above = (values[..., None] > taus) & valid[..., None]  # [..., S, n, T]
    counts = valid.sum(-1)[..., None]  # [..., S, 1]
    with np.errstate(invalid="ignore", divide="ignore"):
        per_seed = above.sum(-2) / counts  # [..., S, T]
    return np.nanmean(np.where(counts > 0, per_seed, np.nan), axis=-2)


def profile(groups: Sequence[np.ndarray], taus: np.ndarray) -> np.ndarray:
    """[T]: the fraction of simulations above each tau (seeds weigh equally); groups are each
    seed's 1-D finite values."""
    values, lengths = bs.padded([np.asarray(g, float)[:, None] for g in groups])
    valid = np.arange(values.shape[1]) < lengths[:, None]
    return exceedance(values[..., 0], valid, taus)


def profile_replicates(groups: Sequence[np.ndarray], taus: np.ndarray, n_boot: int,
                       rng: np.random.Generator) -> np.ndarray:
    """[B, T]: the profile over two-level bootstrap replicates of the seeds' simulations."""
    draws, valid = bs.resample([np.asarray(g, float)[:, None] for g in groups], n_boot, rng)
    return exceedance(draws[..., 0], valid, taus)


def scenario_profiles(per_scenario: dict[str, Sequence[np.ndarray]], taus: np.ndarray, n_boot: int,
                      name: str, level: float = bs.LEVEL) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The mean over scenarios of their profiles, with its stratified-bootstrap band (lo, hi)."""
    points, reps = [], []
    for scenario, groups in per_scenario.items():
        points.append(profile(groups, taus))
        reps.append(profile_replicates(groups, taus, n_boot, bs.rng_for("profile", name, scenario)))
    lo, hi = bs.percentile_interval(np.mean(reps, axis=0), level)
    return np.mean(points, axis=0), lo, hi


def seed_band(per_seed: np.ndarray, n_boot: int, rng: np.random.Generator, level: float = bs.LEVEL
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per row of per_seed [I, S] (NaN where a seed lacks the row): the mean over the seeds
    and the percentile interval of that mean over resampled seeds."""
    per_seed = np.asarray(per_seed, float)
    pick = rng.integers(0, per_seed.shape[1], (n_boot, per_seed.shape[1]))
    with warnings.catch_warnings(), np.errstate(invalid="ignore"):
        warnings.simplefilter("ignore", RuntimeWarning)  # a replicate that drew only NaN seeds
        means = np.nanmean(per_seed[:, pick], axis=-1).T  # [B, I]
        lo, hi = bs.percentile_interval(means, level)
        return np.nanmean(per_seed, axis=1), lo, hi
