"""Seed-aware statistics: two-level (seeds, then simulations) bootstrap, probability of
improvement, interquartile mean.

A cell's evaluation rows come from a few trained policies (seeds), each run on the same
simulations. Simulations of one seed share that seed's policy, so pooling them as
independent would understate the uncertainty. Here every estimate weighs the seeds equally
(the mean over seeds of each seed's mean over simulations), and its interval comes from a
two-level bootstrap: each replicate draws the seeds with replacement, then each drawn seed's
simulations with replacement. With one seed it is the ordinary bootstrap of the simulations;
with one value per seed, the bootstrap of the seeds; a single value gives a zero-width interval.
Intervals are percentile intervals of the replicates.

Why not rliable (Agarwal et al. 2021), the field's standard: rliable 1.2.0 resolves to arch
7.2.0, which fails at import with our pandas 3 (`deprecate_kwarg` changed signature), and it
pulls in statsmodels, arch, seaborn and formulaic (~100 MB) for what is a few lines of
numpy; its stratified bootstrap also resamples runs only, not the simulations within them.
scipy.stats.bootstrap resamples flat samples (no nesting), so it does not fit either; the
tests use it as an independent check of the one-seed case.

Every bootstrap draws from its own generator seeded from BOOT_SEED and the cell's name,
so results do not depend on which other cells or models are in the report.
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Sequence

import numpy as np
from scipy import stats

BOOT_SEED = 2024
N_BOOT = 4000
LEVEL = 0.95


def rng_for(*names: object) -> np.random.Generator:
    """A generator that depends only on BOOT_SEED and the names (stable across runs)."""
    return np.random.default_rng([BOOT_SEED, zlib.crc32("|".join(map(str, names)).encode())])


def padded(groups: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Seeds' [n_s, K] arrays stacked into [S, n_max, K] (NaN padding) and their lengths [S]."""
    lengths = np.array([len(g) for g in groups])
    k = groups[0].shape[1]
    out = np.full((len(groups), int(lengths.max()), k), math.nan)
    for s, g in enumerate(groups):
        out[s, : len(g)] = g
    return out, lengths


def seed_means(groups: Sequence[np.ndarray]) -> np.ndarray:
    """[S, K]: each seed's mean over its simulations, NaNs ignored (NaN where none is finite)."""
    values, _ = padded(groups)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.nansum(values, 1) / np.isfinite(values).sum(1)


def point_estimate(groups: Sequence[np.ndarray]) -> np.ndarray:
    """[K]: the mean over seeds of the seeds' means (seeds with no finite value skipped)."""
    means = seed_means(groups)
    finite = np.isfinite(means)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(finite, means, 0.0).sum(0) / finite.sum(0)


def resample(
    groups: Sequence[np.ndarray], n_boot: int, rng: np.random.Generator, pick: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Two-level resample of seeds' [n_s, K] rows: drawn seeds' values and validity.

    Returns values [B, S, n_max, K] and a mask [B, S, n_max] of the draws that exist (a seed
    with fewer simulations than n_max leaves the rest of its row unused). Rows are drawn
    whole, so the K metrics of one simulation stay together. `pick` [B, S] gives the drawn
    seeds instead of drawing them (`whole_seed_groups`: one draw shared by scenarios).
    """
    values, lengths = padded(groups)
    n_seeds, n_max = len(groups), values.shape[1]
    if pick is None:
        pick = rng.integers(0, n_seeds, (n_boot, n_seeds))
    n = lengths[pick]  # [B, S]
    sims = np.floor(rng.random((n_boot, n_seeds, n_max)) * n[..., None]).astype(np.int64)
    return values[pick[..., None], sims], np.arange(n_max) < n[..., None]


def replicate_means(groups: Sequence[np.ndarray], n_boot: int, rng: np.random.Generator,
                    pick: np.ndarray | None = None) -> np.ndarray:
    """[B, S, K]: per replicate, the drawn seeds' means over their drawn simulations."""
    draws, valid = resample(groups, n_boot, rng, pick)
    finite = np.isfinite(draws) & valid[..., None]
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(finite, draws, 0.0).sum(2) / finite.sum(2)


def mean_over_seeds(per_seed: np.ndarray) -> np.ndarray:
    """Mean over axis -2 (seed slots) ignoring NaN seeds; NaN where none is finite."""
    finite = np.isfinite(per_seed)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(finite, per_seed, 0.0).sum(-2) / finite.sum(-2)


def percentile_interval(samples: np.ndarray, level: float = LEVEL) -> tuple[np.ndarray, np.ndarray]:
    """Percentile interval over axis 0, NaN replicates ignored."""
    alpha = (1 - level) / 2
    lo, hi = np.nanquantile(samples, [alpha, 1 - alpha], axis=0)
    return lo, hi


def whole_seed_groups(per_scenario: Sequence[tuple[list, list[np.ndarray]]]) -> tuple[list, list[list]]:
    """One model's (seeds, groups) per scenario aligned on the union of its seeds (ascending).

    Resampling whole seeds keeps a trained policy's scores on every scenario together: its
    scores correlate across scenarios, so drawing each scenario's seeds apart (rliable's
    stratified bootstrap, meant for independent tasks) understates the spread of anything
    pooled over scenarios. A seed a scenario lacks gets an all-NaN group, which the means
    skip. Returns the union and, per scenario, its groups in the union's order.
    """
    union = sorted({s for seeds, _ in per_scenario for s in seeds})
    aligned = []
    for seeds, groups in per_scenario:
        by_seed = dict(zip(seeds, groups, strict=True))
        k = groups[0].shape[1]
        aligned.append([by_seed.get(s, np.full((1, k), math.nan)) for s in union])
    return union, aligned


def whole_seed_replicates(per_scenario: Sequence[tuple[list, list[np.ndarray]]], n_boot: int,
                          pick_rng: np.random.Generator, sims_rng: Sequence[np.random.Generator]) -> list[np.ndarray]:
    """Per scenario, [B, U, K] replicates of the means of one model's U seeds (their union), the
    same seeds drawn in every scenario (`pick_rng`) and each drawn seed's simulations drawn per
    scenario (`sims_rng`, one generator each)."""
    union, aligned = whole_seed_groups(per_scenario)
    pick = pick_rng.integers(0, len(union), (n_boot, len(union)))
    return [replicate_means(groups, n_boot, rng, pick) for groups, rng in zip(aligned, sims_rng, strict=True)]


def expanded_level(level: float, n: int) -> float:
    """The percentile interval's level widened for n resampled units (Hesterberg's expanded
    percentile interval): the bootstrap's spread of a mean is sqrt((n-1)/n) of the true one and
    its tails normal, where Student's t with n-1 degrees of freedom holds; widening the level so
    that its normal quantile matches sqrt(n/(n-1)) t_{n-1} restores the coverage at small n
    (tests/test_whole_seed_coverage.py: 94 % at 10 seeds)."""
    if n < 2:
        return level
    z = math.sqrt(n / (n - 1)) * stats.t.ppf(0.5 + level / 2, n - 1)
    return float(1 - 2 * stats.norm.sf(z))


def probability_of_improvement(x: Sequence[np.ndarray], y: Sequence[np.ndarray]) -> float:
    """P(X < Y) + P(X = Y) / 2, X a simulation of a random seed of x, Y likewise of y.

    Each seed weighs equally, and within a seed each simulation: the Mann-Whitney statistic
    with seed-level weights. Lower is better (collision rates): 1 means x always did better.
    """
    codes_x, codes_y, n_values = _codes(x, y)
    (px, lx), (py, ly) = padded(codes_x), padded(codes_y)
    hx = _histogram(px[None, ..., 0], np.arange(px.shape[1]) < lx[:, None], n_values)
    hy = _histogram(py[None, ..., 0], np.arange(py.shape[1]) < ly[:, None], n_values)
    return float(_compare(hx, hy)[0])


def bootstrap_improvement(
    x: Sequence[np.ndarray], y: Sequence[np.ndarray], n_boot: int, rng: np.random.Generator,
    picks: tuple[np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:
    """[B] probabilities of improvement over independent two-level resamples of x and y
    (`picks`: the seeds drawn for x and for y, as `resample`'s pick)."""
    codes_x, codes_y, n_values = _codes(x, y)
    pick_x, pick_y = picks or (None, None)
    dx, mx = resample(codes_x, n_boot, rng, pick_x)
    dy, my = resample(codes_y, n_boot, rng, pick_y)
    return _compare(_histogram(dx[..., 0], mx, n_values), _histogram(dy[..., 0], my, n_values))


def _codes(x: Sequence[np.ndarray], y: Sequence[np.ndarray]) -> tuple[list, list, int]:
    """Both samples' values replaced by their rank among the distinct values of the two
    (NaN kept): every comparison of draws is then a comparison of these ranks."""
    values = np.concatenate([g[:, 0] for g in (*x, *y)])
    distinct = np.unique(values[np.isfinite(values)])

    def code(g: np.ndarray) -> np.ndarray:
        out = np.searchsorted(distinct, g).astype(float)
        out[~np.isfinite(g)] = math.nan
        return out

    return [code(g) for g in x], [code(g) for g in y], max(len(distinct), 1)


def _histogram(codes: np.ndarray, valid: np.ndarray, n_values: int) -> np.ndarray:
    """[B, n_values]: per replicate, the weight on each distinct value; a draw weighs
    1 / (seeds with a finite draw x finite draws of its seed), so each replicate sums to 1."""
    valid = valid & np.isfinite(codes)
    per_seed = valid.sum(-1, keepdims=True)
    seeds = (per_seed > 0).sum(-2, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        w = np.where(valid, 1.0 / (per_seed * seeds), 0.0)
    b = codes.shape[0]
    flat = (np.arange(b)[:, None, None] * n_values + np.where(valid, codes, 0).astype(np.int64)).ravel()
    return np.bincount(flat, weights=w.ravel(), minlength=b * n_values).reshape(b, n_values)


def _compare(hx: np.ndarray, hy: np.ndarray) -> np.ndarray:
    """Sum over values u of hx[u] * (hy above u + hy at u / 2)."""
    above = np.cumsum(hy[:, ::-1], axis=1)[:, ::-1] - hy  # weight of y strictly greater than u
    return (hx * (above + 0.5 * hy)).sum(1)


def iqm(values: np.ndarray, axis: int = -1) -> np.ndarray:
    """Interquartile mean: the mean after cutting floor(n/4) values from each end (as
    scipy.stats.trim_mean(values, 0.25) and rliable do); NaN where a value is NaN (a bootstrap
    replicate that drew no finite value, which the percentile interval then skips)."""
    has_nan = np.isnan(values).any(axis=axis)
    values = np.sort(values, axis=axis)
    n = values.shape[axis]
    cut = n // 4
    return np.where(has_nan, math.nan, np.take(values, np.arange(cut, n - cut), axis=axis).mean(axis=axis))
