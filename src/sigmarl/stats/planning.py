"""Seeds a decision needs, by simulation of the test that decides, and the interval of a
difference that the same test gives.

The analytic power of `sigmarl.stats.power` is Welch's, and assumes normal seed means; ours
are skewed (one seed in ten learns slowly and collides several times more), and the verdicts
come from a permutation test (`sigmarl.stats.permutation`). Here the power of that test at n
seeds per side is estimated from the observed seeds themselves:

- each side's seed means are centred on their mean and scaled by sqrt(m / (m - 1)) (m seeds),
  so that a draw from them has the sample's variance, not the smaller (m - 1) / m of it;
- `SIMULATIONS` datasets of n seeds per side are drawn with replacement (a bootstrap), the
  variant's shifted by the assumed true difference;
- each dataset is tested with the verdict's permutation test and TOST (`permutation_p`),
  exact where 2n seeds have at most `DRAWS` splits, else from `DRAWS` random splits (the
  verdict itself draws 20,000; fewer here for speed, which costs a little power, so the
  seeds found err on the side of more);
- power is the share of datasets whose p is <= alpha.

The smallest n with power >= the target is searched by doubling from Welch's answer (or
halving, when that already has the power), then bisection until the bracket is within
`RELATIVE` of its top (the answer is its top), up to `MAX_SEEDS`. Every draw comes from
fixed seeds, and the draws of n seeds are the first n of the draws of more (common random
numbers), so the same seeds give the same answer and power rises smoothly with n.

The interval of the difference inverts the verdict's test: the shifts of the variant's seeds
that its permutation test (at the verdict's own splits) does not reject at 1 - level. It holds
0 exactly when the unadjusted test does not reject, and it is unbounded on a side where no
split of so few seeds can reach the level (3 against 3 seeds: 20 splits, p >= 0.1).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from sigmarl.stats import permutation
from sigmarl.stats.permutation import permutation_p

SIMULATIONS = 400  # datasets per power estimate: standard error <= 0.02 at power 0.8
DRAWS = 199  # random splits per simulated dataset: p = (1 + k) / 200 <= 0.05 at k <= 9
MAX_SEEDS = 1000
RELATIVE = 0.05  # the search stops when its bracket is this close (about the simulations' own error)
SEED = 20261204
_GRID = 64  # shifts per refinement of the interval's ends
_ROUNDS = 3


def bootstrap_source(values) -> np.ndarray:
    """Seed means centred on their mean and scaled to the sample variance (ddof 1)."""
    v = np.asarray(values, float)
    m = len(v)
    return (v - v.mean()) * math.sqrt(m / (m - 1))


def _draw(source: np.ndarray, n: int, sims: int, seed: list[int]) -> np.ndarray:
    """[sims, n] draws from `source`; the first n columns are the same for every larger n."""
    u = np.random.default_rng(seed).random((n, sims)).T
    return source[np.minimum((u * len(source)).astype(np.intp), len(source) - 1)]


def power(a, b, n: int, true_difference: float, margin: float, alpha: float, kind: str,
          sims: int | None = None, draws: int | None = None, seed: int = SEED) -> float:
    """The share of `sims` simulated datasets of n seeds per side that the verdict's test decides:
    kind "difference" (two-sided, p <= alpha) or "equivalence" (TOST within +-margin, p <= alpha).
    a, b: the variant's and the baseline's observed seed means (two or more each)."""
    sims, draws = sims or SIMULATIONS, draws or DRAWS
    variant = _draw(bootstrap_source(a), n, sims, [seed, 0]) + true_difference
    baseline = _draw(bootstrap_source(b), n, sims, [seed, 1])
    p_diff, p_eq = permutation_p(variant, baseline, margin, draws=draws, seed=seed, exact_limit=draws)
    return float(np.mean((p_diff if kind == "difference" else p_eq) <= alpha))


def smallest_n(power_at: Callable[[int], float], target: float, start: int = 2, cap: int | None = None,
               relative: float | None = None) -> int | None:
    """The smallest n (within `relative`, from above) with power_at(n) >= target, searched from
    `start`; None when even `cap` falls short. n = 1 counts as short (no test)."""
    cap, relative = cap or MAX_SEEDS, relative or RELATIVE

    def enough(n: int) -> bool:
        return power_at(n) >= target

    n = min(max(int(start), 2), cap)
    if enough(n):
        lo, hi = n // 2, n
        while lo >= 2 and enough(lo):
            lo, hi = lo // 2, lo
        lo = max(lo, 1)
    else:
        lo, hi = n, min(2 * n, cap)
        while not enough(hi):
            if hi == cap:
                return None
            lo, hi = hi, min(2 * hi, cap)
    while hi - lo > max(1.0, relative * hi):
        mid = (lo + hi) // 2
        lo, hi = (lo, mid) if enough(mid) else (mid, hi)
    return hi


def seeds_for(a, b, true_difference: float, margin: float, alpha: float, target: float, kind: str,
              start: int = 2, cap: int | None = None, sims: int | None = None, draws: int | None = None,
              seed: int = SEED) -> int | None:
    """Seeds per side for the verdict's test to decide `kind` with power `target` when the true
    difference is `true_difference` (None: not within `cap`, or equivalence at |difference| >= margin)."""
    if kind == "equivalence" and not abs(true_difference) < margin:
        return None
    return smallest_n(lambda n: power(a, b, n, true_difference, margin, alpha, kind, sims, draws, seed),
                      target, start, cap)


def shift_interval(a, b, level: float = 0.95, draws: int = permutation.DRAWS,
                   seed: int = permutation.SEED) -> tuple[float, float]:
    """The shifts s of mean(a) - mean(b) that the permutation test of (a - s) against b does not
    reject at 1 - level: (low, high), an end +-inf where no shift is rejected on that side."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    d = float(a.mean() - b.mean())
    alpha = 1 - level

    def kept(shifts: np.ndarray) -> np.ndarray:
        p, _ = permutation_p(a[None, :] - shifts[:, None], b, 0.0, draws, seed)
        return np.atleast_1d(p) > alpha

    width = 4 * (float(np.ptp(np.concatenate([a, b]))) + abs(d)) or 1.0
    ends = []
    for side in (-1.0, 1.0):
        far = d + side * width
        if kept(np.array([far]))[0]:
            ends.append(side * math.inf)
            continue
        inner = d  # kept (no difference left); `far` rejected
        for _ in range(_ROUNDS):
            grid = np.linspace(far, inner, _GRID + 1)
            first = int(np.argmax(kept(grid)))  # the outermost kept shift of the grid
            far, inner = grid[first - 1], grid[first]
        ends.append(float(inner))
    return ends[0], ends[1]
