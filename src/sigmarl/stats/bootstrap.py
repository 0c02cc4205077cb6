"""Seed-aware statistics: two-level (seeds, then simulations) bootstrap, probability of
improvement, interquartile mean, performance profiles, variance components, t intervals.

Simulations of one seed share its policy, so every estimate weighs the seeds equally (the mean
over seeds of each seed's mean over simulations), and its interval is the percentile interval of
a two-level bootstrap: each replicate draws the seeds with replacement, then each drawn seed's
simulations. Hand-written: scipy.stats.bootstrap resamples flat samples (the tests use it for the
one-seed case), and rliable (1.2.0 fails at import with pandas 3) resamples runs only. Every
bootstrap draws from a generator seeded from BOOT_SEED and the cell's name, so a cell's interval
does not depend on the other cells. Pooling over scenarios: docs/concepts.md.
"""

from __future__ import annotations

import math
import warnings
import zlib
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

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


def mean_over_seeds(values: np.ndarray, axis: int = -2) -> np.ndarray:
    """Mean over `axis` (default: the seed slots) of the finite values; NaN where none is."""
    finite = np.isfinite(values)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(finite, values, 0.0).sum(axis) / finite.sum(axis)


def seed_means(groups: Sequence[np.ndarray]) -> np.ndarray:
    """[S, K]: each seed's mean over its simulations, NaNs ignored (NaN where none is finite)."""
    return mean_over_seeds(padded(groups)[0], 1)


def point_estimate(groups: Sequence[np.ndarray]) -> np.ndarray:
    """[K]: the mean over seeds of the seeds' means (seeds with no finite value skipped)."""
    return mean_over_seeds(seed_means(groups), 0)


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
    return mean_over_seeds(np.where(valid[..., None], draws, math.nan), 2)


def percentile_interval(samples: np.ndarray, level: float = LEVEL) -> tuple[np.ndarray, np.ndarray]:
    """Percentile interval over axis 0, NaN replicates ignored."""
    alpha = (1 - level) / 2
    return tuple(np.nanquantile(samples, [alpha, 1 - alpha], axis=0))


def whole_seed_groups(per_scenario: Sequence[tuple[list, list[np.ndarray]]]) -> tuple[list, list[list]]:
    """One model's (seeds, groups) per scenario aligned on the union of its seeds (ascending), so
    that a resample draws whole seeds, each with its scores on every scenario (they correlate, so
    drawing each scenario's seeds apart, rliable's stratified bootstrap, is too narrow). A seed a
    scenario lacks gets an all-NaN group, which the means skip."""
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
    z = math.sqrt(n / (n - 1)) * t_critical(n - 1, level)
    return float(1 - 2 * stats.norm.sf(z))


def probability_of_improvement(x: Sequence[np.ndarray], y: Sequence[np.ndarray]) -> float:
    """P(X < Y) + P(X = Y) / 2, X a simulation of a random seed of x, Y likewise of y.

    Each seed weighs equally, and within a seed each simulation: the Mann-Whitney statistic
    with seed-level weights. Lower is better (collision rates): 1 means x always did better.
    """
    codes_x, codes_y, n_values = _codes(x, y)
    hx, hy = (_histogram(padded(c)[0][None, ..., 0], None, n_values) for c in (codes_x, codes_y))
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


def _histogram(codes: np.ndarray, valid: np.ndarray | None, n_values: int) -> np.ndarray:
    """[B, n_values]: per replicate, the weight on each distinct value; a finite draw (of those
    `valid`) weighs 1 / (seeds with a finite draw x finite draws of its seed): each sums to 1."""
    valid = np.isfinite(codes) if valid is None else valid & np.isfinite(codes)
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
    """Interquartile mean (scipy.stats.trim_mean(values, 0.25), as rliable's); NaN where a value
    is NaN (a replicate that drew no finite value, which the percentile interval then skips)."""
    return np.where(np.isnan(values).any(axis=axis), math.nan, stats.trim_mean(values, 0.25, axis=axis))


# Performance profiles, as rliable draws them: a model's profile is the fraction of its simulations
# whose CR_total exceeds tau, for every tau (lower is better); each seed weighs equally, scenarios'
# profiles are averaged, and the band is the percentile interval over two-level bootstrap
# replicates drawn per scenario (stratified). The training curves' band: per iteration, the
# percentile interval of the mean over seeds drawn with replacement.


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
    values = padded([np.asarray(g, float)[:, None] for g in groups])[0][..., 0]
    return exceedance(values, np.isfinite(values), taus)


def profile_replicates(groups: Sequence[np.ndarray], taus: np.ndarray, n_boot: int,
                       rng: np.random.Generator) -> np.ndarray:
    """[B, T]: the profile over two-level bootstrap replicates of the seeds' simulations."""
    draws, valid = resample([np.asarray(g, float)[:, None] for g in groups], n_boot, rng)
    return exceedance(draws[..., 0], valid, taus)


def scenario_profiles(per_scenario: dict[str, Sequence[np.ndarray]], taus: np.ndarray, n_boot: int,
                      name: str, level: float = LEVEL) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The mean over scenarios of their profiles, with its stratified-bootstrap band (lo, hi)."""
    points, reps = [], []
    for scenario, groups in per_scenario.items():
        points.append(profile(groups, taus))
        reps.append(profile_replicates(groups, taus, n_boot, rng_for("profile", name, scenario)))
    lo, hi = percentile_interval(np.mean(reps, axis=0), level)
    return np.mean(points, axis=0), lo, hi


def seed_band(per_seed: np.ndarray, n_boot: int, rng: np.random.Generator, level: float = LEVEL
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per row of per_seed [I, S] (NaN where a seed lacks the row): the mean over the seeds
    and the percentile interval of that mean over resampled seeds."""
    per_seed = np.asarray(per_seed, float)
    pick = rng.integers(0, per_seed.shape[1], (n_boot, per_seed.shape[1]))
    with warnings.catch_warnings(), np.errstate(invalid="ignore"):
        warnings.simplefilter("ignore", RuntimeWarning)  # a replicate that drew only NaN seeds
        means = np.nanmean(per_seed[:, pick], axis=-1).T  # [B, I]
        lo, hi = percentile_interval(means, level)
        return np.nanmean(per_seed, axis=1), lo, hi


# Two-level variance components of a cell: simulation j of seed i = mu + a_i + e_ij, seed effects of
# variance sigma_seed^2, simulation noise sigma_sim^2, by one-way random-effects ANOVA (method of
# moments): MSW = sum_ij (x_ij - xbar_i)^2 / (N - k), MSB = sum_i n_i (xbar_i - xbar)^2 / (k - 1),
# sigma_sim^2 = MSW, sigma_seed^2 = max(0, (MSB - MSW) / n0), n0 = (N - sum_i n_i^2 / N) / (k - 1).
# A seed's mean over n simulations has variance sigma_seed^2 + sigma_sim^2 / n.


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


def t_critical(df: float, level: float = 0.95) -> float:
    """The t with P(|T| < t) = level: the two-sided critical value for a `level` interval."""
    return float(stats.t.interval(level, df)[1])


def mean_ci(values: Iterable[float], level: float = 0.95) -> tuple[float, float, float, int]:
    """(mean, CI half-width t_(n-1) s / sqrt(n), sample standard deviation, n) of the finite
    values; the half-width and the deviation NaN with fewer than two."""
    x = np.asarray(list(values), float)
    x = x[np.isfinite(x)]
    if len(x) < 2:
        return (float(x.mean()) if len(x) else math.nan), math.nan, math.nan, len(x)
    return float(x.mean()), t_critical(len(x) - 1, level) * float(stats.sem(x)), float(x.std(ddof=1)), len(x)
