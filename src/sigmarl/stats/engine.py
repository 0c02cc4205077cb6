"""The comparison engine: every comparison the report makes is a contrast of per-seed values,
decided by one test, with one interval and one seeds-needed rule.

A contrast is sum_i w_i mean(group_i) over independent groups of per-seed values: a model
against its baseline (+1, -1), an interaction ((x - bx) - (y - by): +1, -1, -1, +1), a curve
window against its reference. Its standard error is Welch's, sqrt(sum_i w_i^2 s_i^2 / n_i).

The test (its null is stated once, with its reason, in docs/concepts.md, "One test"): a
studentized bootstrap in which each group is resampled from its own seeds only, never pooled
with another's, so no group is assumed to be another shifted. For a null value c of the
contrast, null worlds are built from the seeds and the largest p of them is kept:

- shifted: every group moved onto a world where the contrast is c by centring it on its own
  mean (each keeps its own spread and shape);
- scaled (two groups only): the first group multiplied so that its mean sits at the second's
  plus c (its spread scaled with it, as a rate's seeds scale with their mean); skipped where
  that factor is not positive;
- pooled (two groups only): the first group moved by c and the two pooled, split at random into
  groups of their sizes (a studentized permutation test: the world where the two models'
  seeds are exchangeable, in which it holds its level exactly).

The null holds in each of these worlds, so a verdict must survive all of them: p is the largest
of the worlds' p-values (their supremum). In each world t* = (contrast* - c) / se* over the resamples, and the one-sided p of "greater"
is (1 + #{t* >= t_obs}) / (1 + draws), t_obs = (estimate - c) / se; "less" mirrors it, and
two-sided is twice the smaller, capped at 1. One set of drawn seeds serves every null value
and world (a world only moves or scales a group's resampled mean and spread).

Draws: from a fixed seed, in blocks of `BLOCK`, until every p's Monte Carlo standard error
sqrt(p (1 - p) / draws) is under `MC_ERROR` (0.0005: the third decimal is reproducible), at
most `MAX_DRAWS`. The interval is the same bootstrap-t's, estimate - q se, from the shifted
world. A group with fewer than 2 seeds leaves the contrast undecidable: p-values and interval
NaN, shown as "–" and decided "undecided".

scipy's `permutation_test` and `bootstrap` resample pooled or observed samples, not each group
from its own seeds under a null, so they are not used here (the tests use them where they agree).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from scipy import stats

from sigmarl.stats.tests import Test, holm, welch  # noqa: F401  (holm: the families' correction, re-exported)

SEED = 20241207
BLOCK = 50_000
MC_ERROR = 0.0005
MAX_DRAWS = 1_000_000
ALTERNATIVES = ("two-sided", "greater", "less")


@dataclass(frozen=True)
class Null:
    """H0 of a test: the contrast is `value`, against `alternative` ("greater": it is larger)."""

    value: float
    alternative: str = "two-sided"


@dataclass(frozen=True)
class Record:
    """One contrast decided: its estimate, standard error, interval and p-value per null."""

    estimate: float
    se: float
    ns: tuple[int, ...]
    ci_low: float
    ci_high: float
    p: Mapping[str, float] = field(default_factory=dict)
    draws: int = 0

    @property
    def decidable(self) -> bool:
        return min(self.ns, default=0) >= 2


def _moments(groups: Sequence[np.ndarray], rng: np.random.Generator, n_draws: int) -> list[tuple]:
    """Per group, its resamples' means and variances ([n_draws] each), drawn from its own seeds."""
    out = []
    for g in groups:
        idx = rng.integers(0, len(g), (n_draws, len(g)))
        draw = g[idx]
        out.append((draw.mean(1), draw.var(1, ddof=1)))
    return out


def _t_stars(groups, weights, means, moments, nulls: Mapping[str, Null]
             ) -> tuple[np.ndarray, dict[tuple[str, str], np.ndarray]]:
    """The shifted world's t* of this block's resamples (centred on the estimate), and
    (null name, world) -> t* in that null world."""
    w = np.asarray(weights, float)
    ns = np.array([len(g) for g in groups], float)
    shift_num = sum(wi * (m - mu) for wi, (m, _), mu in zip(w, moments, means, strict=True))
    shift_se = np.sqrt(sum(wi * wi * v / n for wi, (_, v), n in zip(w, moments, ns, strict=True)))
    out = {}
    with np.errstate(divide="ignore", invalid="ignore"):
        shifted = np.nan_to_num(shift_num / shift_se, nan=0.0)
        for name, null in nulls.items():
            out[(name, "shifted")] = shifted
            factor = _scale_factor(means, weights, null.value)
            if factor is None:
                continue
            (ma, va), (mb, vb) = moments
            num = factor * ma - mb - null.value
            se = np.sqrt(factor * factor * va / ns[0] + vb / ns[1])
            out[(name, "scaled")] = np.nan_to_num(num / se, nan=0.0)
    return shifted, out


def _pooled_t_stars(groups, weights, nulls: Mapping[str, Null], rng: np.random.Generator, n_draws: int
                    ) -> dict[tuple[str, str], np.ndarray]:
    """(null name, "pooled") -> Welch's t over random splits of the two groups pooled, the first
    moved by the null value (the world where the two are exchangeable); none for other contrasts."""
    if len(groups) != 2 or tuple(weights) != (1.0, -1.0):
        return {}
    a, b = groups
    na, nb = len(a), len(b)
    perm = np.argsort(rng.random((n_draws, na + nb)), axis=1)
    out = {}
    for name, null in nulls.items():
        x = np.concatenate([a - null.value, b])[perm]
        ga, gb = x[:, :na], x[:, na:]
        se = np.sqrt(ga.var(1, ddof=1) / na + gb.var(1, ddof=1) / nb)
        with np.errstate(divide="ignore", invalid="ignore"):
            out[(name, "pooled")] = np.nan_to_num((ga.mean(1) - gb.mean(1)) / se, nan=0.0)
    return out


def _scale_factor(means: Sequence[float], weights: Sequence[float], value: float) -> float | None:
    """The factor that moves the first of two groups (+1, -1) onto a contrast of `value`."""
    if len(means) != 2 or tuple(weights) != (1.0, -1.0) or means[0] == 0:
        return None
    factor = (means[1] + value) / means[0]
    return factor if math.isfinite(factor) and factor > 0 else None


def _p(count_greater: int, count_less: int, draws: int, alternative: str) -> float:
    greater = (1 + count_greater) / (1 + draws)
    less = (1 + count_less) / (1 + draws)
    if alternative == "greater":
        return greater
    if alternative == "less":
        return less
    return min(1.0, 2 * min(greater, less))


def compare(groups: Sequence[Sequence[float]], weights: Sequence[float], nulls: Mapping[str, Null],
            level: float = 0.95, seed: int = SEED, draws: int | None = None) -> Record:
    """Decide one contrast of per-seed values against each named null (see the module's text);
    `draws` fixes the number of resamples (a simulation of the level) instead of `MC_ERROR`."""
    for null in nulls.values():
        if null.alternative not in ALTERNATIVES:
            raise ValueError(f"unknown alternative {null.alternative!r}; known: {', '.join(ALTERNATIVES)}")
    gs = [np.asarray(g, float)[np.isfinite(np.asarray(g, float))] for g in groups]
    w = [float(x) for x in weights]
    ns = tuple(len(g) for g in gs)
    if min(ns, default=0) == 0:
        return Record(math.nan, math.nan, ns, math.nan, math.nan, {k: math.nan for k in nulls})
    means = [float(g.mean()) for g in gs]
    estimate = float(sum(wi * m for wi, m in zip(w, means, strict=True)))
    if min(ns) < 2:
        return Record(estimate, math.nan, ns, math.nan, math.nan, {k: math.nan for k in nulls})
    se = math.sqrt(sum(wi * wi * float(g.var(ddof=1)) / len(g) for wi, g in zip(w, gs, strict=True)))
    rng = np.random.default_rng(seed)
    counts: dict[tuple[str, str], list[int]] = {}
    shifted_t: list[np.ndarray] = []
    block = draws or BLOCK
    drawn = 0
    while True:
        shifted, stars = _t_stars(gs, w, means, _moments(gs, rng, block), nulls)
        stars.update(_pooled_t_stars(gs, w, nulls, rng, block))
        shifted_t.append(shifted)
        for key, t in stars.items():
            t_obs = _t_obs(estimate, nulls[key[0]].value, se)
            c = counts.setdefault(key, [0, 0])
            tie = 1e-9 * max(1.0, abs(t_obs)) if math.isfinite(t_obs) else 0.0  # rounding is no difference
            c[0] += int(np.count_nonzero(t >= t_obs - tie))
            c[1] += int(np.count_nonzero(t <= t_obs + tie))
        drawn += block
        p = _worst_p(counts, nulls, drawn)
        if draws or drawn >= MAX_DRAWS or all(_mc_error(x, drawn) < MC_ERROR for x in p.values()):
            break
    lo, hi = _interval(estimate, se, np.concatenate(shifted_t), level)
    return Record(estimate, se, ns, lo, hi, p, drawn)


def _t_obs(estimate: float, value: float, se: float) -> float:
    if se > 0:
        return (estimate - value) / se
    return 0.0 if estimate == value else math.copysign(math.inf, estimate - value)


def _worst_p(counts: Mapping[tuple[str, str], list[int]], nulls: Mapping[str, Null], draws: int) -> dict[str, float]:
    """Per null, the larger p of its worlds."""
    p: dict[str, float] = {}
    for (name, _), (greater, less) in counts.items():
        p[name] = max(p.get(name, 0.0), _p(greater, less, draws, nulls[name].alternative))
    return {name: p[name] for name in nulls}


def _mc_error(p: float, draws: int) -> float:
    return math.sqrt(p * (1 - p) / draws)


def _interval(estimate: float, se: float, t_star: np.ndarray, level: float) -> tuple[float, float]:
    """The bootstrap-t interval: estimate - q(1 - a/2) se, estimate - q(a/2) se."""
    if se == 0:
        return estimate, estimate
    a = (1 - level) / 2
    q_lo, q_hi = np.quantile(t_star, [a, 1 - a])
    return float(estimate - q_hi * se), float(estimate - q_lo * se)


def difference(model: Sequence[float], baseline: Sequence[float], nulls: Mapping[str, Null],
               level: float = 0.95) -> Record:
    """The contrast model minus baseline."""
    return compare([model, baseline], [1.0, -1.0], nulls, level)


def comparison_test(variant: Sequence[float], baseline: Sequence[float], margin: float, level: float = 0.95) -> Test:
    """A comparison (variant minus baseline) decided by the engine: the two-sided p of no
    difference, equivalence within +-margin as the larger p of its two one-sided nulls, and the
    engine's interval; Welch's figures beside them (reported, not decided on). One seed on a side
    or no spread at all: Welch's record as it stands (undecidable, or decided without noise)."""
    test = welch(variant, baseline, margin)
    if not math.isfinite(test.se) or test.se == 0:
        return test
    nulls = {"difference": Null(0.0), "above": Null(-margin, "greater"), "below": Null(margin, "less")}
    r = difference(variant, baseline, nulls, level)
    return replace(test, p_difference=r.p["difference"], p_equivalence=max(r.p["above"], r.p["below"]),
                   ci=(r.ci_low, r.ci_high))


def interaction(x: Sequence[float], x_base: Sequence[float], y: Sequence[float], y_base: Sequence[float],
                nulls: Mapping[str, Null], level: float = 0.95) -> Record:
    """The contrast (x - x_base) - (y - y_base), four independent groups."""
    return compare([x, x_base, y, y_base], [1.0, -1.0, -1.0, 1.0], nulls, level)


def seeds_needed(effect: float, variances: Sequence[float], weights: Sequence[float], alpha: float,
                 power: float = 0.8, sides: int = 2, cap: int = 100_000) -> int | None:
    """Seeds per group at which the contrast, with these per-seed variances and a true value
    `effect` from its null, reaches `power` at `alpha` (`sides`-sided): Welch's t with
    Satterthwaite's degrees of freedom and its noncentral distribution. Checked against the
    engine's own test by simulation (tests/test_engine.py). None: no effect, or over `cap`."""
    v = [w * w * x for w, x in zip(weights, variances, strict=True)]
    if effect == 0 or not all(map(math.isfinite, (effect, *v))) or sum(v) <= 0:
        return None

    def power_at(n: int) -> float:
        se = math.sqrt(sum(v) / n)
        df = sum(v) ** 2 * (n - 1) / sum(x * x for x in v)
        crit = float(stats.t.ppf(1 - alpha / sides, df))
        return float(stats.nct.sf(crit, df, abs(effect) / se))

    n = 2
    while power_at(n) < power:
        n *= 2
        if n > cap:
            return None
    lo = n // 2 if n > 2 else 1
    while n - lo > 1:
        mid = (lo + n) // 2
        lo, n = (lo, mid) if power_at(mid) >= power else (mid, n)
    return max(n, 2)
