"""The comparison engine: every comparison of the report is a contrast of per-seed values,
sum_i w_i mean(group_i) over independent groups (a model against its baseline: +1, -1; an
interaction: +1, -1, -1, +1; a curve window against its reference), decided by one test, with
one interval and one seeds-needed rule. Its null, its worlds and why: docs/concepts.md, "One test".

Welch's t, sqrt(sum_i w_i^2 s_i^2 / n_i) its standard error, referred to a studentized bootstrap
in worlds where the null value c holds: shifted (every group centred on its own mean), scaled
and pooled (two groups: the first multiplied onto the second's mean plus c, where that factor is
positive; the first moved by c, the two pooled and split at random). p is the largest of the
worlds'; one-sided p of "greater" is (1 + #{t* >= t_obs}) / (1 + draws), "less" mirrored,
two-sided twice the smaller. Draws come from SEED in blocks until each p is settled (`_settled`).
The interval is the shifted world's bootstrap-t; a group with fewer than 2 seeds leaves the
contrast undecidable (NaN). Hand-written because scipy's `permutation_test` and `bootstrap`
resample pooled or observed samples, never each group from its own seeds under a null.

Also here: Welch's record (`Test`), Holm's correction, the verdict rule, power and seeds needed.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from scipy import stats

SEED = 20241207
BLOCK = 50_000
MC_ERROR = 0.0005
MAX_DRAWS = 1_000_000
FAR = 4  # Monte Carlo errors above every level: a p there is drawn no further (`_settled`)
ALTERNATIVES = ("two-sided", "greater", "less")


@dataclass(frozen=True)
class Test:
    """One comparison's record as the verdict tables read it: Welch's figures (`welch`) with the
    deciding test's p-values and interval (`comparison_test`) in place of Welch's."""

    n_variant: int
    n_baseline: int
    variant_mean: float
    baseline_mean: float
    difference: float
    se: float
    df: float
    p_difference: float
    p_equivalence: float
    p_difference_welch: float = math.nan  # Welch's p of the difference, whichever test decides
    ci: tuple[float, float] | None = None  # the deciding test's own interval, where it has one

    def interval(self, level: float) -> tuple[float, float]:
        """The deciding test's interval where it gave one, else Welch's t-interval of the difference."""
        if self.ci is not None:
            return self.ci
        if not math.isfinite(self.se):
            return math.nan, math.nan
        if self.se == 0:
            return self.difference, self.difference
        half = float(stats.t.ppf(0.5 + level / 2, self.df)) * self.se
        return self.difference - half, self.difference + half


def welch(variant: np.ndarray, baseline: np.ndarray, margin: float) -> Test:
    """Welch's two-sided test of no difference and TOST within +-margin."""
    a, b = np.asarray(variant, float), np.asarray(baseline, float)
    na, nb = len(a), len(b)
    d = float(a.mean() - b.mean()) if na and nb else math.nan
    means = (float(a.mean()) if na else math.nan, float(b.mean()) if nb else math.nan)
    if na < 2 or nb < 2:
        return Test(na, nb, *means, d, math.nan, math.nan, math.nan, math.nan)
    va, vb = a.var(ddof=1) / na, b.var(ddof=1) / nb
    se = math.sqrt(va + vb)
    if se == 0:  # every value of both sides is the same: no noise to test against
        return Test(na, nb, *means, d, 0.0, math.inf, float(d == 0), float(abs(d) >= margin))
    df = (va + vb) ** 2 / (va**2 / (na - 1) + vb**2 / (nb - 1))
    p_diff = min(1.0, 2 * float(stats.t.sf(abs(d) / se, df)))
    p_eq = max(float(stats.t.sf((d + margin) / se, df)), float(stats.t.cdf((d - margin) / se, df)))
    return Test(na, nb, *means, d, se, df, p_diff, p_eq, p_diff)


def holm(p_values: Sequence[float]) -> np.ndarray:
    """Holm's step-down adjusted p-values: the i-th smallest of m is multiplied by m - i + 1,
    made non-decreasing along the order and capped at 1. NaN p-values count as 1 in the
    family (a comparison that could not be tested still is one) and stay NaN."""
    p = np.asarray(p_values, float)
    filled = np.where(np.isnan(p), 1.0, p)
    m = len(p)
    order = np.argsort(filled, kind="stable")
    adjusted = np.empty(m)
    adjusted[order] = np.minimum(1.0, np.maximum.accumulate(filled[order] * (m - np.arange(m))))
    return np.where(np.isnan(p), math.nan, adjusted)


def verdict(test: Test, sign: int, p_difference: float, p_equivalence: float, level_difference: float,
            level_equivalence: float) -> str:
    """A comparison's verdict from its adjusted p-values: a difference first (better or worse by
    the metric's direction `sign`, +1 when higher is better), then equivalence, else undecided."""
    if p_difference <= level_difference:
        return "better" if test.difference * sign > 0 else "worse"
    if p_equivalence <= level_equivalence:
        return "equivalent"
    return "undecided"


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
    def mc_error(self) -> float:
        """The largest Monte Carlo standard error of its p-values (NaN: none drawn)."""
        return max((_mc_error(p, self.draws) for p in self.p.values()), default=math.nan) if self.draws else math.nan

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
    moved by the null value (the world where the two are exchangeable); none for other contrasts.
    One split's sums serve every null: moving the first group's k values in a split's group by v
    moves its sum by -k v and its sum of squares by -2 v (their sum) + k v^2."""
    if len(groups) != 2 or tuple(weights) != (1.0, -1.0):
        return {}
    a, b = groups
    na, nb = len(a), len(b)
    perm = np.argsort(rng.random((n_draws, na + nb)), axis=1)[:, :na]
    centre = float(np.concatenate([a, b]).mean())  # the t is unmoved by a common shift; sums stay small
    x = np.concatenate([a, b]) - centre
    is_a = np.arange(na + nb) < na
    xs, first = x[perm], is_a[perm]
    s, q, k, t = xs.sum(1), (xs * xs).sum(1), first.sum(1), np.where(first, xs, 0.0).sum(1)
    total, total_sq, a_sum = x.sum(), (x * x).sum(), x[:na].sum()
    out = {}
    for name, null in nulls.items():
        v = null.value
        sa, qa = s - k * v, q - 2 * v * t + k * v * v
        sb = total - na * v - sa
        qb = total_sq - 2 * v * a_sum + na * v * v - qa
        va = np.maximum(qa - sa * sa / na, 0.0) / (na - 1)
        vb = np.maximum(qb - sb * sb / nb, 0.0) / (nb - 1)
        with np.errstate(divide="ignore", invalid="ignore"):
            out[(name, "pooled")] = np.nan_to_num((sa / na - sb / nb) / np.sqrt(va / na + vb / nb), nan=0.0)
    return out


def _scale_factor(means: Sequence[float], weights: Sequence[float], value: float) -> float | None:
    """The factor that moves the first of two groups (+1, -1) onto a contrast of `value`."""
    if len(means) != 2 or tuple(weights) != (1.0, -1.0) or means[0] == 0:
        return None
    factor = (means[1] + value) / means[0]
    return factor if math.isfinite(factor) and factor > 0 else None


def compare(groups: Sequence[Sequence[float]], weights: Sequence[float], nulls: Mapping[str, Null],
            level: float = 0.95, draws: int | None = None, decides: float | None = 0.05) -> Record:
    """Decide one contrast of per-seed values against each named null (see the module's text);
    `draws` fixes the number of resamples (a simulation of the level) instead of `MC_ERROR`;
    `decides`: the largest level the p-values are compared with (None: every p to MC_ERROR)."""
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
    t_obs = {name: _t_obs(estimate, null.value, se) for name, null in nulls.items()}
    rng = np.random.default_rng(SEED)
    counts: dict[tuple[str, str], list[int]] = {}
    shifted_t: list[np.ndarray] = []
    block = draws or BLOCK
    drawn = 0
    while True:
        shifted, stars = _t_stars(gs, w, means, _moments(gs, rng, block), nulls)
        stars.update(_pooled_t_stars(gs, w, nulls, rng, block))
        shifted_t.append(shifted)
        for (name, world), t in stars.items():
            tie = 1e-9 * max(1.0, abs(t_obs[name])) if math.isfinite(t_obs[name]) else 0.0  # rounding is no difference
            c = counts.setdefault((name, world), [0, 0])
            c[0] += int(np.count_nonzero(t >= t_obs[name] - tie))
            c[1] += int(np.count_nonzero(t <= t_obs[name] + tie))
        drawn += block
        p = _worst_p(counts, nulls, drawn)
        if draws or drawn >= MAX_DRAWS or all(_settled(x, drawn, decides) for x in p.values()):
            break
    lo, hi = _interval(estimate, se, np.concatenate(shifted_t), level)
    return Record(estimate, se, ns, lo, hi, p, drawn)


def _t_obs(estimate: float, value: float, se: float) -> float:
    if se > 0:
        return (estimate - value) / se
    return 0.0 if estimate == value else math.copysign(math.inf, estimate - value)


def _worst_p(counts: Mapping[tuple[str, str], list[int]], nulls: Mapping[str, Null], draws: int) -> dict[str, float]:
    """Per null, the larger p of its worlds: "greater" (1 + #{t* >= t_obs}) / (1 + draws), "less"
    mirrored, two-sided twice the smaller of the two (capped at 1)."""
    p: dict[str, float] = {}
    for (name, _), (n_greater, n_less) in counts.items():
        greater, less = (1 + n_greater) / (1 + draws), (1 + n_less) / (1 + draws)
        one = {"greater": greater, "less": less}.get(nulls[name].alternative, min(1.0, 2 * min(greater, less)))
        p[name] = max(p.get(name, 0.0), one)
    return {name: p[name] for name in nulls}


def _mc_error(p: float, draws: int) -> float:
    return math.sqrt(p * (1 - p) / draws)


def _settled(p: float, draws: int, decides: float | None) -> bool:
    """Drawn enough: its Monte Carlo error is under MC_ERROR, or it lies FAR Monte Carlo errors
    above `decides`, the largest level that any family compares it with (Holm's adjusted p of
    a comparison depends only on the p-values at or below its own, so such a p decides nothing)."""
    error = _mc_error(p, draws)
    return error < MC_ERROR or (decides is not None and p - FAR * error > decides)


def _interval(estimate: float, se: float, t_star: np.ndarray, level: float) -> tuple[float, float]:
    """The bootstrap-t interval: estimate - q(1 - a/2) se, estimate - q(a/2) se."""
    if se == 0:
        return estimate, estimate
    a = (1 - level) / 2
    q_lo, q_hi = np.quantile(t_star, [a, 1 - a])
    with np.errstate(over="ignore", invalid="ignore"):  # a resample without spread: an unbounded end
        return float(estimate - q_hi * se), float(estimate - q_lo * se)


def difference(model: Sequence[float], baseline: Sequence[float], nulls: Mapping[str, Null],
               level: float = 0.95) -> Record:
    """The contrast model minus baseline, its p-values judged at 1 - level."""
    return compare([model, baseline], [1.0, -1.0], nulls, level, decides=1 - level)


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
    return compare([x, x_base, y, y_base], [1.0, -1.0, -1.0, 1.0], nulls, level, decides=1 - level)


def power(n: int, effect: float, variances: Sequence[float], weights: Sequence[float], alpha: float,
          sides: int = 2, margin: float | None = None) -> float:
    """The power at n seeds a group of the contrast's t (Welch's, Satterthwaite's degrees of freedom,
    its noncentral distribution) when its true value is `effect`: to reject no difference
    (`sides`-sided at alpha), or, with `margin`, to show equivalence within +-margin (TOST at
    alpha a side: P(T1 > t) + P(T2 < -t) - 1)."""
    v = [w * w * x for w, x in zip(weights, variances, strict=True)]
    se = math.sqrt(sum(v) / n)
    df = sum(v) ** 2 * (n - 1) / sum(x * x for x in v)
    if margin is None:
        crit = float(stats.t.ppf(1 - alpha / sides, df))
        nc = abs(effect) / se
        return float(stats.nct.sf(crit, df, nc)) + (float(stats.nct.cdf(-crit, df, nc)) if sides == 2 else 0.0)
    crit = float(stats.t.ppf(1 - alpha, df))
    upper, lower = stats.nct.sf(crit, df, (effect + margin) / se), stats.nct.cdf(-crit, df, (effect - margin) / se)
    return max(0.0, float(upper) + float(lower) - 1)


def seeds_needed(effect: float, variances: Sequence[float], weights: Sequence[float], alpha: float,
                 power_target: float = 0.8, sides: int = 2, margin: float | None = None,
                 cap: int = 100_000) -> int | None:
    """The fewest seeds a group (at least 2) at which `power` reaches `power_target`. Checked
    against the engine's own test by simulation (tests/test_engine.py). None: no effect (or, for
    equivalence, |effect| >= margin), no spread, or over `cap`."""
    v = [w * w * x for w, x in zip(weights, variances, strict=True)]
    if not all(map(math.isfinite, (effect, *v))) or sum(v) <= 0:
        return None
    if (effect == 0) if margin is None else not abs(effect) < margin:
        return None

    def enough(n: int) -> bool:
        return power(n, effect, variances, weights, alpha, sides, margin) >= power_target

    n = 2
    while not enough(n):
        n *= 2
        if n > cap:
            return None
    lo = n // 2 if n > 2 else 1
    while n - lo > 1:
        mid = (lo + n) // 2
        lo, n = (lo, mid) if enough(mid) else (mid, n)
    return max(n, 2)
